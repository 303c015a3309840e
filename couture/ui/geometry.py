"""Picking and camera geometry for the two views (pure numpy).

Correspondence between the pattern and the drape is through the mesh: a
material point is a triangle and barycentric coordinates, the same in the
rest positions X (pattern view) and the draped positions x (3D view).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class MaterialPoint:
    """A point of the cloth: triangle index and barycentric weights (sum 1)."""

    tri: int
    bary: np.ndarray
    """shape (3,), float64"""

    def on(self, positions: np.ndarray, tris: np.ndarray) -> np.ndarray:
        """The point in a configuration (X (n, 2) or x (n, 3))."""
        return self.bary @ np.asarray(positions, np.float64)[tris[self.tri]]

    def nearest_vertex(self, tris: np.ndarray) -> int:
        return int(tris[self.tri][int(np.argmax(self.bary))])


def locate_in_pattern(
    X: np.ndarray, tris: np.ndarray, p: np.ndarray, tri_mask: np.ndarray | None = None
) -> MaterialPoint | None:
    """The triangle of the rest mesh containing the 2D point ``p`` [m] and its
    barycentric weights; if p lies outside every triangle, the closest
    triangle by barycentric violation (so a click just beside a boundary still
    lands on the cloth). ``tri_mask`` restricts the search (e.g. one panel,
    because panels may overlap in material space)."""
    X = np.asarray(X, np.float64)
    idx = np.arange(len(tris)) if tri_mask is None else np.flatnonzero(tri_mask)
    if idx.size == 0:
        return None
    t = tris[idx]
    a, b, c = X[t[:, 0]], X[t[:, 1]], X[t[:, 2]]
    v0, v1, v2 = b - a, c - a, np.asarray(p, np.float64)[None, :] - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    den = np.where(np.abs(den) > 1e-300, den, 1e-300)
    l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
    l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
    l0 = 1.0 - l1 - l2
    lam = np.stack([l0, l1, l2], axis=-1)
    violation = np.maximum(-lam, 0.0).sum(axis=1)
    k = int(np.argmin(violation))
    bary = np.clip(lam[k], 0.0, None)
    bary /= bary.sum()
    return MaterialPoint(int(idx[k]), bary)


def ray_hit(x: np.ndarray, tris: np.ndarray, origin, direction) -> tuple[MaterialPoint, float] | None:
    """First intersection of a ray with a triangle mesh (Möller-Trumbore,
    vectorised, both faces): the material point and the ray parameter, or None."""
    x = np.asarray(x, np.float64)
    o = np.asarray(origin, np.float64)
    d = np.asarray(direction, np.float64)
    a, b, c = x[tris[:, 0]], x[tris[:, 1]], x[tris[:, 2]]
    e1, e2 = b - a, c - a
    pvec = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pvec)
    ok = np.abs(det) > 1e-14
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tvec = o - a
    u = np.einsum("ij,ij->i", tvec, pvec) * inv
    qvec = np.cross(tvec, e1)
    v = (qvec @ d) * inv
    t = np.einsum("ij,ij->i", e2, qvec) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    if not hit.any():
        return None
    k = int(np.flatnonzero(hit)[np.argmin(t[hit])])
    return MaterialPoint(k, np.array([1 - u[k] - v[k], u[k], v[k]])), float(t[k])


@dataclass
class BodyPick:
    """Where a ray meets the body's ellipsoid proxy (:func:`pick_body`)."""

    point: np.ndarray
    """[m], shape (3,): on the proxy, within its fit error outside the body"""
    normal: np.ndarray
    """outward unit normal of the ellipsoid there, shape (3,)"""
    t: float
    """[m] along the unit ray direction"""
    leaf: int
    """index of the ellipsoid in ``proxy.leaves``"""
    region: str
    """its body region ('torso', 'arm_l', ...)"""
    error: float
    """[m] its leaf's fit error (max of Meng's normal distance and the
    overshoot): the body lies within about this of ``point``"""


def pick_body(ray_origin, ray_dir, proxy) -> BodyPick | None:
    """The body point a ray (a click in the 3D view) lands on: its first
    intersection with the ellipsoid proxy (couture.cloth.proxy, Meng §4),
    closed-form per ellipsoid, instead of a ray against every body triangle;
    None on a miss. ValueError for a zero or non-finite ray."""
    hit, t, q, n, leaf = proxy.raycast(np.asarray(ray_origin, np.float64), np.asarray(ray_dir, np.float64))
    if not hit[0]:
        return None
    k = int(leaf[0])
    return BodyPick(
        point=q[0].copy(),
        normal=n[0].copy(),
        t=float(t[0]),
        leaf=k,
        region=proxy.regions[k],
        error=float(proxy.nodes[proxy.leaves[k]].error),
    )


def closest_material_point(x: np.ndarray, tris: np.ndarray, p) -> MaterialPoint:
    """Material point at the vertex of ``x`` nearest to the 3D point ``p``
    (a drag's grab point lies on the surface, so the nearest vertex's
    incident triangle is where it is; we report the vertex itself)."""
    x = np.asarray(x, np.float64)
    v = int(np.argmin(((x - np.asarray(p, np.float64)) ** 2).sum(axis=1)))
    rows, cols = np.nonzero(tris == v)
    if rows.size == 0:
        raise ValueError("vertex belongs to no triangle")
    bary = np.zeros(3)
    bary[cols[0]] = 1.0
    return MaterialPoint(int(rows[0]), bary)


# --- camera ------------------------------------------------------------------


def quat_to_matrix(wxyz) -> np.ndarray:
    w, x, y, z = (float(c) for c in wxyz)
    n = w * w + x * x + y * y + z * z
    s = 2.0 / n if n > 0 else 0.0
    return np.array(
        [
            [1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)],
            [s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)],
            [s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)],
        ]
    )


@dataclass
class CameraState:
    """A browser camera as viser reports it (OpenCV convention: camera +z
    looks forward, +y down; ``wxyz`` rotates camera to world)."""

    position: np.ndarray
    """[m], shape (3,)"""
    wxyz: np.ndarray
    """shape (4,)"""
    fov: float
    """vertical field of view [rad]"""
    aspect: float
    """width / height"""
    width: int
    """viewport [px]"""
    height: int
    near: float = 0.01
    """[m]"""
    far: float = 1000.0
    """[m]"""

    @classmethod
    def from_viser(cls, camera) -> "CameraState":
        return cls(
            np.asarray(camera.position, np.float64),
            np.asarray(camera.wxyz, np.float64),
            float(camera.fov),
            float(camera.aspect),
            int(camera.image_width),
            int(camera.image_height),
            float(getattr(camera, "near", 0.01)),
            float(getattr(camera, "far", 1000.0)),
        )

    def view_proj_gl(self) -> np.ndarray:
        """4x4 OpenGL view-projection (world [m] -> clip; NDC x right, y up,
        both in [-1, 1]), what ``EditMsg.view_proj`` carries."""
        R = quat_to_matrix(self.wxyz) @ np.diag([1.0, -1.0, -1.0])
        view = np.eye(4)
        view[:3, :3] = R.T
        view[:3, 3] = -R.T @ self.position
        f = 1.0 / np.tan(0.5 * self.fov)
        n, fa = self.near, self.far
        proj = np.array(
            [
                [f / self.aspect, 0, 0, 0],
                [0, f, 0, 0],
                [0, 0, (fa + n) / (n - fa), 2 * fa * n / (n - fa)],
                [0, 0, -1, 0],
            ]
        )
        return proj @ view

    def view_projection(self) -> np.ndarray:
        """3x4 matrix P taking homogeneous world points to homogeneous OpenCV
        screen coordinates normalised to [0, 1]² (origin top-left): for a world
        point p, (u w, v w, w) = P @ (p, 1)."""
        R = quat_to_matrix(self.wxyz)
        fy = 0.5 / np.tan(0.5 * self.fov)
        fx = fy / self.aspect
        K = np.array([[fx, 0.0, 0.5], [0.0, fy, 0.5], [0.0, 0.0, 1.0]])
        Rt = np.hstack([R.T, -(R.T @ self.position)[:, None]])
        return K @ Rt

    def project(self, points: np.ndarray) -> np.ndarray:
        """World points (k, 3) → normalised screen (k, 2) in [0, 1]² when visible."""
        p = np.atleast_2d(np.asarray(points, np.float64))
        h = np.hstack([p, np.ones((len(p), 1))]) @ self.view_projection().T
        return h[:, :2] / h[:, 2:3]

    def to_pixels(self, points: np.ndarray) -> np.ndarray:
        return self.project(points) * np.array([self.width, self.height])

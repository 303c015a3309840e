"""Bodies the cloth rests on, as signed distance fields (positive outside).

Every body offers ``phi_grad(points (n, 3)) -> (phi (n,) [m], grad (n, 3))``;
the ones here also ``phi_hess(points) -> (n, 3, 3) [1/m]``, the SDF's Hessian
(its curvature), which the contact stiffness needs to be the exact Hessian.

- :class:`SphereBody`, :class:`PlaneBody`: closed-form SDFs for tests and the
  SC Fig. 5 sphere scene.
- :class:`GridSDFBody`: a regular-grid SDF, trilinearly interpolated (grad is
  the exact gradient of the interpolant). :func:`load_mannequin_sdf` builds
  it once for the embedded mannequin or a graded body (1 cm grid over its bounding box plus a
  margin, exact point-triangle distances, sign from angle-weighted
  pseudonormals) and caches it as ``.npz`` under ``$COUTURE_CACHE`` or
  ``~/.cache/couture``.
"""

from __future__ import annotations

import hashlib
import os
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from couture.cloth import kernels as K

MANNEQUIN_OBJ = Path(__file__).resolve().parent.parent / "assets" / "mannequin" / "body_a_pose.obj"


@dataclass
class SphereBody:
    center: np.ndarray
    """[m], shape (3,)"""
    radius: float
    """[m]"""

    def phi_grad(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = np.asarray(points, dtype=np.float64) - np.asarray(self.center, dtype=np.float64)
        r = np.linalg.norm(d, axis=1)
        safe = np.where(r > 0, r, 1.0)
        grad = d / safe[:, None]
        grad[r == 0] = (0.0, 1.0, 0.0)
        return r - self.radius, grad

    def phi_hess(self, points: np.ndarray) -> np.ndarray:
        """(I - n nᵀ) / r: the distance to the centre curves with 1/r across n."""
        d = np.asarray(points, dtype=np.float64) - np.asarray(self.center, dtype=np.float64)
        r = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
        n = d / r[:, None]
        return (np.eye(3)[None] - n[:, :, None] * n[:, None, :]) / r[:, None, None]


@dataclass
class PlaneBody:
    """Half-space {p : n.(p - point) < 0} (a floor or a table top)."""

    point: np.ndarray
    """[m], shape (3,)"""
    normal: np.ndarray
    """outward unit normal, shape (3,)"""

    def phi_grad(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = np.asarray(self.normal, dtype=np.float64)
        n = n / np.linalg.norm(n)
        p = np.asarray(points, dtype=np.float64)
        return (p - np.asarray(self.point, dtype=np.float64)) @ n, np.broadcast_to(n, p.shape).copy()

    def phi_hess(self, points: np.ndarray) -> np.ndarray:
        return np.zeros((len(points), 3, 3))


@dataclass
class GridSDFBody:
    origin: np.ndarray
    """position of grid node (0, 0, 0) [m], shape (3,)"""
    spacing: float
    """[m]"""
    values: np.ndarray
    """signed distance at the nodes [m], shape (nx, ny, nz), float64"""
    interpolation: str = "bspline"
    """'bspline': C² cubic B-spline (default; smooth contact forces, see
    kernels.bspline_phi_grad); 'trilinear': C⁰, its gradient jumps across cell faces"""

    def phi_grad(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = np.ascontiguousarray(points, dtype=np.float64)
        phi = np.empty(len(p))
        grad = np.empty((len(p), 3))
        kernel = K.bspline_phi_grad if self.interpolation == "bspline" else K.trilinear_phi_grad
        kernel(p, np.asarray(self.origin, np.float64), float(self.spacing), self.values, phi, grad)
        return phi, grad

    def phi_hess(self, points: np.ndarray) -> np.ndarray:
        """The B-spline interpolant's Hessian [1/m], (n, 3, 3); zero for 'trilinear'
        (piecewise linear: no curvature inside a cell)."""
        p = np.ascontiguousarray(points, dtype=np.float64)
        hess = np.zeros((len(p), 3, 3))
        if self.interpolation == "bspline":
            K.bspline_phi_hess(p, np.asarray(self.origin, np.float64), float(self.spacing), self.values, hess)
        return hess


class TriangleMeshDistance:
    """Exact signed distance to a closed, outward-oriented triangle mesh
    (candidate faces from a k-d tree of face centroids)."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, k: int = 24):
        from scipy.spatial import cKDTree

        V = np.ascontiguousarray(vertices, dtype=np.float64)
        F = np.ascontiguousarray(faces, dtype=np.int64)
        self.V, self.F, self.k = V, F, min(k, len(F))
        e1 = V[F[:, 1]] - V[F[:, 0]]
        e2 = V[F[:, 2]] - V[F[:, 0]]
        fn = np.cross(e1, e2)
        fn /= np.linalg.norm(fn, axis=1)[:, None]
        self.face_n = fn
        # edge pseudonormal: sum of the normals of the two faces at the edge
        a = F.reshape(-1)
        b = F[:, [1, 2, 0]].reshape(-1)
        key = np.minimum(a, b) * len(V) + np.maximum(a, b)
        uniq, inv = np.unique(key, return_inverse=True)
        acc = np.zeros((len(uniq), 3))
        np.add.at(acc, inv, np.repeat(fn, 3, axis=0))
        self.edge_n = acc[inv].reshape(len(F), 3, 3)
        # vertex pseudonormal: angle-weighted face normals
        vn = np.zeros_like(V)
        for c in range(3):
            p0 = V[F[:, c]]
            u = V[F[:, (c + 1) % 3]] - p0
            w = V[F[:, (c + 2) % 3]] - p0
            cosang = np.einsum("ij,ij->i", u, w) / (np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1))
            ang = np.arccos(np.clip(cosang, -1.0, 1.0))
            np.add.at(vn, F[:, c], fn * ang[:, None])
        self.vert_n = vn
        centroids = V[F].mean(axis=1)
        self.tree = cKDTree(centroids)
        self.reach = float(np.linalg.norm(V[F] - centroids[:, None], axis=2).max())
        """[m] farthest triangle point from its centroid: (distance to the nearest
        centroid) - reach is a lower bound on a point's distance to the mesh"""

    def phi_grad(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact signed distance and its gradient (the unit direction from the
        closest surface point, outward), so the mesh itself is a body; near
        the surface (the k nearest faces by centroid are searched)."""
        p = np.ascontiguousarray(points, dtype=np.float64)
        phi = np.empty(len(p))
        grad = np.empty((len(p), 3))
        if len(p):
            _, cand = self.tree.query(p, k=self.k)
            cand = np.ascontiguousarray(cand.reshape(len(p), -1), dtype=np.int64)
            K.signed_distance_grad_candidates(p, cand, self.V, self.F, self.face_n, self.edge_n, self.vert_n, phi, grad)
        return phi, grad

    def __call__(self, points: np.ndarray, chunk: int = 100_000, progress: str | None = None) -> np.ndarray:
        points = np.ascontiguousarray(points, dtype=np.float64)
        out = np.empty(len(points))
        t0 = time.perf_counter()
        for s in range(0, len(points), chunk):
            p = points[s : s + chunk]
            _, cand = self.tree.query(p, k=self.k)
            cand = np.ascontiguousarray(cand.reshape(len(p), -1), dtype=np.int64)
            K.signed_distance_candidates(
                p, cand, self.V, self.F, self.face_n, self.edge_n, self.vert_n, out[s : s + chunk]
            )
            if progress:
                done = min(s + chunk, len(points))
                print(
                    f"\r{progress}: {done}/{len(points)} points, {time.perf_counter() - t0:.1f} s",
                    end="",
                    file=sys.stderr,
                    flush=True,
                )
        if progress:
            print(file=sys.stderr)
        return out


BAND_NODES = 5
"""grid spacings outside the surface within which build_grid_sdf's values are exact"""


def build_grid_sdf(
    vertices, faces, spacing: float = 0.01, margin: float = 0.05, progress: str | None = None
) -> GridSDFBody:
    """Grid SDF over the mesh's bounding box grown by ``margin`` [m].

    Nodes inside the body or within ``BAND_NODES`` spacings of its surface get
    exact signed distances. The rest, far outside (proved far by a bounded
    nearest-centroid query; the 24-nearest query for them dominated the build,
    which is now about 3x cheaper), get the band's width plus their grid
    distance to the band: >= the band like the exact value, so the contact,
    which acts within its 1 cm offset, sees the same body. The B-spline reads
    nodes at most 2 spacings away, so it is bit-identical to the all-exact
    grid everywhere inside the body and within 3 spacings outside it."""
    from scipy import ndimage

    V = np.asarray(vertices, dtype=np.float64)
    lo = V.min(axis=0) - margin
    hi = V.max(axis=0) + margin
    shape = tuple(int(n) for n in np.ceil((hi - lo) / spacing).astype(int) + 1)
    axes = [lo[d] + spacing * np.arange(shape[d]) for d in range(3)]
    P = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    dist = TriangleMeshDistance(V, faces)
    band = BAND_NODES * spacing
    dc, _ = dist.tree.query(P, k=1, distance_upper_bound=band + dist.reach)
    far = ~np.isfinite(dc).reshape(shape)
    # far nodes cut off from the grid's border by the band lie inside the body
    labels, _ = ndimage.label(far)
    border = np.zeros(shape, bool)
    border[[0, -1], :, :] = border[:, [0, -1], :] = border[:, :, [0, -1]] = True
    outside = far & np.isin(labels, np.unique(labels[border & far]))
    exact = ~outside.reshape(-1)
    values = np.empty(len(P))
    values[exact] = dist(np.ascontiguousarray(P[exact]), progress=progress)
    values = values.reshape(shape)
    values[outside] = band + ndimage.distance_transform_edt(outside)[outside] * spacing
    return GridSDFBody(origin=lo, spacing=float(spacing), values=values)


def load_mannequin_mesh(name: str = "default"):
    """(vertices (n, 3), faces (m, 3)) of a body [m], y up: the embedded A-pose
    mannequin, or a graded body of :mod:`couture.bodies` by name."""
    from couture import bodies

    return bodies.load_mesh(name)


def cache_dir() -> Path:
    return Path(os.environ.get("COUTURE_CACHE", Path.home() / ".cache" / "couture"))


_SDF_LOADED: dict[tuple[str, int, int, float, float, str], GridSDFBody] = {}
"""grid SDFs this process has loaded, by body mesh file (path, mtime, size), spacing, margin and cache folder"""


def load_mannequin_sdf(
    spacing: float = 0.01, margin: float = 0.05, verbose: bool = True, name: str = "default"
) -> GridSDFBody:
    """A body's grid SDF (the default mannequin, or the graded body ``name``),
    from the cache or built (and cached, one file per body mesh) now.

    Each call returns a body of its own over the grid this process loaded
    first (its arrays are shared, and nothing writes them): every ClothModel
    on a named body calls this, and reading and decompressing the cached
    file each time took 33 ms of the 41 ms a 300-vertex skirt's model took
    to build (3.5 ms now)."""
    from couture import bodies

    obj = bodies.obj_path(name)
    st = obj.stat()
    key = (str(obj.resolve()), st.st_mtime_ns, st.st_size, float(spacing), float(margin), str(cache_dir()))
    loaded = _SDF_LOADED.get(key)
    if loaded is not None:
        return replace(loaded)
    digest = hashlib.sha1(obj.read_bytes()).hexdigest()[:12]
    stem = "mannequin" if name == "default" else f"body_{name}"
    path = cache_dir() / f"{stem}_sdf_{digest}_{spacing:g}_{margin:g}_v1.npz"
    if path.exists():
        with np.load(path) as z:
            body = GridSDFBody(
                origin=z["origin"], spacing=float(z["spacing"]), values=np.ascontiguousarray(z["values"])
            )
    else:
        V, F = load_mannequin_mesh(name)
        body = build_grid_sdf(V, F, spacing, margin, progress=f"{stem} SDF" if verbose else None)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".tmp{os.getpid()}.npz")
        np.savez_compressed(tmp, origin=body.origin, spacing=body.spacing, values=body.values)
        os.replace(tmp, path)
    _SDF_LOADED[key] = body
    return replace(body)

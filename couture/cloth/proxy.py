"""A hierarchy of ellipsoids bounding the body: the fast collision proxy of
Meng et al. 2010 §4 (papers/meng2010-virtual-try-on.txt).

The body's volume is sampled (grid points inside it) together with its
surface (the mesh vertices and dense points on the triangles, each with its
outward normal). An initial segmentation by body region (head, torso, arms,
legs) gives the top clusters; each cluster is bounded by an ellipsoid
(:func:`fit_ellipsoid`: the minimum-volume enclosing ellipsoid of its points,
so they lie on or inside it) and split in two across one of its principal
axes while its error exceeds the region's threshold (:func:`build_hierarchy`).

The error of a leaf is Meng's maximal normal distance (MND, Eq. 1): for each
body surface point of the cluster, the distance along the body's outward
normal from the point to the ellipsoid surface; reported as max and mean,
separately for the mesh vertices and the points sampled on the triangles.
Also per leaf: the ``overshoot``, the largest distance by which its
ellipsoid's surface stands out of the body (true SDF on points sampled on the
ellipsoid), which bounds how far the proxy's surface lies outside the body
(the other side of a Hausdorff distance). A cluster is split while
max(MND, overshoot) exceeds its threshold.

:class:`EllipsoidProxyBody` is a body like ``couture.cloth.body.GridSDFBody``:
``phi_grad(points) -> (phi, grad)``, the signed distance to the union of the
leaf ellipsoids (exact outside it), plus picking queries (``nearest``,
``raycast``). :func:`load_body_proxy` builds it for a body (the embedded
mannequin or a graded size) once and caches it beside the body's SDF. The
try-on drag slides pieces along it (couture.tryon) and the 3D view picks the
body with its rays (couture.ui.geometry.pick_body).

Everything is SI (metres); y is up on the mannequin, z to its front.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from couture.cloth import proxy_kernels as PK

# ---------------------------------------------------------------- regions

REGION_CLASSES = ("torso", "head", "arms", "legs")
"""threshold classes; a region name maps to its class by prefix ('arm_l' -> 'arms')"""

DEFAULT_THRESHOLDS = {"torso": 0.015, "legs": 0.015, "arms": 0.02, "head": 0.02}
"""[m] maximal normal distance allowed per region class: tight where garments
fit closely (torso, hips), looser on limbs and head (Meng §4.2: thresholds per
region, by the garments to be tried on)"""

# landmarks of the embedded A-pose mannequin [m] (couture/assets/mannequin):
# legs part below the crotch (y ≈ 0), the neck is narrowest at y ≈ 0.6, the
# arms hang clear of the torso for |x| > 0.15 between y = 0.15 and 0.45
MANNEQUIN_CROTCH_Y = -0.02
MANNEQUIN_NECK_Y = 0.58
MANNEQUIN_ARM_X = 0.18
MANNEQUIN_ARM_LOW_Y = 0.1


def mannequin_regions(points: np.ndarray) -> np.ndarray:
    """Region name per point (n, 3) of the embedded mannequin: 'head', 'torso',
    'arm_l', 'arm_r', 'leg_l', 'leg_r' (l: x < 0). Planar cuts at the
    landmarks above."""
    p = np.asarray(points, dtype=np.float64)
    out = np.full(len(p), "torso", dtype=object)
    side = np.where(p[:, 0] < 0, "_l", "_r")
    legs = p[:, 1] < MANNEQUIN_CROTCH_Y
    head = p[:, 1] > MANNEQUIN_NECK_Y
    arms = ~legs & ~head & (np.abs(p[:, 0]) > MANNEQUIN_ARM_X) & (p[:, 1] > MANNEQUIN_ARM_LOW_Y)
    out[legs] = "leg" + side[legs]
    out[head] = "head"
    out[arms] = "arm" + side[arms]
    return out.astype(str)


def region_class(region: str) -> str:
    for c in REGION_CLASSES:
        if region == c or region.startswith(c.rstrip("s")):
            return c
    return region


def threshold_of(region: str, thresholds: dict[str, float]) -> float:
    cls = region_class(region)
    if region in thresholds:
        return float(thresholds[region])
    if cls in thresholds:
        return float(thresholds[cls])
    raise ValueError(f"no threshold for region {region!r} (class {cls!r}); thresholds give {sorted(thresholds)}")


# ---------------------------------------------------------------- one ellipsoid


@dataclass(frozen=True)
class Ellipsoid:
    center: np.ndarray
    """[m], shape (3,)"""
    rot: np.ndarray
    """(3, 3), columns are the axes (orthonormal)"""
    radii: np.ndarray
    """semi-axes [m], shape (3,), along the columns of rot"""

    def local(self, points: np.ndarray) -> np.ndarray:
        """Local coordinates y = Rᵀ (p - c), (n, 3)."""
        return (np.asarray(points, np.float64) - self.center) @ self.rot

    def level(self, points: np.ndarray) -> np.ndarray:
        """Σ (y_i / a_i)², < 1 inside, (n,)."""
        return np.sum((self.local(points) / self.radii) ** 2, axis=1)

    def volume(self) -> float:
        return float(4.0 / 3.0 * np.pi * np.prod(self.radii))

    def surface_points(self, n: int = 400) -> np.ndarray:
        """n points on the surface (a Fibonacci sphere, stretched), (n, 3) [m]."""
        u = fibonacci_sphere(n)
        return self.center + (u * self.radii) @ self.rot.T


def fibonacci_sphere(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    th = np.pi * (1.0 + 5**0.5) * i
    return np.column_stack([r * np.cos(th), r * np.sin(th), z])


def _mvee(P: np.ndarray, tol: float, max_iter: int = 2000) -> tuple[np.ndarray, np.ndarray]:
    """Khachiyan's minimum-volume enclosing ellipsoid of P (m, 3), to relative
    tolerance tol: (center (3,), A (3, 3)) with (p - c)ᵀ A (p - c) <= ~1."""
    m, d = P.shape
    Q = np.vstack([P.T, np.ones(m)])
    u = np.full(m, 1.0 / m)
    for _ in range(max_iter):
        X = (Q * u) @ Q.T
        M = np.einsum("ij,ji->i", Q.T, np.linalg.solve(X, Q))
        j = int(np.argmax(M))
        step = (M[j] - d - 1.0) / ((d + 1.0) * (M[j] - 1.0))
        if step < tol:
            break
        u *= 1.0 - step
        u[j] += step
    c = P.T @ u
    S = (P.T * u) @ P - np.outer(c, c)
    return c, np.linalg.inv(S) / d


def fit_ellipsoid(points: np.ndarray, method: str = "mvee", tol: float = 5e-3) -> Ellipsoid:
    """An ellipsoid bounding points (m, 3) [m]: every point on or inside it.

    'mvee': Khachiyan's minimum-volume enclosing ellipsoid of the convex hull's
    vertices (tightest in volume; 'pca' for fewer than 4 points); 'pca': centred on the points' bounding box
    in their principal frame, axes along the principal directions, radii
    ∝ the spread along each and scaled to enclose. Both end with an exact
    rescale so the farthest point lies on the surface (Khachiyan's tolerance
    does not leave points outside). Degenerate (flat) point sets get a
    thickness of 1e-4 x their size (at least 10 µm)."""
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3 or len(P) < 2:
        raise ValueError(f"fit_ellipsoid needs (m >= 2, 3) points, got shape {P.shape}")
    if not np.isfinite(P).all():
        raise ValueError("fit_ellipsoid: points hold NaN or infinity")
    mean = P.mean(axis=0)
    _, sv, Vt = np.linalg.svd(P - mean, full_matrices=False)
    size = float(np.ptp(P, axis=0).max())
    floor = max(1e-4 * size, 1e-5)
    sv = np.r_[sv, np.zeros(3 - len(sv))]
    if method == "pca" or len(P) < 4 or sv[2] < 1e-9 * max(sv[0], 1e-300):
        R = np.linalg.svd(np.vstack([P - mean, np.zeros((3, 3))]))[2].T  # a full frame for m < 3
        y = (P - mean) @ R
        center = mean + R @ (0.5 * (y.max(axis=0) + y.min(axis=0)))
        spread = np.maximum(0.5 * np.ptp(y, axis=0), floor)
    elif method == "mvee":
        from scipy.spatial import ConvexHull

        hull = P[ConvexHull(P).vertices]
        center, A = _mvee(hull, tol)
        w, R = np.linalg.eigh(A)
        spread = 1.0 / np.sqrt(np.maximum(w, 1e-300))
    else:
        raise ValueError(f"unknown fit method {method!r}; use 'mvee' or 'pca'")
    if np.linalg.det(R) < 0:
        R = R.copy()
        R[:, 2] *= -1.0
    y = (P - center) @ R
    k = float(np.sqrt(np.max(np.sum((y / spread) ** 2, axis=1))))
    radii = np.maximum(spread * k * (1.0 + 1e-9), floor)
    order = np.argsort(-radii)  # largest axis first
    return Ellipsoid(center=center, rot=np.ascontiguousarray(R[:, order]), radii=radii[order])


def normal_distance(ell: Ellipsoid, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Meng's normal distance (Eq. 1): from each point (n, 3) along its unit
    normal (n, 3) to where that line meets the ellipsoid surface [m], (n,).
    A point inside goes outward (the positive root); a point outside goes to
    the nearer crossing along ±normal, or +inf when the line misses."""
    y = ell.local(points) / ell.radii
    d = (np.asarray(normals, np.float64) @ ell.rot) / ell.radii
    A = np.sum(d * d, axis=1)
    B = 2.0 * np.sum(y * d, axis=1)
    C = np.sum(y * y, axis=1) - 1.0
    disc = B * B - 4.0 * A * C
    sq = np.sqrt(np.maximum(disc, 0.0))
    t_plus = (-B + sq) / (2.0 * A)
    t_minus = (-B - sq) / (2.0 * A)
    out = np.where(C <= 0.0, t_plus, np.minimum(np.abs(t_plus), np.abs(t_minus)))
    return np.where(disc < 0.0, np.inf, np.abs(out))


# ---------------------------------------------------------------- samples of the body


@dataclass
class BodySamples:
    """What the hierarchy is fitted to and measured on."""

    volume: np.ndarray
    """grid points inside the body [m], (nv, 3)"""
    surface: np.ndarray
    """mesh vertices then points sampled on the triangles [m], (ns, 3)"""
    normals: np.ndarray
    """outward unit normals at ``surface``, (ns, 3): angle-weighted pseudonormals
    at vertices, face normals at samples"""
    is_vertex: np.ndarray
    """(ns,) bool: True for a mesh vertex, False for a triangle sample"""
    volume_ijk: np.ndarray | None = None
    """(nv, 3) int: lattice indices of the volume points, when they come from a
    regular grid (then each cluster is fitted with its volume grown by one
    cell (face neighbours), so neighbouring ellipsoids overlap across their cut and leave no
    gap inside the body)"""


def sample_triangles(vertices, faces, per_triangle: float = 4.0, seed: int = 0):
    """Points spread uniformly by area on the triangles (about per_triangle per
    triangle on average; fixed seed): (points (k, 3), face normals (k, 3))."""
    V = np.asarray(vertices, np.float64)
    F = np.asarray(faces, np.int64)
    e1 = V[F[:, 1]] - V[F[:, 0]]
    e2 = V[F[:, 2]] - V[F[:, 0]]
    cr = np.cross(e1, e2)
    area = 0.5 * np.linalg.norm(cr, axis=1)
    fn = cr / np.maximum(2.0 * area, 1e-300)[:, None]
    rng = np.random.default_rng(seed)
    k = int(round(per_triangle * len(F)))
    tri = rng.choice(len(F), size=k, p=area / area.sum())
    r1 = np.sqrt(rng.random(k))
    r2 = rng.random(k)
    b0, b1, b2 = 1.0 - r1, r1 * (1.0 - r2), r1 * r2
    P = b0[:, None] * V[F[tri, 0]] + b1[:, None] * V[F[tri, 1]] + b2[:, None] * V[F[tri, 2]]
    return P, fn[tri]


def vertex_normals(vertices, faces) -> np.ndarray:
    """Angle-weighted vertex pseudonormals, unit, (n, 3)."""
    V = np.asarray(vertices, np.float64)
    F = np.asarray(faces, np.int64)
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    fn /= np.maximum(np.linalg.norm(fn, axis=1), 1e-300)[:, None]
    vn = np.zeros_like(V)
    for c in range(3):
        p0 = V[F[:, c]]
        u = V[F[:, (c + 1) % 3]] - p0
        w = V[F[:, (c + 2) % 3]] - p0
        cosang = np.einsum("ij,ij->i", u, w) / np.maximum(np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1), 1e-300)
        np.add.at(vn, F[:, c], fn * np.arccos(np.clip(cosang, -1.0, 1.0))[:, None])
    return vn / np.maximum(np.linalg.norm(vn, axis=1), 1e-300)[:, None]


def body_samples(vertices, faces, sdf, volume_spacing: float = 0.01, per_triangle: float = 4.0) -> BodySamples:
    """Volume grid points (where ``sdf`` < 0) and surface samples of a closed,
    outward-oriented mesh. ``sdf(points) -> phi`` [m], positive outside."""
    V = np.asarray(vertices, np.float64)
    lo, hi = V.min(axis=0), V.max(axis=0)
    axes = [np.arange(lo[d] + 0.5 * volume_spacing, hi[d], volume_spacing) for d in range(3)]
    G = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    I = np.stack(np.meshgrid(*[np.arange(len(a)) for a in axes], indexing="ij"), axis=-1).reshape(-1, 3)
    inside = sdf(G) < 0.0
    S, Sn = sample_triangles(V, faces, per_triangle)
    return BodySamples(
        volume=G[inside],
        volume_ijk=I[inside],
        surface=np.vstack([V, S]),
        normals=np.vstack([vertex_normals(V, faces), Sn]),
        is_vertex=np.r_[np.ones(len(V), bool), np.zeros(len(S), bool)],
    )


# ---------------------------------------------------------------- the hierarchy


@dataclass
class ProxyNode:
    ellipsoid: Ellipsoid
    region: str
    threshold: float
    """[m]"""
    depth: int
    parent: int
    """index of the parent node, -1 for a region's top cluster"""
    children: list[int] = field(default_factory=list)
    n_vertices: int = 0
    n_samples: int = 0
    n_volume: int = 0
    mnd_vertex_max: float = 0.0
    """[m] Meng's maximal normal distance over the cluster's mesh vertices"""
    mnd_vertex_mean: float = 0.0
    mnd_sample_max: float = 0.0
    """[m] the same over the points sampled on the triangles"""
    mnd_sample_mean: float = 0.0
    overshoot: float = 0.0
    """[m] how far the ellipsoid's surface stands out of the body at most"""
    met: bool = True
    """False when splitting stopped at min_points / max_depth above the threshold"""
    cut: tuple[np.ndarray, float] | None = None
    """the split of an inner node: (unit normal u (3,), offset [m]); a point p
    goes to the first child when p·u < offset, else to the second"""

    @property
    def error(self) -> float:
        """[m] what the split criterion compares with the threshold"""
        return max(self.mnd_vertex_max, self.mnd_sample_max, self.overshoot)

    @property
    def is_leaf(self) -> bool:
        return not self.children


def _error(st: dict) -> float:
    return max(st["mnd_vertex_max"], st["mnd_sample_max"], st["overshoot"])


def _cluster_stats(ell, surf, nrm, isv, sdf, n_shell):
    nd = normal_distance(ell, surf, nrm) if len(surf) else np.zeros(0)
    ndv, nds = nd[isv], nd[~isv]
    over = 0.0
    if sdf is not None:
        over = max(0.0, float(np.max(sdf(ell.surface_points(n_shell)))))
    return dict(
        n_vertices=int(isv.sum()),
        n_samples=int((~isv).sum()),
        mnd_vertex_max=float(ndv.max()) if len(ndv) else 0.0,
        mnd_vertex_mean=float(ndv.mean()) if len(ndv) else 0.0,
        mnd_sample_max=float(nds.max()) if len(nds) else 0.0,
        mnd_sample_mean=float(nds.mean()) if len(nds) else 0.0,
        overshoot=over,
    )


class ComponentRegions:
    """Region labels with each region's pieces that the body does not connect
    made regions of their own: the volume points of a region (``regions``,
    planar landmark cuts) are split into 6-connected components of their
    lattice; the largest keeps the name, the others become '<name>#k' (same
    threshold class). A landmark cut that fits one body can catch a distant
    part of another (a graded body's hand hanging below the default
    mannequin's arm landmark, labelled torso): fitted together with the torso,
    its points ended in needle-thin leaves that stood 0.1 m out of the body.
    Any point (``__call__``) takes the label of the nearest volume point of
    its planar region."""

    def __init__(self, regions: Callable[[np.ndarray], np.ndarray], vol: np.ndarray, ijk: np.ndarray):
        from scipy import ndimage
        from scipy.spatial import cKDTree

        self.regions = regions
        base = np.asarray(regions(vol)).astype(object)
        rv = base.copy()
        idx = np.asarray(ijk, np.int64)
        idx = idx - idx.min(axis=0) + 1
        shape = tuple(int(v) for v in idx.max(axis=0) + 2)
        self.trees: dict[str, tuple] = {}
        for name in sorted(set(base.tolist())):
            iv = np.nonzero(base == name)[0]
            grid = np.zeros(shape, bool)
            grid[tuple(idx[iv].T)] = True
            lab, n = ndimage.label(grid)
            if n <= 1:
                continue
            comp = lab[tuple(idx[iv].T)]
            sizes = np.bincount(comp, minlength=n + 1)
            order = np.argsort(-sizes[1:], kind="stable") + 1  # largest first
            names = {int(c): (name if k == 0 else f"{name}#{k}") for k, c in enumerate(order)}
            rv[iv] = [names[int(c)] for c in comp]
            self.trees[name] = (cKDTree(vol[iv]), rv[iv])
        self.volume_labels = rv.astype(str)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        out = np.asarray(self.regions(points)).astype(object)
        for name, (tree, labels) in self.trees.items():
            js = np.nonzero(out == name)[0]
            if len(js):
                _, near = tree.query(np.asarray(points)[js])
                out[js] = labels[near]
        return out.astype(str)


def build_hierarchy(
    samples: BodySamples,
    regions: Callable[[np.ndarray], np.ndarray] | None = None,
    thresholds: dict[str, float] | None = None,
    *,
    sdf: Callable[[np.ndarray], np.ndarray] | None = None,
    method: str = "mvee",
    two_sided: bool = True,
    min_points: int = 3,
    max_depth: int = 20,
    n_shell: int = 600,
    progress: str | None = None,
) -> list[ProxyNode]:
    """Meng's distance-error segmentation: the nodes of the ellipsoid tree
    (region top clusters first, children after their parents).

    regions(points) -> name per point (None: one region 'torso'; the pieces of a
    region the body does not connect are regions of their own when the volume
    points come from a lattice, ``ComponentRegions``); thresholds
    [m] per region name or class (default DEFAULT_THRESHOLDS). A cluster is
    split in two across its longest axis at the median of its volume points,
    while its error (max normal distance over its surface points, and with
    ``two_sided`` the overshoot measured with ``sdf``) exceeds its threshold,
    unless it holds fewer than ``min_points`` points or is
    ``max_depth`` deep (then ``met`` is False)."""
    thresholds = dict(DEFAULT_THRESHOLDS if thresholds is None else thresholds)
    for k, v in thresholds.items():
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"threshold for {k!r} must be a positive length [m], got {v!r}")
    if two_sided and sdf is None:
        raise ValueError("two_sided splitting needs the body's sdf")
    vol, surf, nrm, isv = samples.volume, samples.surface, samples.normals, samples.is_vertex
    if regions is None:
        rv = np.full(len(vol), "torso")
        rs = np.full(len(surf), "torso")
    else:
        if samples.volume_ijk is not None and len(vol):
            labels = ComponentRegions(regions, vol, samples.volume_ijk)
            rv, rs = labels.volume_labels, labels(surf)
        else:
            rv, rs = np.asarray(regions(vol)), np.asarray(regions(surf))
    t0 = time.perf_counter()
    nodes: list[ProxyNode] = []
    stack = []
    for name in sorted(set(rv.tolist()) | set(rs.tolist())):
        thr = threshold_of(name, thresholds)
        stack.append((np.nonzero(rv == name)[0], np.nonzero(rs == name)[0], name, thr, 0, -1))
    over_sdf = sdf if two_sided else None

    grow = None
    if samples.volume_ijk is not None and len(vol):
        ijk = np.asarray(samples.volume_ijk, np.int64) + 1
        dims = ijk.max(axis=0) + 2
        lattice = np.full(tuple(dims), -1, np.int64)
        lattice[tuple(ijk.T)] = np.arange(len(vol))
        # the six face neighbours: enough to close the slab between two halves
        steps = np.array([(0, 0, 0), (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)])

        def grow(iv):
            nb = lattice[tuple((ijk[iv][:, None, :] + steps[None]).reshape(-1, 3).T)]
            return np.unique(nb[nb >= 0])

    def make(iv, isf, grown=True):
        P = np.vstack([vol[iv if grow is None or not grown else grow(iv)], surf[isf]])
        ell = fit_ellipsoid(P, method)
        return ell, _cluster_stats(ell, surf[isf], nrm[isf], isv[isf], over_sdf, n_shell)

    def tight(node, iv, isf):
        """A cluster too small to split: fitted to its own points, without the
        grown volume (a handful of points in a crease, where the cell of
        growth bulges across the crease and out of the body), if that meets
        the threshold; else it stays unmet."""
        if grow is None:
            node.met = False
            return
        try:
            ell, st = make(iv, isf, grown=False)
        except (ValueError, np.linalg.LinAlgError):
            node.met = False
            return
        trial = ProxyNode(ellipsoid=ell, region=node.region, threshold=node.threshold, depth=0, parent=-1, **st)
        if trial.error <= node.threshold:
            node.ellipsoid = ell
            for k, v in st.items():
                setattr(node, k, v)
        else:
            node.met = False

    while stack:
        iv, isf, name, thr, depth, parent = stack.pop()
        ell, st = make(iv, isf)
        node = ProxyNode(ellipsoid=ell, region=name, threshold=thr, depth=depth, parent=parent, n_volume=len(iv), **st)
        idx = len(nodes)
        nodes.append(node)
        if parent >= 0:
            nodes[parent].children.append(idx)
        if node.error <= thr:
            continue
        if len(iv) + len(isf) < min_points or depth >= max_depth:
            tight(node, iv, isf)
            continue
        # the split: across the longest axis at the median of the volume points
        # along it (mass halves; chunks stay compact, so the bulge of their
        # bounding ellipsoids, ~0.37 of a chunk's size, shrinks geometrically;
        # trying all three axes for the smaller worst error made thin slabs)
        u = ell.rot[:, 0]
        pv, ps = vol[iv] @ u, surf[isf] @ u
        # halfway between the two middle values: no point sits on the cut, so
        # membership does not hang on the rounding of p·u
        q = np.sort(pv if len(pv) >= 8 else np.r_[pv, ps])
        allq = np.sort(np.r_[pv, ps])
        mid = q[len(q) // 2]
        j = int(np.searchsorted(allq, mid))
        cut = 0.5 * (allq[j - 1] + allq[j]) if j > 0 else float(mid)
        halves = [(iv[pv < cut], isf[ps < cut]), (iv[pv >= cut], isf[ps >= cut])]
        if any(len(a) + len(b) < 2 for a, b in halves):
            tight(node, iv, isf)
            continue
        node.cut = (u.copy(), cut)
        for a, b in reversed(halves):  # first half popped (and numbered) first
            stack.append((a, b, name, thr, depth + 1, idx))
        if progress and len(nodes) % 200 == 0:
            print(
                f"\r{progress}: {len(nodes)} nodes, {time.perf_counter() - t0:.1f} s",
                end="",
                file=sys.stderr,
                flush=True,
            )
    if progress:
        print(f"\r{progress}: {len(nodes)} nodes, {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
    return nodes


# ---------------------------------------------------------------- the body


class EllipsoidProxyBody:
    """The union of a hierarchy's leaf ellipsoids as a body (positive outside).

    ``phi_grad(points) -> (phi (n,) [m], grad (n, 3))``: min over the leaves of
    each one's exact signed distance (exact outside the union, the depth in
    the deepest ellipsoid inside it); grad is the outward unit normal at the
    closest point of that ellipsoid, the exact gradient of phi wherever one
    ellipsoid wins. No ``phi_hess``: models fall back to their Gauss-Newton
    contact block."""

    def __init__(self, nodes: list[ProxyNode], grid_cell: float | None = 0.03, blend: float = 0.0):
        """grid_cell [m]: cell of the candidate grid that answers phi_grad near
        the body (None: the sphere tree alone); blend [m]: 0 for the exact
        min over the leaves, else a smooth (C¹) min that rounds the creases
        where leaves meet (proxy_kernels._merge), e.g. for contact; there the
        gradient is a blend of two normals, shorter than 1."""
        if not (np.isfinite(blend) and blend >= 0):
            raise ValueError(f"blend must be a length >= 0 [m], got {blend!r}")
        self.blend = float(blend)
        if not nodes:
            raise ValueError("EllipsoidProxyBody needs at least one node")
        self.nodes = nodes
        self.leaves = np.array([i for i, n in enumerate(nodes) if n.is_leaf], dtype=np.int64)
        leaf = [nodes[i].ellipsoid for i in self.leaves]
        self.centers = np.ascontiguousarray([e.center for e in leaf], dtype=np.float64)
        self.rot = np.ascontiguousarray([e.rot for e in leaf], dtype=np.float64)
        self.radii = np.ascontiguousarray([e.radii for e in leaf], dtype=np.float64)
        self.rmax = np.ascontiguousarray(self.radii.max(axis=1))
        self.regions = [nodes[i].region for i in self.leaves]
        # the sphere tree over the hierarchy: each node's ball holds its leaves' ellipsoids
        N = len(nodes)
        self.child0 = np.full(N, -1, np.int64)
        self.child1 = np.full(N, -1, np.int64)
        self.leaf_of = np.full(N, -1, np.int64)
        self.leaf_of[self.leaves] = np.arange(len(self.leaves))
        for i, n in enumerate(nodes):
            if n.children:
                if len(n.children) != 2 or min(n.children) <= i:
                    raise ValueError(f"node {i}: an inner node needs two children after it, has {n.children}")
                self.child0[i], self.child1[i] = n.children
        self.roots = np.array([i for i, n in enumerate(nodes) if n.parent < 0], np.int64)
        self.sph_c = np.ascontiguousarray([n.ellipsoid.center for n in nodes], dtype=np.float64)
        self.sph_r = np.array([n.ellipsoid.radii.max() for n in nodes], dtype=np.float64)
        for i in range(N - 1, -1, -1):  # children come after their parents
            if self.child0[i] >= 0:
                c = [self.child0[i], self.child1[i]]
                self.sph_r[i] = max(np.linalg.norm(self.sph_c[j] - self.sph_c[i]) + self.sph_r[j] for j in c)
        self.grid_origin = None
        if grid_cell is not None:
            self._build_grid(grid_cell)

    def _build_grid(self, cell: float = 0.03, margin: float = 0.1, band: float = 0.06) -> None:
        """Candidate leaves per cell of a regular grid over the leaves' extent
        grown by ``margin`` [m] (cell_candidates), for cells whose centre is
        within ``band`` [m] outside the proxy (or inside it); points elsewhere
        go through the sphere tree."""
        lo = (self.centers - self.rmax[:, None]).min(axis=0) - margin
        hi = (self.centers + self.rmax[:, None]).max(axis=0) + margin
        shape = np.ceil((hi - lo) / cell).astype(np.int64)
        axes = [lo[d] + cell * (np.arange(shape[d]) + 0.5) for d in range(3)]
        C = np.ascontiguousarray(np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3))
        phi_c = self._tree(C, 0.0)[0]
        far = phi_c > band  # the tree answers there: one leaf or two are near
        near = np.nonzero(~far)[0]
        cnt = np.zeros(len(C), np.int64)
        items = []
        for s in range(0, len(near), 4096):  # (cells, leaves) masks a chunk at a time
            idx = near[s : s + 4096]
            keep = np.empty((len(idx), self.n_ellipsoids), dtype=np.bool_)
            PK.cell_candidates(
                np.ascontiguousarray(C[idx]), 0.5 * np.sqrt(3.0) * cell, phi_c[idx],
                self.centers, self.rot, self.radii, self.blend, keep,
            )  # fmt: skip
            cnt[idx] = keep.sum(axis=1)
            items.append(np.nonzero(keep)[1])
        self.grid_origin, self.grid_cell, self.grid_shape = lo, float(cell), shape
        self.cell_start = np.r_[0, np.cumsum(cnt)].astype(np.int64)
        self.cell_far = far
        self.cell_items = np.ascontiguousarray(np.concatenate(items) if items else np.zeros(0), dtype=np.int64)

    def _tree(self, p, blend=None):
        blend = self.blend if blend is None else blend
        phi = np.empty(len(p))
        grad = np.empty((len(p), 3))
        which = np.empty(len(p), np.int64)
        PK.tree_phi_grad(
            p, self.roots, self.child0, self.child1, self.leaf_of, self.sph_c, self.sph_r,
            self.centers, self.rot, self.radii, blend, phi, grad, which,
        )  # fmt: skip
        return phi, grad, which

    @property
    def n_ellipsoids(self) -> int:
        return len(self.leaves)

    def phi_grad_which(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """phi_grad plus the winning leaf's index into ``self.leaves`` (n,)."""
        p = np.ascontiguousarray(points, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points must be (n, 3), got shape {p.shape}")
        if self.grid_origin is None:
            return self._tree(p)
        phi = np.empty(len(p))
        grad = np.empty((len(p), 3))
        which = np.empty(len(p), np.int64)
        out = np.empty(len(p), np.bool_)
        PK.grid_phi_grad(
            p, self.grid_origin, self.grid_cell, self.grid_shape, self.cell_start, self.cell_items, self.cell_far,
            self.centers, self.rot, self.radii, self.blend, phi, grad, which, out,
        )  # fmt: skip
        if out.any():
            phi[out], grad[out], which[out] = self._tree(np.ascontiguousarray(p[out]))
        return phi, grad, which

    def phi_grad_brute(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """phi_grad_which with blend 0, every leaf tried (no tree, no grid): a check."""
        p = np.ascontiguousarray(points, dtype=np.float64)
        phi = np.empty(len(p))
        grad = np.empty((len(p), 3))
        which = np.empty(len(p), np.int64)
        PK.union_phi_grad(p, self.centers, self.rot, self.radii, self.rmax, phi, grad, which)
        return phi, grad, which

    def phi_grad(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        phi, grad, _ = self.phi_grad_which(points)
        return phi, grad

    def nearest(self, points: np.ndarray, max_iter: int = 64) -> tuple[np.ndarray, np.ndarray]:
        """A point on the proxy's surface and the outward normal there, ((n, 3),
        (n, 3)): for a point outside the union the closest one (one exact step);
        a point inside goes to its deepest ellipsoid's surface, which may lie
        inside another one, so it is pushed out again until it is on the
        union's surface (a near point, not always the nearest)."""
        q = np.array(points, dtype=np.float64)
        phi, grad = self.phi_grad(q)
        q -= phi[:, None] * grad
        for _ in range(max_iter):
            phi, g = self.phi_grad(q)
            inside = phi < -1e-9
            if not inside.any():
                break
            q[inside] -= phi[inside, None] * g[inside]
            grad[inside] = g[inside]
        return q, grad

    def raycast(
        self, origins: np.ndarray, directions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """First hit of rays o + t d (t >= 0) with the proxy (picking, dragging):
        (hit (n,) bool, t (n,) [m along unit d], point (n, 3), outward normal
        (n, 3), leaf index (n,), -1 on a miss). A ray starting inside the union
        hits at t = 0."""
        o = np.atleast_2d(np.asarray(origins, np.float64))
        d = np.atleast_2d(np.asarray(directions, np.float64))
        o, d = np.broadcast_arrays(o, d)
        dn = np.linalg.norm(d, axis=1)
        if np.any(dn == 0) or not np.isfinite(d).all() or not np.isfinite(o).all():
            raise ValueError("raycast needs finite origins and nonzero finite directions")
        d = d / dn[:, None]
        # local, scaled: |y + t e|² = 1 per ellipsoid, (n, K)
        y = np.einsum("nkj,kji->nki", o[:, None, :] - self.centers[None], self.rot) / self.radii[None]
        e = np.einsum("nj,kji->nki", d, self.rot) / self.radii[None]
        A = np.sum(e * e, axis=2)
        B = 2.0 * np.sum(y * e, axis=2)
        C = np.sum(y * y, axis=2) - 1.0
        disc = B * B - 4.0 * A * C
        sq = np.sqrt(np.maximum(disc, 0.0))
        t0 = (-B - sq) / (2.0 * A)
        t1 = (-B + sq) / (2.0 * A)
        t = np.where(C <= 0.0, 0.0, np.where((disc >= 0) & (t0 >= 0), t0, np.inf))
        t = np.where((disc < 0) & (C > 0), np.inf, t)
        del t1
        k = np.argmin(t, axis=1)
        tk = t[np.arange(len(o)), k]
        hit = np.isfinite(tk)
        tk = np.where(hit, tk, np.nan)
        pts = o + tk[:, None] * d
        normal = np.full_like(pts, np.nan)
        if hit.any():
            kk = k[hit]
            yl = np.einsum("nj,nji->ni", pts[hit] - self.centers[kk], self.rot[kk]) / self.radii[kk] ** 2
            nw = np.einsum("nij,nj->ni", self.rot[kk], yl)
            normal[hit] = nw / np.linalg.norm(nw, axis=1)[:, None]
        return hit, tk, pts, normal, np.where(hit, k, -1)

    def region_stats(self) -> dict[str, dict]:
        """Per region: leaves, threshold, MND max/mean from vertices and from
        triangle samples, overshoot, leaves that missed their threshold."""
        out: dict[str, dict] = {}
        for i in self.leaves:
            n = self.nodes[i]
            r = out.setdefault(
                n.region,
                dict(
                    threshold_m=n.threshold,
                    n_ellipsoids=0,
                    unmet=0,
                    mnd_vertex_max_m=0.0,
                    mnd_sample_max_m=0.0,
                    overshoot_max_m=0.0,
                    _sv=0.0,
                    _nv=0,
                    _ss=0.0,
                    _ns=0,
                ),
            )
            r["n_ellipsoids"] += 1
            r["unmet"] += int(not n.met)
            r["mnd_vertex_max_m"] = max(r["mnd_vertex_max_m"], n.mnd_vertex_max)
            r["mnd_sample_max_m"] = max(r["mnd_sample_max_m"], n.mnd_sample_max)
            r["overshoot_max_m"] = max(r["overshoot_max_m"], n.overshoot)
            r["_sv"] += n.mnd_vertex_mean * n.n_vertices
            r["_nv"] += n.n_vertices
            r["_ss"] += n.mnd_sample_mean * n.n_samples
            r["_ns"] += n.n_samples
        for r in out.values():
            r["mnd_vertex_mean_m"] = r.pop("_sv") / max(r.pop("_nv"), 1)
            r["mnd_sample_mean_m"] = r.pop("_ss") / max(r.pop("_ns"), 1)
        return out


# ---------------------------------------------------------------- save, load, the mannequin's

_STAT_FIELDS = (
    "threshold",
    "n_vertices",
    "n_samples",
    "n_volume",
    "mnd_vertex_max",
    "mnd_vertex_mean",
    "mnd_sample_max",
    "mnd_sample_mean",
    "overshoot",
)


def save_nodes(path, nodes: list[ProxyNode]) -> None:
    arrays: dict[str, Any] = dict(
        center=np.array([n.ellipsoid.center for n in nodes]),
        rot=np.array([n.ellipsoid.rot for n in nodes]),
        radii=np.array([n.ellipsoid.radii for n in nodes]),
        depth=np.array([n.depth for n in nodes]),
        parent=np.array([n.parent for n in nodes]),
        met=np.array([n.met for n in nodes]),
        cut_u=np.array([n.cut[0] if n.cut else np.full(3, np.nan) for n in nodes]),
        cut_off=np.array([n.cut[1] if n.cut else np.nan for n in nodes]),
        region=np.array(json.dumps([n.region for n in nodes])),
    )
    for f in _STAT_FIELDS:
        arrays[f] = np.array([getattr(n, f) for n in nodes], dtype=np.float64)
    np.savez_compressed(path, **arrays)


def load_nodes(path) -> list[ProxyNode]:
    with np.load(path) as npz:
        z = {k: npz[k] for k in npz.files}  # read each array once
    regions = json.loads(str(z["region"]))
    nodes = []
    for i in range(len(z["depth"])):
        stats: dict[str, Any] = {f: (int(z[f][i]) if f.startswith("n_") else float(z[f][i])) for f in _STAT_FIELDS}
        nodes.append(
            ProxyNode(
                ellipsoid=Ellipsoid(z["center"][i].copy(), z["rot"][i].copy(), z["radii"][i].copy()),
                region=regions[i],
                depth=int(z["depth"][i]),
                parent=int(z["parent"][i]),
                met=bool(z["met"][i]),
                cut=None if np.isnan(z["cut_off"][i]) else (z["cut_u"][i].copy(), float(z["cut_off"][i])),
                **stats,
            )
        )
    for i, n in enumerate(nodes):
        if n.parent >= 0:
            nodes[n.parent].children.append(i)
    return nodes


def build_mannequin_proxy(
    thresholds: dict[str, float] | None = None, verbose: bool = True, name: str = "default", **kw
) -> EllipsoidProxyBody:
    """A body's proxy (the default mannequin, or the graded body ``name`` of
    couture.bodies, which share its pose and so its region landmarks), built
    now (~1 min): volume points from its grid SDF's nodes, overshoot measured
    with the grid SDF."""
    from couture.cloth.body import load_mannequin_mesh, load_mannequin_sdf

    V, F = load_mannequin_mesh(name)
    grid = load_mannequin_sdf(verbose=verbose, name=name)

    def sdf(p):
        return grid.phi_grad(p)[0]

    samples = body_samples(V, F, sdf)
    label = "mannequin proxy" if name == "default" else f"body {name} proxy"
    nodes = build_hierarchy(samples, mannequin_regions, thresholds, sdf=sdf, progress=label if verbose else None, **kw)
    return EllipsoidProxyBody(nodes)


PROXY_VERSION = 6
_LOADED: dict[str, EllipsoidProxyBody] = {}
"""proxies loaded in this process, by cache file (a solver asks once per solve)"""


def load_body_proxy(
    name: str = "default", thresholds: dict[str, float] | None = None, verbose: bool = True, blend: float = 0.0
) -> EllipsoidProxyBody:
    """The ellipsoid proxy of the body ``name`` ('default': the embedded
    mannequin, or a graded body of couture.bodies), from the cache (beside
    the body's SDF: ``$COUTURE_CACHE`` or ``~/.cache/couture``; one file per
    body mesh and thresholds, so another body or an edited mesh gets its own)
    or built and cached now; loaded once per process. blend [m]: its smooth
    min (EllipsoidProxyBody)."""
    from couture import bodies
    from couture.cloth.body import cache_dir

    obj = bodies.obj_path(name)
    thr = dict(DEFAULT_THRESHOLDS if thresholds is None else thresholds)
    key = json.dumps(
        dict(
            t=sorted(thr.items()),
            v=PROXY_VERSION,
            lm=[MANNEQUIN_CROTCH_Y, MANNEQUIN_NECK_Y, MANNEQUIN_ARM_X, MANNEQUIN_ARM_LOW_Y],
        )
    )
    digest = hashlib.sha1(obj.read_bytes() + key.encode()).hexdigest()[:12]
    stem = "mannequin" if name == "default" else f"body_{name}"
    path = cache_dir() / f"{stem}_proxy_{digest}_v{PROXY_VERSION}.npz"
    cache_key = f"{path}|{float(blend)!r}"
    if cache_key in _LOADED:
        return _LOADED[cache_key]
    if path.exists():
        nodes = load_nodes(path)
    else:
        nodes = build_mannequin_proxy(thr, verbose=verbose, name=name).nodes
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".tmp{os.getpid()}.npz")
        save_nodes(tmp, nodes)
        os.replace(tmp, path)
    body = _LOADED[cache_key] = EllipsoidProxyBody(nodes, blend=blend)
    return body


def load_mannequin_proxy(
    thresholds: dict[str, float] | None = None, verbose: bool = True, blend: float = 0.0
) -> EllipsoidProxyBody:
    """The embedded mannequin's proxy (load_body_proxy('default'))."""
    return load_body_proxy("default", thresholds, verbose, blend)

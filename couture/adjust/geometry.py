"""Triangle shapes, flattening and embedding for pattern adjustment (Bartle et al. 2016 §4).

Every triangle is handled as a 2x2 *edge matrix*: its two edge vectors
``p1 - p0`` and ``p2 - p0`` as columns, in a 2D frame. A 3D triangle's frame
puts the first edge on the x axis and the triangle in the upper half plane
(the paper's footnote 1: ``[[|u|, |v| cos θ], [0, |v| sin θ]]``); a pattern
triangle keeps its pattern coordinates (a rotation on the left changes
nothing the fixed point uses).

- :func:`lscm` and :func:`arap_embed`: per-panel flattening (least squares
  conformal maps, then ARAP local-global, Liu et al. 2008) and the embedding
  of a set of disconnected target triangles back into connected panels;
- :func:`stretch`: Bartle's eq. 8 per triangle;
- :class:`SurfaceDistance`: exact point-to-surface distances, for Hausdorff
  distances and sliding points along a surface.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .kernels import closest_points_candidates


def frames3(x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Edge matrices of 3D triangles in their own frames, shape (m, 2, 2):
    ``[[|e1|, e2·x̂], [0, e2·ŷ]]`` with x̂ along e1 and ŷ in the triangle's plane."""
    p0, p1, p2 = x[tris[:, 0]], x[tris[:, 1]], x[tris[:, 2]]
    e1, e2 = p1 - p0, p2 - p0
    l1 = np.linalg.norm(e1, axis=1)
    xh = e1 / l1[:, None]
    a = np.einsum("ij,ij->i", e2, xh)
    h = np.linalg.norm(e2 - a[:, None] * xh, axis=1)
    t = np.zeros((len(tris), 2, 2))
    t[:, 0, 0], t[:, 0, 1], t[:, 1, 1] = l1, a, h
    return t


def edges2(X: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Edge matrices of 2D triangles in pattern coordinates, shape (m, 2, 2)."""
    return np.stack([X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 0]]], axis=2)


def areas(t: np.ndarray) -> np.ndarray:
    """Signed areas of triangles given as edge matrices (m, 2, 2)."""
    return 0.5 * np.linalg.det(t)


def principal_stretches(F: np.ndarray) -> np.ndarray:
    """Singular values (descending) of 2x2 maps, shape (m, 2)."""
    return np.linalg.svd(F, compute_uv=False)


def stretch(t_target: np.ndarray, t_current: np.ndarray) -> np.ndarray:
    """Bartle's eq. 8 per triangle: ``1 - sqrt((λ1 - 1)² + (λ2 - 1)²)`` with λ
    the principal stretches of ``t_target t_current⁻¹`` (the map from the
    current triangle onto the target one). 1 for congruent triangles.

    The paper names the eigenvalues of that matrix; in the aligned frames it
    is upper triangular, so its eigenvalues are the two axis ratios and miss
    shear. We take its singular values (the principal stretches), which are
    frame independent and include shear: never more lenient."""
    lam = principal_stretches(t_target @ np.linalg.inv(t_current))
    return 1.0 - np.sqrt(((lam - 1.0) ** 2).sum(axis=1))


def _gradients(tref: np.ndarray) -> np.ndarray:
    """Hat-function gradients per triangle vertex in the reference frame, (m, 3, 2):
    a linear map's Jacobian is ``J = sum_k X_k ⊗ g_k``."""
    G = np.linalg.inv(tref)  # rows: gradients of the barycentric coordinates of vertices 1 and 2
    g = np.empty((len(tref), 3, 2))
    g[:, 1], g[:, 2] = G[:, 0], G[:, 1]
    g[:, 0] = -G[:, 0] - G[:, 1]
    return g


def _components(n: int, tris: np.ndarray) -> np.ndarray:
    from scipy.sparse.csgraph import connected_components

    i = np.concatenate([tris[:, 0], tris[:, 1], tris[:, 2]])
    j = np.concatenate([tris[:, 1], tris[:, 2], tris[:, 0]])
    A = sp.coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    return connected_components(A, directed=False)[1]


def lscm(x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Least squares conformal map of a 3D triangle mesh (Lévy et al. 2002) to
    the plane, each connected piece with two far-apart vertices pinned at their
    3D distance; returns (n, 2) [m]. Vertices in no triangle stay at 0."""
    n = len(x)
    tref = frames3(x, tris)
    g = _gradients(tref)
    w = np.sqrt(np.abs(areas(tref)))
    m = len(tris)
    rows, cols, vals = [], [], []
    # Cauchy-Riemann: J00 - J11 = 0 and J01 + J10 = 0, with J[d, c] = sum_k X_k[d] g_k[c]
    for k in range(3):
        v = tris[:, k]
        r0, r1 = np.arange(m), m + np.arange(m)
        rows += [r0, r0, r1, r1]
        cols += [v, n + v, v, n + v]
        vals += [w * g[:, k, 0], -w * g[:, k, 1], w * g[:, k, 1], w * g[:, k, 0]]
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(2 * m, 2 * n))
    comp = _components(n, tris)
    used = np.zeros(n, bool)
    used[tris.ravel()] = True
    pins, pin_val = [], []
    for c in np.unique(comp[used]):
        idx = np.nonzero((comp == c) & used)[0]
        a = idx[np.argmax(np.linalg.norm(x[idx] - x[idx[0]], axis=1))]
        b = idx[np.argmax(np.linalg.norm(x[idx] - x[a], axis=1))]
        pins += [a, b, n + a, n + b]
        pin_val += [0.0, float(np.linalg.norm(x[b] - x[a])), 0.0, 0.0]
    unused = np.nonzero(~used)[0]
    pins += list(unused) + list(n + unused)
    pin_val += [0.0] * (2 * len(unused))
    pins_a = np.asarray(pins)
    free = np.setdiff1d(np.arange(2 * n), pins_a)
    z = np.zeros(2 * n)
    z[pins_a] = pin_val
    Af, Ap = A[:, free], A[:, pins_a]
    rhs = -(Ap @ z[pins_a])
    N = (Af.T @ Af).tocsc()
    z[free] = splu(N).solve(Af.T @ rhs)
    X = np.column_stack([z[:n], z[n:]])
    # the pins sit at their 3D chord distance, which makes a curved piece too
    # small: scale each piece to its 3D area (an isometric flattening, where
    # one exists, is conformal and so is then found exactly)
    a3 = np.abs(areas(tref))
    a2 = np.abs(areas(edges2(X, tris)))
    tri_comp = comp[tris[:, 0]]
    for c in np.unique(tri_comp):
        sel = tri_comp == c
        idx = comp == c
        X[idx] = X[idx][0] + (X[idx] - X[idx][0]) * np.sqrt(a3[sel].sum() / a2[sel].sum())
    return X


def _polar_rotations(J: np.ndarray) -> np.ndarray:
    """Closest rotations (det +1) to 2x2 matrices, (m, 2, 2)."""
    U, _, Vt = np.linalg.svd(J)
    R = U @ Vt
    bad = np.linalg.det(R) < 0
    if bad.any():
        U = U.copy()
        U[bad, :, 1] *= -1
        R[bad] = U[bad] @ Vt[bad]
    return R


class Embedding:
    """ARAP embedding (Liu et al. 2008) of reference triangles into connected
    2D panels: minimize ``sum_t A_t |J_t(X) - R_t|²`` over X and rotations
    R_t, with ``J_t = E_t(X) tref_t⁻¹`` the map from the reference triangle
    (edge matrix ``tref_t``) to the embedded one. The global step's matrix
    (a cotangent Laplacian of the reference triangles) is factored once.
    One vertex per connected piece is held (translation); rotations follow
    the local fits."""

    def __init__(self, tris: np.ndarray, tref: np.ndarray, n: int, hold: np.ndarray | None = None):
        self.tris = np.asarray(tris)
        self.n = n
        m = len(tris)
        g = _gradients(tref)
        self.w = np.sqrt(np.abs(areas(tref)))
        rows = np.concatenate([np.arange(m) * 2 + c for _k in range(3) for c in range(2)])
        cols = np.concatenate([tris[:, k] for k in range(3) for _c in range(2)])
        vals = np.concatenate([self.w * g[:, k, c] for k in range(3) for c in range(2)])
        K = sp.csr_matrix((vals, (rows, cols)), shape=(2 * m, n))
        if hold is None:
            comp = _components(n, tris)
            used = np.zeros(n, bool)
            used[tris.ravel()] = True
            hold = np.array([np.nonzero((comp == c) & used)[0][0] for c in np.unique(comp[used])])
            hold = np.concatenate([hold, np.nonzero(~used)[0]])
        self.hold = np.asarray(hold, np.int64)
        self.free = np.setdiff1d(np.arange(n), self.hold)
        self.K = K
        self.Kf, self.Kh = K[:, self.free], K[:, self.hold]
        self.lu = splu((self.Kf.T @ self.Kf).tocsc())
        self.tref_inv = np.linalg.inv(tref)

    def jacobians(self, X: np.ndarray) -> np.ndarray:
        return edges2(X, self.tris) @ self.tref_inv

    def energy(self, X: np.ndarray) -> float:
        J = self.jacobians(X)
        R = _polar_rotations(J)
        return float((self.w**2 * ((J - R) ** 2).sum(axis=(1, 2))).sum())

    def run(self, X0: np.ndarray, iters: int = 50, rtol: float = 1e-10) -> np.ndarray:
        """Local-global iterations from X0 (its held vertices stay), until the
        energy's relative change is below ``rtol`` or ``iters``."""
        X = np.array(X0, dtype=np.float64)
        e_prev = np.inf
        for _ in range(iters):
            R = _polar_rotations(self.jacobians(X))  # local step
            b = (self.w[:, None, None] * R).transpose(0, 2, 1).reshape(-1, 2)  # rows (t, c), columns d
            rhs = self.Kf.T @ (b - self.Kh @ X[self.hold])
            X[self.free] = self.lu.solve(np.ascontiguousarray(rhs))  # global step
            e = self.energy(X)
            if abs(e_prev - e) <= rtol * max(e, 1e-300) or e <= 1e-28:
                break
            e_prev = e
        return X


def flatten(x: np.ndarray, tris: np.ndarray, iters: int = 100) -> np.ndarray:
    """Flatten a 3D mesh, each connected piece apart: LSCM, then ARAP with the
    3D triangles as reference (Liu et al. 2008). Returns (n, 2) [m]."""
    X0 = lscm(x, tris)
    X0 = _orient(X0, tris)
    return Embedding(tris, frames3(x, tris), len(x)).run(X0, iters=iters)


def _orient(X: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Mirror pieces whose triangles came out clockwise (the reference frames are counter-clockwise)."""
    comp = _components(len(X), tris)
    a = areas(edges2(X, tris))
    X = X.copy()
    for c in np.unique(comp[tris[:, 0]]):
        sel = comp[tris[:, 0]] == c
        if a[sel].sum() < 0:
            idx = comp == c
            X[idx, 0] = -X[idx, 0]
    return X


def align_rigid(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """X (k, 2) moved rigidly (rotation + translation, no reflection) onto Y by least squares."""
    cx, cy = X.mean(axis=0), Y.mean(axis=0)
    H = (X - cx).T @ (Y - cy)
    U, _, Vt = np.linalg.svd(H)
    R = (U @ Vt).T
    if np.linalg.det(R) < 0:
        Vt[1] *= -1
        R = (U @ Vt).T
    return (X - cx) @ R.T + cy


class SurfaceDistance:
    """Exact distances from points to a triangle surface: candidate faces are
    every face whose centroid lies within (nearest centroid distance + the
    largest centroid-to-vertex radius), so the closest face is always among them."""

    def __init__(self, V: np.ndarray, F: np.ndarray):
        from scipy.spatial import cKDTree

        self.V = np.ascontiguousarray(V, dtype=np.float64)
        self.F = np.ascontiguousarray(F, dtype=np.int64)
        cent = self.V[self.F].mean(axis=1)
        self.radius = float(np.linalg.norm(self.V[self.F] - cent[:, None], axis=2).max())
        self.tree = cKDTree(cent)

    def closest(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(closest points (k, 3), distances (k,), faces (k,))."""
        P = np.ascontiguousarray(P, dtype=np.float64)
        d0, _ = self.tree.query(P)
        lists = self.tree.query_ball_point(P, d0 + self.radius + 1e-12)
        width = max(len(c) for c in lists)
        cand = np.empty((len(P), width), np.int64)
        for i, c in enumerate(lists):
            cand[i, : len(c)] = c
            cand[i, len(c) :] = c[0]
        q = np.empty_like(P)
        d = np.empty(len(P))
        f = np.empty(len(P), np.int64)
        closest_points_candidates(P, cand, self.V, self.F, q, d, f)
        return q, d, f


def surface_samples(x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Vertices, edge midpoints and centroids of a triangle mesh (what the Hausdorff distance samples)."""
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    return np.concatenate([x[np.unique(tris)], 0.5 * (x[e[:, 0]] + x[e[:, 1]]), x[tris].mean(axis=1)])


def hausdorff(xa: np.ndarray, xb: np.ndarray, tris: np.ndarray, tris_b: np.ndarray | None = None) -> dict:
    """Symmetric Hausdorff and mean distances [m] between two triangle surfaces,
    sampled at vertices, edge midpoints and centroids of each, measured exactly
    to the other surface. Returns {'hausdorff', 'mean', 'a_to_b', 'b_to_a'}."""
    tb = tris if tris_b is None else tris_b
    _, dab, _ = SurfaceDistance(xb, tb).closest(surface_samples(xa, tris))
    _, dba, _ = SurfaceDistance(xa, tris).closest(surface_samples(xb, tb))
    return {
        "hausdorff": float(max(dab.max(), dba.max())),
        "mean": float(0.5 * (dab.mean() + dba.mean())),
        "a_to_b": float(dab.max()),
        "b_to_a": float(dba.max()),
    }

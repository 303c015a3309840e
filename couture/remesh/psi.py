"""Ψ: mesh vertex motion per unit pointer motion for a pattern edit (SC §6).

On the boundary, Ψ is the linear interpolation of the polyline Jacobian
along each drafted polyline edge; inside each panel it is interpolated with
positive mean value coordinates (PMVC, Lipman et al. 2007) of the panel's
boundary (outline and holes). Both maps depend on the mesh only, not on the
edit, so they are precomputed once per mesh as one sparse linear map

    L = [B; W B]   (n x k_total): stacked polyline values -> all mesh vertices

(B: polyline -> boundary vertices, W: boundary -> interior coordinates) and an
edit costs one sparse product. The same L moves the mesh when the pattern
changes (:func:`follow_pattern`), so Ψ·Δd is exactly the mesh motion for a
polyline motion J·Δd: the mesh update is linear in the edit, which is what
first-order sensitivity needs.

Plain mean value coordinates (Floater 2003) are available as
``method='mvc'`` for comparison; they go negative behind non-convex corners
and invert elements there (SC Fig. 8).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from couture.pattern.drafted import DraftedPattern, PanelJacobian
from couture.remesh import kernels
from couture.remesh.meshing import RemeshResult


@dataclass
class PsiCoordinates:
    """Precomputed interpolation of polyline values over a mesh."""

    L: sp.csr_matrix
    """stacked polyline values (all loops of ``RemeshResult.loops``) -> mesh vertices, shape (n, k_total)"""
    W: sp.csr_matrix
    """boundary -> interior coordinates, shape (n_interior, n_boundary); rows sum to 1"""
    boundary: np.ndarray
    """boundary mesh vertices, shape (n_boundary,), int32"""
    interior: np.ndarray
    """interior mesh vertices, shape (n_interior,), int32"""
    loop_keys: list[tuple[str, int]]
    """(panel name, loop) of each stacked loop; loop 0 = outline, j + 1 = hole j"""
    loop_offsets: np.ndarray
    """first stacked polyline index of each loop, shape (n_loops + 1,)"""
    method: str
    precompute_s: float
    """wall time of the coordinate precompute [s]"""

    @property
    def n_vertices(self) -> int:
        return self.L.shape[0]

    def stack(self, per_loop: dict[tuple[str, int], np.ndarray], width: int) -> np.ndarray:
        """Stack per-loop arrays (k_loop, width) in loop order; missing loops are zero."""
        out = np.zeros((int(self.loop_offsets[-1]), width))
        for i, key in enumerate(self.loop_keys):
            v = per_loop.get(key)
            if v is not None:
                v = np.asarray(v, np.float64).reshape(len(v), -1)
                if len(v) != self.loop_offsets[i + 1] - self.loop_offsets[i]:
                    raise ValueError(
                        f"{key}: {len(v)} polyline values, the mesh was built from "
                        f"{self.loop_offsets[i + 1] - self.loop_offsets[i]}"
                    )
                out[self.loop_offsets[i] : self.loop_offsets[i + 1]] = v
        return out


def build_coordinates(result: RemeshResult, method: str = "pmvc") -> PsiCoordinates:
    """Precompute the interpolation (``method`` 'pmvc' or 'mvc') for a mesh."""
    if method not in ("pmvc", "mvc"):
        raise ValueError(f"method must be 'pmvc' or 'mvc', got {method!r}")
    t0 = time.perf_counter()
    mesh = result.mesh
    X = mesh.X
    n = len(X)
    B = result.boundary_matrix()
    boundary = result.boundary_vertices()
    is_b = np.zeros(n, bool)
    is_b[boundary] = True
    interior = np.flatnonzero(~is_b).astype(np.int32)
    row_of_interior = np.full(n, -1, np.int64)
    row_of_interior[interior] = np.arange(len(interior))

    kernel = kernels.pmvc_dense if method == "pmvc" else kernels.mvc_dense
    rows, cols, vals = [], [], []
    b_off = 0
    for pi in range(len(mesh.panel_names)):
        loops = result.panel_loops(pi)
        chains = [lp.chain for lp in loops]
        nb = sum(len(c) for c in chains)
        local_edges, off = [], 0
        for c in chains:
            k = len(c)
            local_edges.append(off + np.column_stack([np.arange(k), (np.arange(k) + 1) % k]))
            off += k
        P = X[np.concatenate(chains)]
        E = np.concatenate(local_edges).astype(np.int64)
        verts = result.panel_vertices[pi]
        inner = verts[~is_b[verts]]
        if len(inner):
            Wd = np.empty((len(inner), nb))
            kernel(P, E, np.ascontiguousarray(X[inner]), Wd)
            r, c = np.nonzero(Wd)
            rows.append(row_of_interior[inner][r])
            cols.append(b_off + c)
            vals.append(Wd[r, c])
        b_off += nb
    W = sp.csr_matrix(
        (
            np.concatenate(vals) if vals else np.zeros(0),
            (np.concatenate(rows) if rows else np.zeros(0, int), np.concatenate(cols) if cols else np.zeros(0, int)),
        ),
        shape=(len(interior), len(boundary)),
    )
    # L: polyline -> all vertices, rows in mesh vertex order
    Lb = B.tocoo()
    Li = (W @ B).tocoo()
    L = sp.csr_matrix(
        (
            np.concatenate([Lb.data, Li.data]),
            (np.concatenate([boundary[Lb.row], interior[Li.row]]), np.concatenate([Lb.col, Li.col])),
        ),
        shape=(n, B.shape[1]),
    )
    L.sum_duplicates()
    offsets = np.cumsum([0] + [lp.n_poly for lp in result.loops])
    keys = [(mesh.panel_names[lp.panel], lp.loop) for lp in result.loops]
    return PsiCoordinates(
        L=L,
        W=W,
        boundary=boundary,
        interior=interior,
        loop_keys=keys,
        loop_offsets=offsets,
        method=method,
        precompute_s=time.perf_counter() - t0,
    )


def interpolate(coords: PsiCoordinates, poly_values: np.ndarray) -> np.ndarray:
    """Interpolate stacked polyline values (k_total, ...) to all mesh vertices (n, ...)."""
    v = np.asarray(poly_values, np.float64)
    shape = v.shape[1:]
    return np.asarray(coords.L @ v.reshape(len(v), -1)).reshape((coords.n_vertices,) + shape)


def psi(coords: PsiCoordinates, jacobians: dict[str, PanelJacobian]) -> np.ndarray:
    """Ψ for one edit: per-vertex 2x2 tensors, shape (n, 2, 2), so that the mesh
    moves by ``psi[i] @ dd`` [m] for a pointer motion dd [m]. Panels missing
    from ``jacobians`` stay put."""
    per_loop = {}
    for name, jac in jacobians.items():
        per_loop[(name, 0)] = np.asarray(jac.outline).reshape(-1, 4)
        for j, h in enumerate(jac.holes):
            per_loop[(name, j + 1)] = np.asarray(h).reshape(-1, 4)
    J = coords.stack(per_loop, 4)
    return np.asarray(coords.L @ J).reshape(-1, 2, 2)


def follow_pattern(coords: PsiCoordinates, drafted: DraftedPattern) -> np.ndarray:
    """Rest positions X (n, 2) [m] of the same mesh moved to an edited pattern
    (same polyline vertex counts): boundary on the new polylines, interior by
    the precomputed coordinates. Linear in the polylines, so for an edit with
    Jacobian J it moves by exactly Ψ·Δd up to the pattern's own nonlinearity."""
    per_loop = {}
    for p in drafted.panels:
        per_loop[(p.name, 0)] = p.outline
        for j, h in enumerate(p.holes):
            per_loop[(p.name, j + 1)] = h
    missing = [k for k in coords.loop_keys if k not in per_loop]
    if missing:
        raise KeyError(f"follow_pattern: the edited pattern lacks loops {missing}")
    return interpolate(coords, coords.stack(per_loop, 2))

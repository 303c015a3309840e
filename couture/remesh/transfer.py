"""Barycentric maps between meshes of the same pattern, in the 2D domain.

Used for (a) carrying the simulation state (3D positions, velocities, any
per-vertex field) onto a fresh mesh after a full remesh (SC §6) and (b) the
coarse <-> fine maps of cascadic refinement (SC §7.1). Points are located in
the 2D rest domain with a uniform grid; a point outside every triangle (round
off at the boundary, or a boundary that moved) takes the nearest triangle's
closest point. Panel-aware: with panel ids a point only looks in triangles of
its own panel, since panels are separate pieces of cloth even where their
drafted outlines overlap in the plane.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from couture.mesh import GarmentMesh
from couture.remesh import kernels


def locate_points(
    X: np.ndarray,
    tris: np.ndarray,
    P: np.ndarray,
    *,
    tri_group: np.ndarray | None = None,
    point_group: np.ndarray | None = None,
    tol: float = 1e-10,
) -> tuple[np.ndarray, np.ndarray]:
    """Containing (or nearest) triangle of each point and its barycentrics.

    Returns (tri (p,) int64, bary (p, 3) float64); bary is clamped to the
    triangle (non-negative, sums to 1). With ``tri_group`` (m,) and
    ``point_group`` (p,), a point only considers triangles of its group.
    """
    X = np.ascontiguousarray(X, np.float64)
    T = np.ascontiguousarray(tris, np.int64)
    P = np.ascontiguousarray(P, np.float64)
    tri_out = np.full(len(P), -1, np.int64)
    bary_out = np.zeros((len(P), 3))
    if tri_group is None or point_group is None:
        groups = [(np.arange(len(T)), np.arange(len(P)))]
    else:
        tri_group = np.asarray(tri_group)
        point_group = np.asarray(point_group)
        groups = [(np.flatnonzero(tri_group == g), np.flatnonzero(point_group == g)) for g in np.unique(point_group)]
    for tsel, psel in groups:
        if len(psel) == 0:
            continue
        if len(tsel) == 0:
            raise ValueError("locate_points: a point group has no triangles")
        Tg = T[tsel]
        used = np.unique(Tg)
        lo = X[used].min(axis=0)
        hi = X[used].max(axis=0)
        ext = np.maximum(hi - lo, 1e-12)
        cell = float(np.sqrt(ext[0] * ext[1] / len(Tg)) * 2.0) or float(ext.max())
        nx = int(np.clip(np.ceil(ext[0] / cell), 1, 4096))
        ny = int(np.clip(np.ceil(ext[1] / cell), 1, 4096))
        cell = float(max(ext[0] / nx, ext[1] / ny))
        count, items = kernels.build_grid(X, Tg, lo, cell, nx, ny)
        t_loc = np.empty(len(psel), np.int64)
        b_loc = np.empty((len(psel), 3))
        kernels.locate(X, Tg, count, items, lo, cell, nx, ny, np.ascontiguousarray(P[psel]), t_loc, b_loc, tol)
        tri_out[psel] = tsel[t_loc]
        bary_out[psel] = b_loc
    bary_out = np.clip(bary_out, 0.0, None)
    bary_out /= bary_out.sum(axis=1, keepdims=True)
    return tri_out, bary_out


def interpolation_matrix(tris: np.ndarray, tri: np.ndarray, bary: np.ndarray, n_source: int) -> sp.csr_matrix:
    """Sparse (p, n_source) matrix applying a (tri, bary) map to per-vertex fields."""
    T = np.asarray(tris, np.int64)
    p = len(tri)
    rows = np.repeat(np.arange(p), 3)
    return sp.csr_matrix((bary.ravel(), (rows, T[tri].ravel())), shape=(p, n_source))


def apply_map(tris: np.ndarray, tri: np.ndarray, bary: np.ndarray, field: np.ndarray) -> np.ndarray:
    """Evaluate a per-vertex field of the source mesh (n_source, ...) at the mapped points (p, ...)."""
    field = np.asarray(field)
    T = np.asarray(tris, np.int64)[tri]  # (p, 3)
    b = bary.reshape(bary.shape + (1,) * (field.ndim - 1))
    return (field[T] * b).sum(axis=1)


def transfer_state(
    old_X: np.ndarray,
    old_tris: np.ndarray,
    old_fields,
    new_X: np.ndarray,
    *,
    old_tri_panel: np.ndarray | None = None,
    new_vertex_panel: np.ndarray | None = None,
):
    """Carry per-vertex fields from an old mesh to new vertices by barycentric
    interpolation in the 2D rest domain.

    ``old_fields``: one array (n_old, ...) or a dict of them; the result has
    the same form with n_new rows. Pass ``old_tri_panel`` and
    ``new_vertex_panel`` to keep panels apart.
    """
    tri, bary = locate_points(old_X, old_tris, new_X, tri_group=old_tri_panel, point_group=new_vertex_panel)
    if isinstance(old_fields, dict):
        return {k: apply_map(old_tris, tri, bary, v) for k, v in old_fields.items()}
    return apply_map(old_tris, tri, bary, old_fields)


def vertex_panel(mesh: GarmentMesh) -> np.ndarray:
    """Panel index of each vertex (from any incident triangle), shape (n,), int32."""
    out = np.full(mesh.n_vertices, -1, np.int32)
    out[mesh.tris.ravel()] = np.repeat(mesh.tri_panel, 3)
    return out


def prolongation(coarse: GarmentMesh, fine: GarmentMesh) -> tuple[np.ndarray, np.ndarray]:
    """Coarse -> fine map: for each fine vertex, a coarse triangle of the same
    panel and barycentrics, (parent_tri (nf,) int64, bary (nf, 3) float64)."""
    _check_panels(coarse, fine)
    return locate_points(coarse.X, coarse.tris, fine.X, tri_group=coarse.tri_panel, point_group=vertex_panel(fine))


def restriction(fine: GarmentMesh, coarse: GarmentMesh) -> tuple[np.ndarray, np.ndarray]:
    """Fine -> coarse map by interpolation: for each coarse vertex, a fine
    triangle of the same panel and barycentrics (parent_tri (nc,), bary (nc, 3))."""
    _check_panels(coarse, fine)
    return locate_points(fine.X, fine.tris, coarse.X, tri_group=fine.tri_panel, point_group=vertex_panel(coarse))


def prolong(coarse: GarmentMesh, parent_tri: np.ndarray, bary: np.ndarray, field: np.ndarray) -> np.ndarray:
    """Apply a :func:`prolongation` map to a coarse per-vertex field (nc, ...) -> (nf, ...)."""
    return apply_map(coarse.tris, parent_tri, bary, field)


def restrict(fine: GarmentMesh, parent_tri: np.ndarray, bary: np.ndarray, field: np.ndarray) -> np.ndarray:
    """Apply a :func:`restriction` map to a fine per-vertex field (nf, ...) -> (nc, ...)."""
    return apply_map(fine.tris, parent_tri, bary, field)


def _check_panels(a: GarmentMesh, b: GarmentMesh) -> None:
    if a.panel_names != b.panel_names:
        raise ValueError(f"meshes of different patterns: panels {a.panel_names} vs {b.panel_names}")

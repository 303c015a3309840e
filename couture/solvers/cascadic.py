"""Cascadic coarse-to-fine refinement (SC §7.1, Bornemann & Deuflhard 1996).

Converge the coarse mesh, prolongate its drape to the fine mesh through a map
fine vertex -> (coarse triangle, barycentric weights) in the 2D pattern domain
(the remesher owns these maps), continue on the fine mesh. ``on_level`` is
called after each level so a node can publish drape/coarse, then drape/fine.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .base import SolveResult


@dataclass
class Prolongation:
    """fine vertex i lies in coarse triangle ``tri[i]`` with barycentric ``bary[i]`` (in X)."""

    tri: np.ndarray
    """coarse triangle index per fine vertex, shape (n_fine,), int"""
    bary: np.ndarray
    """barycentric weights, shape (n_fine, 3), rows sum to 1"""

    def apply(self, coarse_tris: np.ndarray, x_coarse: np.ndarray) -> np.ndarray:
        """Fine positions (n_fine, 3) from coarse positions (n_coarse, 3)."""
        v = coarse_tris[self.tri]
        return np.einsum("ij,ijk->ik", self.bary, x_coarse[v])


def locate(coarse_X: np.ndarray, coarse_tris: np.ndarray, fine_X: np.ndarray) -> Prolongation:
    """Point location of fine rest positions in the coarse 2D mesh (for tests and
    scripts; the remesher provides this map for garments). Points outside every
    triangle (curved boundaries) take the nearest triangle's clamped weights."""
    from scipy.spatial import cKDTree

    P = coarse_X[coarse_tris]  # (m, 3, 2)
    cent = P.mean(axis=1)
    tree = cKDTree(cent)
    k = min(12, len(coarse_tris))
    _, cand = tree.query(fine_X, k=k)
    cand = cand.reshape(len(fine_X), k)
    best_tri = np.zeros(len(fine_X), np.int64)
    best_bary = np.zeros((len(fine_X), 3))
    best_score = np.full(len(fine_X), -np.inf)
    for c in range(k):
        t = cand[:, c]
        a, b, cc = P[t, 0], P[t, 1], P[t, 2]
        v0, v1, v2 = b - a, cc - a, fine_X - a
        d00 = np.einsum("ij,ij->i", v0, v0)
        d01 = np.einsum("ij,ij->i", v0, v1)
        d11 = np.einsum("ij,ij->i", v1, v1)
        d20 = np.einsum("ij,ij->i", v2, v0)
        d21 = np.einsum("ij,ij->i", v2, v1)
        den = d00 * d11 - d01 * d01
        w1 = (d11 * d20 - d01 * d21) / den
        w2 = (d00 * d21 - d01 * d20) / den
        bary = np.column_stack([1 - w1 - w2, w1, w2])
        score = bary.min(axis=1)  # >= 0 inside
        better = score > best_score
        best_score[better] = score[better]
        best_tri[better] = t[better]
        best_bary[better] = bary[better]
    out = best_score < -1e-9
    if out.any():
        b = np.clip(best_bary[out], 0.0, None)
        best_bary[out] = b / b.sum(axis=1, keepdims=True)
    return Prolongation(tri=best_tri, bary=best_bary)


def solve_cascadic(
    coarse_model,
    fine_model,
    prolong: Prolongation,
    solver,
    x0_coarse: np.ndarray,
    *,
    tol_coarse: float = 1e-3,
    tol_fine: float = 1e-4,
    max_seconds: float = 60.0,
    on_level: Callable[[str, SolveResult], bool | None] | None = None,
    fine_solver=None,
) -> tuple[SolveResult, SolveResult | None]:
    """Coarse solve, prolongation, fine solve. Returns (coarse result, fine result).

    ``on_level(level, result)`` is called with 'coarse' then 'fine'; returning
    True after the coarse level skips the fine solve (a new edit arrived).
    Pinned fine vertices keep their own placement. ``fine_solver`` defaults to
    ``solver``. The fine result's stats get 'prolongation_residual' (the fine
    residual of the prolongated start) and 'coarse_s'.
    """
    res_c = solver.solve(coarse_model, x0_coarse, tol=tol_coarse, max_seconds=max_seconds)
    if on_level is not None and on_level("coarse", res_c):
        return res_c, None
    x_f = prolong.apply(coarse_model.mesh.tris, res_c.x)
    r0 = float(fine_model.relative_residual(x_f))
    remaining = max(1.0, max_seconds - res_c.wall_time)
    res_f = (fine_solver or solver).solve(fine_model, x_f, tol=tol_fine, max_seconds=remaining)
    res_f.stats["prolongation_residual"] = r0
    res_f.stats["coarse_s"] = res_c.wall_time
    if on_level is not None:
        on_level("fine", res_f)
    return res_c, res_f

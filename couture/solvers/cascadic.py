"""Cascadic coarse-to-fine refinement (SC §7.1, Bornemann & Deuflhard 1996).

Converge the coarse mesh, prolongate its drape to the fine mesh through a map
fine vertex -> (coarse triangle, barycentric weights) in the 2D pattern domain
(the remesher owns these maps), polish that start toward fine equilibrium
(``polish_prolongated``: close the fine seams, set per-vertex contact depths),
continue on the fine mesh. ``on_level`` is called after each level so a node
can publish drape/coarse, then drape/fine.
"""

from __future__ import annotations

import math
import time
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


def _contact_targets(fine_model, coarse_model, x_coarse, parent_tri, bary):
    """Target penetration [m] of the offset layer per fine vertex, or None when
    either level has no body. The coarse contact force per unit mass (a pressure
    times 1/area_density) is interpolated barycentrically and scaled by the fine
    vertex mass, then the C² contact law (kernels.contact_law) is inverted."""
    if fine_model.body is None or coarse_model.body is None:
        return None
    phi_c, _ = coarse_model.body.phi_grad(np.ascontiguousarray(x_coarse, dtype=np.float64))
    f_c = coarse_model.contact_normal_force(coarse_model.contact_offset - phi_c)
    m_c = np.asarray(coarse_model.mass, dtype=np.float64)
    press = np.divide(f_c, m_c, out=np.zeros_like(f_c), where=m_c > 0)
    f = np.einsum("ij,ij->i", bary, press[coarse_model.mesh.tris[parent_tri]]) * fine_model.mass
    f = np.where(np.isfinite(f) & (f > 0), f, 0.0)
    k, eps = float(fine_model.contact_stiffness), float(fine_model.contact_smoothing)
    if eps <= 0:
        return f / k
    return np.where(f < 0.5 * k * eps, np.sqrt(2.0 * f * eps / k), f / k + 0.5 * eps)


def _contact_pass(fine_model, x, pen_target, movable, iters=3):
    """Move the movable vertices inside the offset layer along the normalized SDF
    gradient to their target penetration (in place). A few Newton steps on
    phi(x) = offset - target: the body's interpolated SDF is no exact distance
    (one step left errors up to 8e-5 m on the skirt, three leave < 1e-7 m)."""
    idx = np.nonzero(movable)[0]
    if not len(idx):
        return
    phi, g = fine_model.body.phi_grad(np.ascontiguousarray(x[idx]))
    inside = np.isfinite(phi) & (phi < fine_model.contact_offset)
    idx, phi, g = idx[inside], phi[inside], g[inside]
    phi_t = fine_model.contact_offset - pen_target[idx]
    for it in range(iters):
        if it:
            phi, g = fine_model.body.phi_grad(np.ascontiguousarray(x[idx]))
        # |grad phi| < 1 near the body's medial axis (between the legs, in an armpit),
        # where phi / |grad|² would throw a vertex centimetres away: there the move is
        # at most the depth change asked for, |phi_t - phi|, and the next pass goes on
        gl2 = np.maximum(np.einsum("ij,ij->i", g, g), 1.0)
        ok = np.isfinite(phi) & np.isfinite(gl2)
        step = np.where(ok, (phi_t - phi) / np.where(ok, gl2, 1.0), 0.0)
        x[idx] += step[:, None] * g


def _seam_pass(fine_model, x, free, alpha):
    """Close seam gaps: over the free seam vertices, minimize
    sum_s |x_e - (1-w) x_a - w x_b|^2 + sum_i alpha_i |x_i - x_i^0|^2 (in place;
    ``alpha`` a scalar or per-vertex (n,) weights). Pinned seam vertices stay
    and enter the right-hand side."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    st, w = fine_model.seam_stencils, fine_model.seam_w
    ns = len(st)
    W = sp.csr_matrix((w.ravel(), (np.repeat(np.arange(ns), 3), st.ravel())), shape=(ns, fine_model.n))
    verts = np.unique(st)
    var = verts[free[verts]]
    fix = verts[~free[verts]]
    if not len(var):
        return
    Wv = W[:, var]
    a = np.broadcast_to(np.asarray(alpha, dtype=np.float64), (fine_model.n,))[var]
    A = (Wv.T @ Wv + sp.diags(a)).tocsc()
    b = a[:, None] * x[var]
    if len(fix):
        b -= Wv.T @ (W[:, fix] @ x[fix])
    y = splu(A).solve(np.ascontiguousarray(b))
    if np.isfinite(y).all():
        x[var] = y


def polish_prolongated(
    fine_model,
    x_fine: np.ndarray,
    coarse_model,
    x_coarse: np.ndarray,
    parent_tri: np.ndarray,
    bary: np.ndarray,
    *,
    seam_alpha: float = 1e-6,
    seam_hold: float = 1e-2,
    seam_rounds: int = 3,
) -> np.ndarray:
    """A near-equilibrium fine start from the plain prolongation ``x_fine`` of the
    coarse drape ``x_coarse`` (fine vertex i in coarse triangle ``parent_tri[i]``
    with barycentric ``bary[i]``). Returns a new (n_fine, 3) array.

    Why: the plain interpolation is far from fine equilibrium although the coarse
    drape is converged, its residual dominated by seams and contact: (1) the fine
    seam vertices of two sewn panels land on different coarse chords, so the
    stiff fine seam springs (5000 mu) gap; (2) fine vertices inside coarse
    triangles lie on chords cutting into the convex body, and the per-vertex
    contact penalty wants a fine vertex (about 1/6 of a coarse vertex's load)
    shallower than a coarse one.

    What:
    1. contact: the coarse normal contact force per unit mass, interpolated
       barycentrically and times the fine vertex mass, is each fine vertex's
       target normal force; the inverted contact law gives its target
       penetration, and fine vertices inside the offset layer move along the
       SDF gradient to that depth (three Newton steps on phi);
    2. seams: over the seam vertices, minimize the sum of squared seam gaps +
       ``seam_alpha`` * sum |x - x_contact|² (one sparse solve);
    3. a closed seam point averages vertices lying on a curved body, so it can
       end deeper than its targets (small test skirt: 0.24 mm, deeper than any
       coarse vertex, 0.20 mm). Seam vertices deeper than their target are
       pushed out to it and the seams closed again with those vertices held
       (weight ``seam_hold``), up to ``seam_rounds`` times. (Redoing contact on
       all seam vertices instead is undone by the next seam solve: an
       orthogonal projection that removes exactly that gap-opening motion.)
    Pinned vertices never move (the solvers hold them at mesh.x0 anyway); a
    model without seams or without body (either level) skips that step; rows
    that are not finite keep their input.

    On the default skirt this removes the seam and contact error (seam gaps to
    round-off, the deepest fine penetration below the coarse one); what is left
    is membrane force, since the coarse shape is not the fine equilibrium: that
    is the fine solver's work (local Newton on the seam vertices or one full
    Newton step here made the start worse).
    """
    x0 = np.asarray(x_fine, dtype=np.float64)
    x = x0.copy()
    free = np.asarray(fine_model.free, dtype=bool)
    pen_t = _contact_targets(
        fine_model, coarse_model, np.asarray(x_coarse, np.float64), np.asarray(parent_tri), np.asarray(bary, np.float64)
    )
    has_seams = bool(getattr(fine_model, "has_seams", False))
    if pen_t is not None:
        _contact_pass(fine_model, x, pen_t, free)
    if has_seams:
        _seam_pass(fine_model, x, free, seam_alpha)
        if pen_t is not None:
            # a closed seam point averages vertices on a curved body, so it can sit
            # deeper than its targets: push those out and close again with them held
            on_seam = np.zeros(fine_model.n, bool)
            on_seam[np.unique(fine_model.seam_stencils)] = True
            held = np.zeros(fine_model.n, bool)
            for _ in range(seam_rounds):
                phi, _g = fine_model.body.phi_grad(x)
                deep = free & on_seam & (fine_model.contact_offset - phi > pen_t + 1e-7)
                if not deep.any():
                    break
                _contact_pass(fine_model, x, pen_t, deep)
                held |= deep
                _seam_pass(fine_model, x, free, np.where(held, seam_hold, seam_alpha))
    bad = ~np.isfinite(x).all(axis=1)
    x[bad] = x0[bad]
    x[~free] = x0[~free]
    return x


def carry_friction(fine_model, coarse_model, parent_tri: np.ndarray, bary: np.ndarray, x_fine: np.ndarray) -> int:
    """Carry the coarse level's friction state to the fine level ('huber' friction
    only; a no-op otherwise): a fine vertex in contact at ``x_fine`` whose three
    coarse parent vertices are all anchored gets the barycentric mix of their
    anchors, so the fine level measures each vertex's slide from where the coarse
    level first held the cloth instead of releasing friction and settling the
    fine discretization's lift frictionless (whose end, the state where
    friction engaged again, the solver's path decided). Other fine vertices in
    contact are anchored where they are; the Coulomb limits are set from the fine
    contact forces at ``x_fine`` (``ClothModel.lag_friction``). Returns how many
    anchors were carried."""
    if (
        getattr(fine_model, "friction_model", "") != "huber"
        or getattr(coarse_model, "friction_model", "") != "huber"
        or "friction" not in fine_model.terms
        or "friction" not in coarse_model.terms
        or not coarse_model.anchored.any()
    ):
        return 0
    verts = coarse_model.mesh.tris[np.asarray(parent_tri)]
    held = coarse_model.anchored[verts].all(axis=1)
    phi, grad = fine_model.body.phi_grad(np.ascontiguousarray(x_fine, dtype=np.float64))
    carried = held & (phi < fine_model.contact_offset) & np.asarray(fine_model.free, bool)
    fine_model.release_friction()
    a = np.einsum("nk,nkd->nd", np.asarray(bary, np.float64), coarse_model.anchor[verts])
    fine_model.anchor[carried] = a[carried]
    g = grad[carried]
    fine_model.anchor_normal[carried] = g / np.maximum(np.linalg.norm(g, axis=1), 1e-300)[:, None]
    fine_model.anchored[carried] = True
    fine_model.lag_friction(x_fine)
    return int(carried.sum())


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
    The prolongated drape is polished (``polish_prolongated``: seams closed,
    contact depths per fine vertex) before the fine solve; pinned fine vertices
    keep their own placement. ``fine_solver`` defaults to ``solver``. The fine
    result's stats get 'prolongation_residual' (the fine relative residual of
    the polished start), 'prolongation_residual_raw' (that of the plain
    interpolation), 'polish_s' and 'coarse_s'.
    """
    res_c = solver.solve(coarse_model, x0_coarse, tol=tol_coarse, max_seconds=max_seconds, from_placement=True)
    if on_level is not None and on_level("coarse", res_c):
        return res_c, None
    x_raw = prolong.apply(coarse_model.mesh.tris, res_c.x)
    t0 = time.perf_counter()
    x_f = polish_prolongated(fine_model, x_raw, coarse_model, res_c.x, prolong.tri, prolong.bary)
    polish_s = time.perf_counter() - t0
    r_raw = float(fine_model.relative_residual(x_raw))
    carried = carry_friction(fine_model, coarse_model, prolong.tri, prolong.bary, x_f)
    r0 = float(fine_model.relative_residual(x_f))
    remaining = max(1.0, max_seconds - res_c.wall_time - polish_s)
    res_f = (fine_solver or solver).solve(
        fine_model, x_f, tol=tol_fine, max_seconds=remaining, friction_after=math.inf if carried else None
    )
    res_f.stats["prolongation_residual"] = r0
    res_f.stats["prolongation_residual_raw"] = r_raw
    res_f.stats["polish_s"] = polish_s
    res_f.stats["coarse_s"] = res_c.wall_time
    if on_level is not None:
        on_level("fine", res_f)
    return res_c, res_f

"""Physics-driven pattern adjustment (Bartle et al. 2016 §4): the fixed point
``T ← T (t_k)⁻¹ t_target`` per triangle, stitched back into panels by an ARAP
embedding, with any equilibrium solver as a black box.

The simulator is a callable ``simulate(X, x_warm) -> Simulated``: the same
mesh with rest positions X (n, 2), solved to equilibrium from ``x_warm``
(the target, every time: the paper's initialization). It may run in this
process or on a solver node over the bus (``couture.client.SolveFanout``);
nothing here knows which.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from couture.mesh import GarmentMesh

from .geometry import Embedding, align_rigid, edges2, flatten, frames3, hausdorff, stretch
from .seams import equalize_seams, max_seam_mismatch

MANNEQUIN_HEIGHT = 1.666
"""[m] height of the default mannequin (its mesh spans y = -0.817 .. 0.849):
Hausdorff distances are reported in % of it, as in Bartle's Table 1"""


@dataclass
class Simulated:
    """One equilibrium solve of an adjusted pattern."""

    x: np.ndarray
    """drape [m], shape (n, 3)"""
    residual: float
    converged: bool
    solver: str = ""
    """who solved it (a solver node's name, or the in-process method)"""
    wall_time_s: float = 0.0
    diagnosis: str = ""


Simulate = Callable[[np.ndarray, np.ndarray], Simulated]


@dataclass
class Iteration:
    k: int
    """0: the start pattern (:data:`STARTS`); k >= 1: after k fixed-point updates"""
    stretch_mean: float
    """Bartle eq. 8, mean over triangles (1 is perfect)"""
    stretch_min: float
    hausdorff_m: float
    hausdorff_pct: float
    """[% of mannequin height]"""
    mean_distance_m: float
    solver: str
    residual: float
    converged: bool
    simulate_s: float
    update_s: float
    """[s] per-triangle update and embedding that made this iteration's pattern"""
    seam_mismatch_m: float = 0.0
    """[m] largest length difference between the two sides of a seam in the simulated pattern"""
    seam_mismatch_raw_m: float = 0.0
    """[m] the same before the seams were equalized (as the embedding left it)"""
    flipped_triangles: int = 0
    """pattern triangles turned clockwise by the embedding (0: a valid pattern)"""


@dataclass
class AdjustResult:
    X: np.ndarray
    """adjusted pattern (the iterate whose drape is closest to the target: least Hausdorff distance) [m], shape (n, 2)"""
    x: np.ndarray
    """its simulated drape [m], shape (n, 3)"""
    X_start: np.ndarray
    """the pattern of iteration 0 (``start``: the flattening, or the update from the source drape)"""
    x_start: np.ndarray
    """its simulated drape"""
    X_flat: np.ndarray
    """the target flattened per panel (compression undone, eq. 9): Bartle's start, simulated only
    when it is iteration 0's pattern"""
    history: list[Iteration]
    best: int
    """index into history of the returned pattern"""
    stopped: str
    """why the iterations stopped"""
    wall_time_s: float
    patterns: list[np.ndarray] = field(default_factory=list)
    """the pattern of every iteration"""
    drapes: list[np.ndarray] = field(default_factory=list)
    """the simulated drape of every iteration"""
    start: str = "flatten"
    """what iteration 0's pattern is (:data:`STARTS`)"""


def undo_compression(t_target: np.ndarray, t_src3: np.ndarray, T_src: np.ndarray) -> np.ndarray:
    """Bartle eq. 9: where the source simulation compressed a triangle (a
    principal stretch σ < 1 of ``M = t_src3 T_src⁻¹``), scale the initial
    guess by 1/σ along that direction; elsewhere keep the target triangle."""
    M = t_src3 @ np.linalg.inv(T_src)
    U, s, _ = np.linalg.svd(M)
    fix = np.maximum(1.0, 1.0 / s)
    C = U @ (fix[:, :, None] * U.transpose(0, 2, 1))
    return C @ t_target


DIVERGED = 1e-2
"""a solve that stopped above this relative residual, or at a non-finite one, gave no drape (a
time-capped solve a little above its tolerance still did)"""


def solve_or_fail(simulate: Simulate, X: np.ndarray, x_warm: np.ndarray) -> Simulated:
    """``simulate(X, x_warm)``, a solve that failed (the solver's error: a
    factorization that failed at every shift, a node gone) returned as a
    diverged one with the error as its diagnosis: one failed re-simulation
    ends the updates, it does not lose the iterates before it."""
    try:
        return simulate(X, x_warm)
    except RuntimeError as e:
        return Simulated(np.array(x_warm, np.float64), float("inf"), False, diagnosis=f"the solve failed: {e}")


def diverged(s) -> bool:
    """Did this solve (a :class:`Simulated` or an :class:`Iteration`) give no drape at all?"""
    return not s.converged and not (np.isfinite(s.residual) and s.residual <= DIVERGED)


STARTS = ("source", "flatten")
"""iteration 0's pattern: ``'source'``, one fixed-point update from the source pattern and its
drape (every triangle ``T_src (t_src)⁻¹ t_target``); ``'flatten'``, the target flattened (Bartle's)"""


def start_from_source(
    mesh: GarmentMesh, x_source: np.ndarray, t_target: np.ndarray, embed_iters: int = 30
) -> np.ndarray:
    """Iteration 0's pattern from the source: the source pattern ``mesh.X`` was simulated to
    ``x_source`` (the drape the edit started from), so that pair is an iterate of the fixed
    point already, and one update from it, ``T_src (t_src)⁻¹ t_target`` per triangle, embedded
    (ARAP from the source pattern), starts where the source's simulation left off: a triangle the edit
    kept gets its source pattern triangle back exactly, one it moved the rest shape its
    source triangle's deformation maps onto the target's. The flattening starts instead from
    the target's 3D shape, with the stretch of the simulation not undone (eq. 9 undoes only
    compression), which the updates must then remove."""
    tris = mesh.tris
    T0 = fixed_point_update(edges2(mesh.X, tris), frames3(x_source, tris), t_target)
    X = Embedding(tris, T0, mesh.n_vertices).run(mesh.X, iters=embed_iters)
    return align_panels(X, mesh.X, tris, mesh.tri_panel)


def fixed_point_update(T: np.ndarray, t_k: np.ndarray, t_target: np.ndarray) -> np.ndarray:
    """Bartle eqs. 6-7 per triangle: ``T ← T (t_k)⁻¹ t_target``. T: pattern
    triangles (m, 2, 2) as edge matrices; t_k, t_target: simulated and target
    triangles in their aligned frames (:func:`~couture.adjust.geometry.frames3`).
    If the simulation maps each aligned triangle by a fixed A (t_k = A
    aligned(T)), the result simulates to exactly t_target."""
    return T @ np.linalg.inv(t_k) @ t_target


def align_panels(X: np.ndarray, X_ref: np.ndarray, tris: np.ndarray, tri_panel: np.ndarray) -> np.ndarray:
    """Each panel of X moved rigidly onto the same panel of X_ref (for layout and comparison)."""
    out = X.copy()
    for p in np.unique(tri_panel):
        v = np.unique(tris[tri_panel == p])
        out[v] = align_rigid(X[v], X_ref[v])
    return out


def adjust(
    mesh: GarmentMesh,
    x_target: np.ndarray,
    simulate: Simulate,
    *,
    x_source: np.ndarray | None = None,
    max_iters: int = 5,
    stop_stretch: float = 0.995,
    stagnation: float = 1e-3,
    embed_iters: int = 30,
    equalize: bool = True,
    height: float = MANNEQUIN_HEIGHT,
    log: Callable[[str], None] | None = print,
    start: str = "source",
) -> AdjustResult:
    """Find rest positions whose simulated drape reproduces ``x_target``.

    ``mesh`` is the source garment's mesh (its X the source pattern, kept for
    layout and eq. 9 with ``x_source``, the source drape); the target lives on
    its vertices. Iteration 0 simulates the ``start`` pattern: with ``'source'``
    (and ``x_source`` given) one update from the source pattern and its drape
    (:func:`start_from_source`), with ``'flatten'`` the flattening-only pattern
    (ARAP flattening of the target per panel, compression undone as in eq. 9,
    Bartle's start); each further iteration applies the fixed point per triangle, embeds (ARAP,
    warm-started from the current pattern) and simulates again. Stops after
    ``max_iters`` updates, when the mean stretch reaches ``stop_stretch``, or
    when it gains less than ``stagnation``. With ``equalize``, every updated
    pattern's seams are made equally long on both sides
    (:func:`~couture.adjust.seams.equalize_seams`) before it is simulated:
    the embedding alone leaves them up to about 2 % apart. Returns the iterate with the least
    Hausdorff distance to the target."""
    t0 = time.perf_counter()
    tris = mesh.tris
    n = mesh.n_vertices
    t_g = frames3(x_target, tris)
    say = log or (lambda s: None)

    tu = time.perf_counter()
    X = flatten(x_target, tris)
    if x_source is not None:
        t0_tris = undo_compression(t_g, frames3(x_source, tris), edges2(mesh.X, tris))
        if not np.allclose(t0_tris, t_g):
            X = Embedding(tris, t0_tris, n).run(X, iters=embed_iters)
    X = align_panels(X, mesh.X, tris, mesh.tri_panel)
    X_flat = X
    if start not in STARTS:
        raise ValueError(f"start {start!r}: choose one of {STARTS}")
    if start == "source":
        if x_source is None:
            start = "flatten"  # no source drape to update from
        else:
            X = start_from_source(mesh, x_source, t_g, embed_iters)
            if equalize:
                X = align_panels(equalize_seams(mesh, X, reference=mesh.X), mesh.X, tris, mesh.tri_panel)
    update_s = time.perf_counter() - tu
    raw_mismatch = max_seam_mismatch(mesh, X, mesh.X)

    history: list[Iteration] = []
    patterns: list[np.ndarray] = []
    drapes: list[np.ndarray] = []
    stopped = f"{max_iters} iterations"
    for k in range(max_iters + 1):
        sim = solve_or_fail(simulate, X, x_target)
        t_k = frames3(sim.x, tris)
        S = stretch(t_g, t_k)
        H = hausdorff(x_target, sim.x, tris)
        if diverged(sim):  # no drape: nothing measured
            S = np.full_like(S, np.nan)
            H = {"hausdorff": float("inf"), "mean": float("inf")}
        it = Iteration(
            k=k,
            stretch_mean=float(S.mean()),
            stretch_min=float(S.min()),
            hausdorff_m=H["hausdorff"],
            hausdorff_pct=100.0 * H["hausdorff"] / height,
            mean_distance_m=H["mean"],
            solver=sim.solver,
            residual=float(sim.residual),
            converged=bool(sim.converged),
            simulate_s=float(sim.wall_time_s),
            update_s=update_s,
            seam_mismatch_m=max_seam_mismatch(mesh, X, mesh.X),
            seam_mismatch_raw_m=raw_mismatch,
            flipped_triangles=int((np.linalg.det(edges2(X, tris)) <= 0).sum()),
        )
        history.append(it)
        patterns.append(X.copy())
        drapes.append(sim.x)
        say(
            f"[adjust] iteration {k}: stretch {it.stretch_mean:.4f} (min {it.stretch_min:.3f}), "
            f"Hausdorff {1e3 * it.hausdorff_m:.1f} mm = {it.hausdorff_pct:.2f} % of height, "
            f"mean distance {1e3 * it.mean_distance_m:.1f} mm; {sim.solver} residual {sim.residual:.1e}"
            f"{'' if sim.converged else ' (NOT converged: ' + (sim.diagnosis or '?') + ')'}, "
            f"solve {sim.wall_time_s:.1f} s; seams off their drafted ease by {1e3 * it.seam_mismatch_m:.1f} mm"
            + (f" ({1e3 * raw_mismatch:.1f} mm before equalizing)" if raw_mismatch != it.seam_mismatch_m else "")
            + (f"; {it.flipped_triangles} triangles FLIPPED" if it.flipped_triangles else "")
        )
        if diverged(sim):
            stopped = f"the solve of iteration {k} diverged (residual {sim.residual:.1e})"
            break
        if it.stretch_mean >= stop_stretch:
            stopped = f"mean stretch {it.stretch_mean:.4f} >= {stop_stretch}"
            break
        if k >= 1 and it.stretch_mean - history[-2].stretch_mean < stagnation:
            stopped = f"stagnated: mean stretch gained {it.stretch_mean - history[-2].stretch_mean:+.4f} < {stagnation}"
            break
        if k == max_iters:
            break
        tu = time.perf_counter()
        T_new = fixed_point_update(edges2(X, tris), t_k, t_g)
        X = Embedding(tris, T_new, n).run(X, iters=embed_iters)
        X = align_panels(X, mesh.X, tris, mesh.tri_panel)
        raw_mismatch = max_seam_mismatch(mesh, X, mesh.X)
        if equalize:
            X = align_panels(equalize_seams(mesh, X, reference=mesh.X), mesh.X, tris, mesh.tri_panel)
        update_s = time.perf_counter() - tu
    # the stretch drives the iteration; the distance to the target is what the
    # designer sees (Bartle §6), so the iterate returned is the closest one
    # (an iterate whose solve diverged is no drape: chosen only if every one did)
    ok = [h for h in history if not diverged(h)] or history
    best = min(ok, key=lambda h: h.hausdorff_m).k
    return AdjustResult(
        X=patterns[best],
        x=drapes[best],
        X_start=patterns[0],
        x_start=drapes[0],
        X_flat=X_flat,
        history=history,
        best=best,
        stopped=stopped,
        wall_time_s=time.perf_counter() - t0,
        patterns=patterns,
        drapes=drapes,
        start=start,
    )


def with_rest(mesh: GarmentMesh, X: np.ndarray, x0: np.ndarray | None = None) -> GarmentMesh:
    """The same mesh (triangles, panels, seams, pins) with rest positions X and placement x0."""
    return GarmentMesh(
        X=X,
        tris=mesh.tris,
        x0=mesh.x0 if x0 is None else x0,
        tri_panel=mesh.tri_panel,
        panel_names=list(mesh.panel_names),
        panel_grain=mesh.panel_grain,
        seam_emitters=mesh.seam_emitters,
        seam_edges=mesh.seam_edges,
        seam_weights=mesh.seam_weights,
        pinned=mesh.pinned,
        level=mesh.level,
        generation=mesh.generation,
    )


def local_simulator(mesh: GarmentMesh, design, method: str = "newton", tol: float = 1e-4, max_seconds: float = 60.0):
    """A :data:`Simulate` that solves in this process (tests, and a reference for the bus)."""
    from couture.cloth.model import ClothModel
    from couture.solvers import get_solver
    from couture.solvers.service import scene_from_design

    solver = get_solver(method)
    model = ClothModel(mesh, design.fabric, scene_from_design(design))

    def simulate(X: np.ndarray, x_warm: np.ndarray) -> Simulated:
        model.set_rest_positions(np.asarray(X, np.float64))
        # as on a solver node, which receives each solve's mesh with its warm start as the
        # placement (with_rest): every solve starts from its own placement
        # (couture.solvers.service.solve_once)
        r = solver.solve(model, np.array(x_warm, np.float64), tol=tol, max_seconds=max_seconds, from_placement=True)
        return Simulated(r.x, r.residual, r.converged, method, r.wall_time, r.diagnosis)

    return simulate

"""Kinetic damping on Baraff-Witkin semi-implicit steps (SC §7), the reference solver.

Each step solves the linearly implicit backward Euler system on free DOFs

    (M + dt² K) Δv = dt (f - dt K v),   v += Δv,   x += dt v,

with K = model.stiffness(x) (PSD). The motion is undamped except for the
integrator's own numerical damping; whenever the total kinetic energy passes a
local maximum over three consecutive steps the velocity is zeroed (kinetic
damping, Barnes 1988).

Adaptive time step (default). We want statics, not a trajectory, and a
backward Euler step with a PSD system is stable at any dt. dt grows
×``dt_grow`` after every accepted step (step length >= 1/2 after
backtracking) up to ``dt_max`` and shrinks when a step cannot lower the total
energy E + ½vᵀMv even after ``max_backtracks`` halvings (first the velocity
is zeroed, then dt ×``dt_shrink``, not below ``dt_min``) — the one thing a
backward Euler step of a conservative system must not do; it does so only
where the linearization is poor. A step is also clamped to ``max_step`` per
vertex (a trust region: dt, hence the factorization, stays). At large dt the
step from rest is a pseudo-transient-continuation Newton step
(K + M/dt²) Δx = f. ``adaptive=False`` gives SC's fixed steps (5 ms, IC(0)).

Both need the C² contact law and the B-spline body SDF (couture.cloth): with
a C¹ penalty and a trilinear SDF every solver chattered at residual ~0.5.
dt_max = 0.1 s, not more: on a crumpled sheet (random start,
tests/test_solvers_slow.py) larger steps made the projected-Hessian steps
crawl. SC's fixed 5 ms steps stall with friction on (anchors engage on moving
cloth and creep); ``couture bench solver`` compares the two.

Linear solves. 'direct' (default): conjugate gradients preconditioned by a
sparse Cholesky factorization (CHOLMOD / PARDISO / SuperLU, see linalg) of an
earlier step's M + dt² K, refreshed only when CG needs more than
``refactor_iters`` iterations (K and dt drift slowly between steps): one
factorization serves many steps. On the 1.6k-vertex skirt a factorization
costs ~70 ms and a solve with it ~1 ms, so reuse is what makes large steps
cheap. 'ic0': shifted incomplete Cholesky IC(0) of the Jacobi-scaled matrix,
seam emitters ordered first, then receivers (SC §7's ordering for ILU(0)); good
at small dt (M dominates), but its CG iterations grow with dt² K. 'jacobi'.

Why IC(0) with a shift rather than ILU(0): the matrix is SPD, so CG needs a
symmetric preconditioner; plain ILU(0) is not symmetric and, measured on seam
springs ~5000x the fabric, stalls; IC(0) of the raw matrix breaks down (negative
pivots) on the same systems, and a small diagonal shift after Jacobi scaling
(Manteuffel) fixes both. The shift grows only on breakdown.

Friction (quasi-static anchors) follows ``common.FrictionSchedule``, as in
Newton: anchors only once the frictionless residual is below
``friction_after`` (1e-2) or the solve crawls (from a fresh placement the
cloth starts inside the contact layer with normal forces up to ~50 N per
vertex, and anchors created there pinned it in place); every
``friction_every`` (20) steps, anchors pulled beyond mu_s f_n slip under
kinetic friction; at a balance (residual <= tol) slipping vertices stick,
and the state is a static Coulomb equilibrium only if every anchor holds
within mu_s f_n. ``converged`` is decided at return from fresh forces
(``common.verdict``), never by the loop, and a solve that stops returns the
best state it saw (``common.BestState``).
"""

from __future__ import annotations

import logging
import time
from typing import Any

import numpy as np

from .base import ProgressCallback, SolveResult
from .common import (
    BestState,
    FrictionSchedule,
    ResidualScale,
    Watch,
    bad_start,
    energy_and_forces,
    energy_round_off,
    finish,
    finite,
    pinned_positions,
)
from .linalg import (
    IC0,
    FactorizationError,
    ReducedSystem,
    factorize,
    pcg,
    pcg_factor,
    resolve_backend,
    seam_first_order,
)

log = logging.getLogger(__name__)


class KineticSolver:
    name = "kinetic"

    def __init__(
        self,
        dt: float = 0.005,
        *,
        adaptive: bool = True,
        dt_max: float = 0.1,
        dt_min: float = 1e-4,
        dt_grow: float = 1.5,
        dt_shrink: float = 0.25,
        preconditioner: str = "direct",
        backend: str = "auto",
        cg_rtol: float = 1e-3,
        cg_maxiter: int = 300,
        refactor_iters: int = 4,
        stall_window: int = 1500,
        max_displacement: float | None = None,
        max_step: float | None = None,
        friction_every: int = 20,
        friction_after: float = 1e-2,
        crawl_window: int = 50,
        max_backtracks: int = 4,
    ):
        """dt [s] first (or fixed) time step (SC's 5 ms); adaptive: grow/shrink
        dt (module docstring); dt_min, dt_max [s], dt_grow, dt_shrink: its bounds
        and factors; preconditioner 'direct' (factorization reuse), 'ic0' or
        'jacobi'; backend: direct backend ('auto' = best importable);
        cg_rtol relative CG tolerance (inexact steps are fine: only the
        trajectory changes, not the equilibrium); cg_maxiter CG cap per step;
        refactor_iters: CG iterations above which the direct preconditioner is
        refreshed (at least; more where a factorization costs more than
        twice that many iterations); stall_window steps without 1% progress before giving up;
        max_displacement [m] per-step vertex motion that counts as blow-up
        (default: 10x the initial bounding-box diagonal); max_step [m] largest
        vertex move of an accepted adaptive step (default 2% of the diagonal:
        penalty contact must not be stepped through), a larger one is redone
        with a shorter dt; friction_every: anchor refresh period in steps;
        friction_after: friction anchors act only once the relative residual
        is below this (a start above it releases all anchors first) or the
        solve crawls (its residual not halved in ``crawl_window`` steps);
        ``solve(friction_after=...)`` overrides it for one solve;
        max_backtracks: halvings of a step that raised the energy before
        the velocity is zeroed or dt shortened (keeps dt, hence the
        factorization, through isolated bad steps)."""
        if preconditioner not in ("direct", "ic0", "jacobi"):
            raise ValueError("preconditioner must be 'direct', 'ic0' or 'jacobi'")
        self.dt = dt
        self.adaptive = adaptive
        self.dt_max = dt_max
        self.dt_min = dt_min
        self.dt_grow = dt_grow
        self.dt_shrink = dt_shrink
        self.preconditioner = preconditioner
        self.backend = resolve_backend(backend) if preconditioner == "direct" else None
        self.cg_rtol = cg_rtol
        self.cg_maxiter = cg_maxiter
        self.refactor_iters = refactor_iters
        self.stall_window = stall_window
        self.max_displacement = max_displacement
        self.max_step = max_step
        self.friction_every = max(1, int(friction_every))
        self.friction_after = friction_after
        self.crawl_window = crawl_window
        self.max_backtracks = max_backtracks
        self._cache = None  # (model, ReducedSystem, IC0 | None)

    def _system(self, model, K):
        c = self._cache
        if c is not None and c[0] is model and c[1].same_pattern(K):
            return c[1], c[2]
        mesh = getattr(model, "mesh", None)
        em = getattr(mesh, "seam_emitters", ()) if mesh is not None else ()
        rc = getattr(mesh, "seam_edges", ()) if mesh is not None else ()
        order = seam_first_order(model.n, np.asarray(model.free, bool), em, rc)
        system = ReducedSystem(K, np.asarray(model.mass, np.float64), np.asarray(model.free, bool), order)
        pre = IC0(system) if self.preconditioner == "ic0" else None
        self._cache = (model, system, pre)
        self._factor = None
        self._t_factor = 0.0
        self._t_iter = 1.0
        return system, pre

    def _solve_direct(self, system, b, x0, stats):
        """CG with the cached factorization; refactor when it has gone stale."""
        A = system.matrix()
        fac = getattr(self, "_factor", None)
        if fac is not None:
            # amortization: keep the factorization while a solve with it costs less than
            # half a refactorization (10k vertices with PARDISO: a factorization ~0.13 s,
            # a CG iteration ~15 ms; with SuperLU ~1.5 s and ~25 ms)
            cap = max(self.refactor_iters, int(0.5 * self._t_factor / max(self._t_iter, 1e-6)))
            tp = time.perf_counter()
            dv, it, rr = pcg_factor(A, b, x0, fac, self.cg_rtol, cap)
            if it:
                self._t_iter = (time.perf_counter() - tp) / it
            stats["cg_iterations"] += it
            stats["cg_max"] = max(stats["cg_max"], it)
            stats["solve_s"] += time.perf_counter() - tp
            if rr <= self.cg_rtol and finite(dv):
                return dv, it, rr
        tf = time.perf_counter()
        if fac is None or fac.backend != self.backend:
            fac = factorize(A, self.backend)
        else:
            fac.refactor(A)
        self._factor = fac
        self._t_factor = time.perf_counter() - tf
        stats["factorizations"] += 1
        stats["precond_s"] += self._t_factor
        tp = time.perf_counter()
        dv, it, rr = pcg_factor(A, b, x0, fac, self.cg_rtol, self.cg_maxiter)
        stats["solve_s"] += time.perf_counter() - tp
        stats["cg_iterations"] += it
        stats["cg_max"] = max(stats["cg_max"], it)
        return dv, it, rr

    def solve(
        self,
        model,
        x0: np.ndarray,
        *,
        tol: float = 1e-4,
        max_iters: int = 10_000,
        max_seconds: float = 60.0,
        callback: ProgressCallback | None = None,
        v0: np.ndarray | None = None,
        friction_after: float | None = None,
        from_placement: bool = False,  # small implicit steps: no guard needed
    ) -> SolveResult:
        t_start = time.perf_counter()
        dt = self.dt
        n = model.n
        free = np.asarray(model.free, bool)
        mass = np.asarray(model.mass, np.float64)
        x = pinned_positions(model, x0)
        v = np.zeros((n, 3)) if v0 is None else np.array(v0, dtype=np.float64)
        v[~free] = 0.0
        stats: dict[str, Any] = dict(
            assembly_s=0.0,
            linear_solve_s=0.0,
            precond_s=0.0,
            solve_s=0.0,
            friction_s=0.0,
            steps=0,
            cg_iterations=0,
            cg_max=0,
            cg_unconverged=0,
            velocity_resets=0,
            rejected_steps=0,
            backtracks=0,
            clamped_steps=0,
            factorizations=0,
            ic_shift=0.0,
            ic_retries=0,
            jacobi_fallbacks=0,
            direct_failures=0,
            friction_checks=0,
            friction_excess_N=0.0,
            forced_steps=0,
            round_off_steps=0,
            dt_final=dt,
            dt_max_reached=dt,
            preconditioner=self.preconditioner,
        )
        history: list[tuple[float, float]] = []
        diag = ""
        converged = False
        scale = float(np.linalg.norm(np.ptp(x, axis=0))) or 1.0
        max_disp = self.max_displacement or 10.0 * scale
        max_step = self.max_step or 0.02 * scale
        watch = Watch(self.stall_window)

        if not finite(x):
            return bad_start(self.name, x, stats)

        best = BestState(model)
        ke_hist = [0.0, 0.0]
        dv_prev = None
        res_scale = None
        pre = None
        it = 0
        attempts = 0
        r = np.inf
        E = f = None
        fric: FrictionSchedule | None = None
        recent: list[float] = []
        mode = self.preconditioner
        while True:
            ta = time.perf_counter()
            if f is None:
                E, f = energy_and_forces(model, x)
            if not finite(f):
                diag = f"diverged: non-finite forces at step {it}"
                break
            if res_scale is None:
                res_scale = ResidualScale(model, x, f)
            r = res_scale(x, f)
            now = time.perf_counter() - t_start
            history.append((now, r))
            recent.append(r)
            # a crawl (the residual has not halved in crawl_window steps, near rest): a
            # garment sliding or turning on the body, which friction stops; stuck at any
            # residual: also cloth sliding off the body it landed on (r about 1)
            stuck = len(recent) > self.crawl_window and r > 0.5 * recent[-1 - self.crawl_window]
            crawling = stuck and r < 1.0
            tf = time.perf_counter()
            if fric is None:
                fric = FrictionSchedule(
                    model,
                    x,
                    r,
                    tol,
                    self.friction_after if friction_after is None else friction_after,
                    self.friction_every,
                )
                changed = fric.present
            else:
                changed = fric.after_step(it, x, r, crawling, stuck)
            if changed:
                watch.restart(it)
                E, f = energy_and_forces(model, x)
                r = res_scale(x, f)
                history[-1] = (now, r)
            stats["friction_s"] += time.perf_counter() - tf
            best.offer(x, r, it)
            rounds = 0
            while r <= tol and rounds < 3 and fric.at_balance(x):
                rounds += 1  # as in Newton: until a balance holds as it is
                watch.restart(it)
                E, f = energy_and_forces(model, x)
                r = res_scale(x, f)
                history[-1] = (now, r)
            if r <= tol and fric.holds():
                converged = True
                stats["assembly_s"] += time.perf_counter() - ta
                break
            if callback is not None and callback(it, x, r):
                diag = "stopped by callback"
                stats["assembly_s"] += time.perf_counter() - ta
                break
            d = watch.check(it, r)
            if d:
                diag = d
                break
            if it >= max_iters or attempts >= 4 * max_iters:
                diag = f"max_iters {max_iters} reached (residual {r:.3g} > tol {tol:.3g})"
                break
            if now >= max_seconds:
                diag = f"max_seconds {max_seconds:g} reached after {it} steps (residual {r:.3g} > tol {tol:.3g})"
                break
            K = model.stiffness(x)
            system, pre = self._system(model, K)
            e_noise = None
            Kv = K @ v.ravel()
            ke0 = 0.5 * float(np.sum(mass[:, None] * v * v))
            stats["assembly_s"] += time.perf_counter() - ta
            # an adaptive step may be redone from rest or with a shorter dt (same x, K)
            while True:
                attempts += 1
                ta = time.perf_counter()
                # Baraff-Witkin: df/dx = -K, so the right side is dt (f - dt K v)
                b = system.restrict(dt * (f.ravel() - dt * Kv))
                system.assemble(K, dt * dt, 1.0)
                tl = time.perf_counter()
                stats["assembly_s"] += tl - ta
                if mode == "direct":
                    try:
                        dv, cg_it, cg_rr = self._solve_direct(system, b, dv_prev, stats)
                    except FactorizationError:
                        # not SPD in floating point (should not happen: K is PSD): IC(0)-PCG
                        mode, pre = "ic0", IC0(system)
                        stats["direct_failures"] += 1
                        continue
                else:
                    if pre is not None:
                        try:
                            pre.factor(system.Ax)
                        except FactorizationError:
                            pre = None
                            stats["jacobi_fallbacks"] += 1
                    tp = time.perf_counter()
                    stats["precond_s"] += tp - tl
                    dv, cg_it, cg_rr = pcg(system, b, dv_prev, pre, self.cg_rtol, self.cg_maxiter)
                    stats["cg_iterations"] += cg_it
                    stats["cg_max"] = max(stats["cg_max"], cg_it)
                stats["linear_solve_s"] += time.perf_counter() - tl
                if cg_rr > self.cg_rtol:
                    stats["cg_unconverged"] += 1
                if not finite(dv):
                    break
                v_new = v + system.prolong(dv, n)
                step = dt * v_new
                big = float(np.max(np.abs(step)))
                if not self.adaptive:
                    break
                if big > max_step:
                    # trust region: shorten the step (and the velocity it implies) instead
                    # of dt, so the factorization of M + dt² K stays valid
                    v_new *= max_step / big
                    step *= max_step / big
                    big = max_step
                    stats["clamped_steps"] += 1
                ta = time.perf_counter()
                ok = False
                alpha = 1.0
                assert E is not None  # set with f at the top of the loop
                total0 = E + ke0
                for _ in range(self.max_backtracks + 1):
                    E_new, f_new = energy_and_forces(model, x + alpha * step)
                    ke_new = alpha * alpha * 0.5 * float(np.sum(mass[:, None] * v_new * v_new))
                    if np.isfinite(E_new + ke_new) and E_new + ke_new <= total0 + 1e-12 * (abs(E) + ke0 + 1e-30):
                        ok = True
                        break
                    # near equilibrium the change is below the energy's round-off (1e-9 of
                    # the terms' magnitudes, which cancel in E): the energy cannot rank the
                    # two states, so rank by the force residual (as Newton does)
                    if e_noise is None:
                        e_noise = energy_round_off(model, x, E)
                    if (
                        np.isfinite(E_new)
                        and abs(E_new + ke_new - total0) <= e_noise
                        and finite(f_new)
                        and res_scale(x + alpha * step, f_new) < r
                    ):
                        ok = True
                        stats["round_off_steps"] += 1
                        break
                    alpha *= 0.5
                    stats["backtracks"] += 1
                stats["assembly_s"] += time.perf_counter() - ta
                if not ok and ke0 == 0.0 and dt <= self.dt_min:
                    # at the dt floor from rest: take the shortest tried step anyway (a descent
                    # direction of the model; the energy test there is at round-off level)
                    ok = True
                    stats["forced_steps"] += 1
                if ok:
                    if alpha < 1.0:
                        step *= alpha
                        v_new *= alpha
                        big *= alpha
                    break
                # no energy decrease along this step: the linearization is poor at this dt;
                # redo it from rest, then with a shorter dt
                stats["rejected_steps"] += 1
                if ke0 > 0.0:
                    v[:] = 0.0
                    Kv[:] = 0.0
                    ke0 = 0.0
                    stats["velocity_resets"] += 1
                    ke_hist = [0.0, 0.0]
                else:
                    dt = max(dt * self.dt_shrink, self.dt_min)
                dv_prev = None
            if not finite(dv):
                diag = f"diverged: linear solve produced non-finite velocities at step {it}"
                break
            if big > max_disp:
                diag = f"diverged: a vertex moved {big:.3g} m in one step (limit {max_disp:.3g} m) at step {it}"
                break
            dv_prev = dv
            v = v_new
            x += step
            log.debug(
                "kinetic step %d: r %.3e E %.9e dt %.3g alpha %.3g cg %d |step| %.3g",
                it,
                r,
                E,
                dt,
                alpha,
                cg_it,
                big,
            )
            it += 1
            if self.adaptive:
                E, f = E_new, f_new
                if alpha >= 0.5:
                    dt = min(dt * self.dt_grow, self.dt_max)
                elif alpha < 0.25:
                    dt = max(dt * 0.5, self.dt_min)
                stats["dt_max_reached"] = max(stats["dt_max_reached"], dt)
            else:
                f = None
            ke = 0.5 * float(np.sum(mass[:, None] * v * v))
            # kinetic damping: a local maximum of kinetic energy over three steps
            if ke_hist[1] > ke_hist[0] and ke < ke_hist[1]:
                v[:] = 0.0
                dv_prev = None
                stats["velocity_resets"] += 1
                ke_hist = [0.0, 0.0]
            else:
                ke_hist = [ke_hist[1], ke]

        stats["steps"] = it
        stats["dt_final"] = dt
        if fric is not None:
            stats.update(friction_checks=fric.checks, slipped=fric.slipped, friction_excess_N=fric.excess)
        if pre is not None:
            stats["ic_shift"] = pre.shift
            stats["ic_retries"] = pre.retries
        return finish(
            model,
            x,
            r,
            "" if converged else diag,
            best,
            tol,
            method=self.name,
            iterations=it,
            t_start=t_start,
            history=history,
            stats=stats,
        )

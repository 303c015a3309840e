"""Newton's method with an Armijo backtracking line search on the energy: the
accuracy reference among the solvers.

Direction: (K + M/h²) p = f on free DOFs by a sparse direct factorization
(couture.solvers.linalg backends). K is PSD but may be singular (a flat sheet
without bending has no out-of-plane stiffness), so a mass-proportional
Levenberg term M/h² is always present; h starts long (1 s: the term is ~1e-5
of K, i.e. pure Newton) and shortens ×10 when the factorization fails, the
direction is not a descent direction or the line search fails; it lengthens
again after full steps. The term only shapes the path: the fixed point is f = 0.

Hessian ('auto', default): the PSD-projected stiffness far from equilibrium;
the true Hessian (membrane unprojected, the body's curvature in the contact
term) once the relative residual is below ``true_below`` (1e-2) or the solve
crawls (its residual not halved in ``crawl_window`` iterations while below
``true_until``), kept until the residual exceeds ``true_until``. Where the true
Hessian is indefinite (compressed regions about to buckle, a fold that wants
to turn), a mass shift M/h_true² makes it definite (h_true shortened ×10 per
failed try, relaxed ×3 after full steps, down to ``shift_floor``); only then
does a step fall back to the projected Hessian. Why: the projected Hessian is
stiffer than the true one exactly along compression and soft modes, so
projected-only Newton converges linearly there, in tiny steps.

``indefinite='trust'`` replaces the mass shift by a trust region (Steihaug's
truncated CG on the true Hessian, preconditioned by a factorization of the
projected one, which never fails; negative curvature is followed to the
region's boundary; a rejected step re-runs CG in a smaller region on the same
factor). Measured against the shift, same start, loaded machine (iterations,
coarse + fine): dress 82 + 162 -> 88 + 129 (failed factorizations 39 -> 0),
default skirt 167 + 36 -> 300 + 39, sheet falling onto a box 146 -> 153 (116
with the true Hessian kept once a crawl turns it on), band on a cone 128 -> 167:
not a uniform gain, so not the default.

Friction: ``common.FrictionSchedule`` (anchors once the residual is below
``friction_after`` or the solve crawls; slips of anchors beyond mu_s every
``friction_every`` iterations; at a balance, convergence requires every
anchor within the static Coulomb limit).
Crawls: where the Newton path creeps down a long shallow valley (a frictionless
sheet held at one vertex on a sphere, its folds forming and rolling: the energy
falls by 1e-5 per iteration for a thousand iterations), the solve hands over to
damped implicit dynamics (``KineticSolver``, pseudo-transient continuation with
momentum) from its best state until the residual is a tenth of it and at most
``dynamics_until`` (where Newton's local convergence takes over), then goes on
with Newton; the dynamics only choose the path, the fixed point is f = 0. A
phase gets ``dynamics_share`` of the time left; if it does not reach its
target and Newton's own path had gone lower in energy, Newton goes on from
where it was: down a long valley whose energy falls at every step while the
residual hovers (the frictionless edited skirt, 10.6k vertices, turning about
the body), the best-residual state lies far behind, and dynamics restarted
there spent the rest of the 120 s turning the skirt again.
``converged`` is decided at return from fresh forces (``common.verdict``);
a solve that stops early returns the best state it saw.
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
    SurfaceGuard,
    Watch,
    bad_start,
    edges_through_body,
    energy_round_off,
    finish,
    finite,
    pinned_positions,
    true_stiffness,
)
from .linalg import Factor, FactorizationError, ReducedSystem, factorize, resolve_backend, seam_first_order

log = logging.getLogger(__name__)


class NewtonSolver:
    name = "newton"

    def __init__(
        self,
        backend: str = "auto",
        *,
        armijo: float = 1e-4,
        max_backtracks: int = 30,
        h0: float = 10.0,
        h_min: float = 1e-7,
        max_step: float | None = None,
        stall_window: int = 100,
        hessian: str = "auto",
        true_below: float = 1e-2,
        true_until: float = 1.0,
        crawl_window: int = 10,
        shift_floor: float = 1e-4,
        friction_after: float = 0.01,
        friction_every: int = 5,
        forcing: float = 0.1,
        forcing_max: float = 1e-2,
        dynamics_phases: int = 2,
        dynamics_until: float = 1e-4,
        dynamics_share: float = 0.5,
        indefinite: str = "shift",
        cg_max: int = 60,
    ):
        """backend: 'auto' | 'pardiso32' | 'pardiso' | 'cholmod' | 'splu'; armijo: sufficient-decrease
        constant; h0, h_min [s]: Levenberg time scale (the term is M/h²);
        max_step [m]: largest vertex move per Newton step (default: a quarter of
        the bounding-box diagonal); stall_window: iterations without 1% residual progress
        nor a 1e-4 relative fall of the energy (a very slow crawl);
        hessian: 'auto' | 'true' | 'projected', true_below, true_until and crawl_window
        (module docstring);
        shift_floor [s]: the shortest time scale h_true of the mass shift M/h_true² that makes
        an indefinite true Hessian definite before a step falls back to the projected one;
        friction_after, friction_every: friction schedule (``solve(friction_after=...)``
        overrides the first for one solve);
        forcing: the direction's linear system is solved to a relative residual
        min(1e-2, forcing * r) at relative force residual r (inexact Newton; only
        approximate backends use it: 'pardiso32', by name);
        dynamics_phases: how many times a crawl (the residual not improved by 1 % in
        ``stall_window`` iterations) hands over to damped dynamics (module docstring),
        each time until the residual is a tenth of the best or ``dynamics_until``;
        dynamics_share: the fraction of the time left that one such phase may take
        (if it does not reach its target and the Newton path had gone lower in
        energy, Newton goes on from where it was);
        indefinite: 'shift' (a mass shift makes an indefinite true Hessian definite) or
        'trust' (a trust region, module docstring); cg_max: the trust region's CG
        iterations per step."""
        self.backend = resolve_backend(backend, approximate=True)
        self.forcing = forcing
        self.forcing_max = forcing_max
        self.armijo = armijo
        self.max_backtracks = max_backtracks
        self.h0 = h0
        self.h_min = h_min
        self.max_step = max_step
        self.stall_window = stall_window
        if hessian not in ("auto", "true", "projected"):
            raise ValueError("hessian must be 'auto', 'true' or 'projected'")
        self.hessian = hessian
        self.true_below = true_below
        self.true_until = true_until
        self.crawl_window = crawl_window
        self.shift_floor = shift_floor
        self.friction_after = friction_after
        self.friction_every = max(1, int(friction_every))
        self.dynamics_phases = int(dynamics_phases)
        self.dynamics_until = dynamics_until
        self.dynamics_share = float(dynamics_share)
        if indefinite not in ("shift", "trust"):
            raise ValueError("indefinite must be 'shift' or 'trust'")
        self.indefinite = indefinite
        self.cg_max = int(cg_max)
        from .kinetic import KineticSolver

        self._dynamics = KineticSolver(friction_after=friction_after, friction_every=friction_every, stall_window=5000)
        self._cache = None
        self._factor: Factor | None = None  # kept across solves on one model: its symbolic analysis is reused

    def _system(self, model, K):
        c = self._cache
        if c is not None and c[0] is model and c[1].same_pattern(K):
            return c[1]
        order = seam_first_order(model.n, np.asarray(model.free, bool))
        system = ReducedSystem(K, np.asarray(model.mass, np.float64), np.asarray(model.free, bool), order)
        self._cache = (model, system)
        self._factor = None
        return system

    def _trust_step(self, model, x, E, r, K_true, system, factor, g, guard, res_scale, stats):
        """One trust-region step on the true Hessian (Steihaug's truncated CG,
        preconditioned by a factorization of the PSD-projected Hessian, which never
        fails): CG follows the true curvature, stops at the region's boundary or
        where it meets negative curvature (and goes to the boundary along it), and a
        rejected step only shrinks the region and re-runs CG on the same factor.
        Returns (x_try, P, 1.0, factor), or None when no step within
        ``max_backtracks`` shrinks lowers the energy (the caller takes a projected
        step)."""
        tl = time.perf_counter()
        c_M = 1.0 / (self.h0 * self.h0)
        system.assemble(K_true, 1.0, c_M)
        A = system.matrix()
        system.assemble(model.stiffness(x), 1.0, c_M)
        B = system.matrix()
        try:
            if factor is None or factor.backend != self.backend:
                factor = factorize(B, self.backend)
            else:
                factor.refactor(B)
            stats["factorizations"] += 1
        except FactorizationError:
            stats["factorization_failures"] += 1
            stats["linear_solve_s"] += time.perf_counter() - tl
            return None
        stats["linear_solve_s"] += time.perf_counter() - tl
        n = model.n
        eta = min(0.1, max(self.forcing * r, 1e-12))
        delta = self._delta
        e_noise = None
        for _ in range(self.max_backtracks):
            tl = time.perf_counter()
            p, hit, cg = steihaug(A, B, g, factor, delta, eta, self.cg_max)
            stats["cg_iterations"] = stats.get("cg_iterations", 0) + cg
            stats["linear_solve_s"] += time.perf_counter() - tl
            p_norm = float(np.sqrt(max(p @ (B @ p), 0.0)))
            pred = float(g @ p - 0.5 * (p @ (A @ p)))
            P = system.prolong(p, n)
            x_try = x + P
            if pred <= 0.0 or not finite(p) or guard.refuses(x_try):
                self._delta = 0.25 * p_norm
                delta = self._delta
                stats["backtracks"] += 1
                continue
            E_try = model.energy(x_try)
            stats["energy_evals"] += 1
            if not np.isfinite(E_try):
                rho = -1.0
            else:
                if e_noise is None:
                    e_noise = energy_round_off(model, x, E)
                if pred <= e_noise:
                    # the predicted decrease is below the energy's round-off: rank by forces
                    f_try = model.forces(x_try)
                    rho = 1.0 if finite(f_try) and res_scale(x_try, f_try) < r else -1.0
                    stats["slope_steps"] += 1
                else:
                    rho = (E - E_try) / pred
            if rho < 0.25:
                self._delta = 0.25 * p_norm
            elif rho > 0.75 and hit:
                self._delta = 2.0 * p_norm
            delta = self._delta
            if rho > 1e-4:
                stats["trust_steps"] = stats.get("trust_steps", 0) + 1
                stats["negative_curvature"] = stats.get("negative_curvature", 0) + int(hit == "negative")
                return x_try, P, 1.0, factor
            stats["backtracks"] += 1
        return None

    def solve(
        self,
        model,
        x0: np.ndarray,
        *,
        tol: float = 1e-8,
        max_iters: int = 1000,
        max_seconds: float = 120.0,
        callback: ProgressCallback | None = None,
        friction_after: float | None = None,
        from_placement: bool = False,
    ) -> SolveResult:
        t_start = time.perf_counter()
        n = model.n
        x = pinned_positions(model, x0)
        stats: dict[str, Any] = dict(
            assembly_s=0.0,
            linear_solve_s=0.0,
            factorizations=0,
            factorization_failures=0,
            backtracks=0,
            line_search_failures=0,
            shift_increases=0,
            energy_evals=0,
            projected_fallbacks=0,
            true_hessian_steps=0,
            backend=self.backend,
            steps=0,
            slope_steps=0,
        )
        history: list[tuple[float, float]] = []
        if not finite(x):
            return bad_start(self.name, x, stats)
        scale = float(np.linalg.norm(np.ptp(x, axis=0))) or 1.0
        max_step = self.max_step or 0.25 * scale
        h = self.h0
        h_true = self.h0
        true_mode = False
        recent: list[float] = []
        watch = Watch(self.stall_window)
        crawl_watch = Watch(self.stall_window)  # the residual alone: blind to energy progress
        phases = 0
        factor = self._factor
        diag = ""
        converged = False
        it = 0
        self._delta = np.inf  # trust region radius (the projected Hessian's norm)
        was_true = False

        ta = time.perf_counter()
        f = model.forces(x)
        E = model.energy(x)
        res_scale = ResidualScale(model, x, f)
        r = res_scale(x, f)
        fric = FrictionSchedule(
            model, x, r, tol, self.friction_after if friction_after is None else friction_after, self.friction_every
        )
        f = model.forces(x)
        E = model.energy(x)
        r = res_scale(x, f)
        stats["assembly_s"] += time.perf_counter() - ta
        e_mark = E
        best = BestState(model)
        # from a placement the first steps close seams centimetres wide: a step of up
        # to max_step (a quarter of the garment) carried a collar 3-4 cm into the neck
        guard = SurfaceGuard(model if from_placement else None)
        while True:
            now = time.perf_counter() - t_start
            history.append((now, r))
            if not (finite(f) and np.isfinite(E)):
                diag = f"diverged: non-finite forces or energy at iteration {it}"
                break
            best.offer(x, r, it)
            rounds = 0
            while r <= tol and rounds < 3 and fric.at_balance(x):
                # until a balance holds as it is (a slip that barely changed the forces is
                # followed at once by sticking where the vertex is)
                rounds += 1
                watch.restart(it)
                f = model.forces(x)
                E = model.energy(x)
                r = res_scale(x, f)
                history.append((now, r))
            if r <= tol and fric.holds():
                converged = True
                break
            if callback is not None and callback(it, x, r):
                diag = "stopped by callback"
                break
            if E < e_mark - 1e-4 * abs(e_mark):
                # far from equilibrium the residual can hover or grow while the energy
                # falls steadily (a sheet settling over a sphere from flat: residual
                # 0.99 -> 700 -> 0.99 in 100 iterations, energy 0.117 -> 0.015 J)
                e_mark = E
                watch.progress(it)
            d = watch.check(it, r)
            crawl = crawl_watch.check(it, r)
            if (d or crawl).startswith("stalled") and phases < self.dynamics_phases and now < max_seconds:
                # the Newton path crawls down a long shallow valley (folds forming and
                # rolling, a garment turning): damped dynamics, whose momentum carries it
                # through, from the best state to a tenth of its residual, then Newton again
                phases += 1
                x_path, E_path = x, E
                state = getattr(model, "friction_state", None)
                anchors_path = state() if state is not None else None
                x0 = best.restore()
                target = max(tol, min(0.1 * best.r, self.dynamics_until))
                sub = None if callback is None else (lambda i, xs, rs, it0=it: callback(it0 + i, xs, rs))
                dyn = self._dynamics.solve(
                    model,
                    x0,
                    tol=target,
                    max_seconds=self.dynamics_share * (max_seconds - now),
                    callback=sub,
                )
                stats["dynamics_phases"] = phases
                log.debug(
                    "newton it %d: dynamics from %.3g to %.3g in %d steps", it, best.r, dyn.residual, dyn.iterations
                )
                stats["dynamics_steps"] = stats.get("dynamics_steps", 0) + dyn.iterations
                history.extend((now + t, rr) for t, rr in dyn.history)
                x = dyn.x
                E = model.energy(x)
                if dyn.residual > target and E_path < E and not dyn.diagnosis.startswith("stopped by callback"):
                    # the dynamics did not get there in their share of the time, and the
                    # Newton path had gone further down: Newton goes on from where it was
                    # (the frictionless edited skirt, 10.6k vertices, turns 0.17 rad about
                    # the body in a valley whose energy falls at every step while the
                    # residual hovers at 1e-3..1; restarted from the best-residual state,
                    # the dynamics spent the rest of the 120 s turning it again)
                    x = x_path
                    put = getattr(model, "set_friction_state", None)
                    if put is not None:
                        put(anchors_path)
                    stats["dynamics_abandoned"] = stats.get("dynamics_abandoned", 0) + 1
                it += 1
                f = model.forces(x)
                E = model.energy(x)
                r = res_scale(x, f)
                e_mark = E
                watch.restart(it)
                crawl_watch.restart(it)
                h, h_true = self.h0, self.h0
                if dyn.diagnosis.startswith("stopped by callback"):
                    diag = dyn.diagnosis
                    break
                continue
            if d:
                diag = d
                break
            if it >= max_iters:
                diag = f"max_iters {max_iters} reached (residual {r:.3g} > tol {tol:.3g})"
                break
            if now >= max_seconds:
                diag = f"max_seconds {max_seconds:g} reached after {it} iterations (residual {r:.3g} > tol {tol:.3g})"
                break

            ta = time.perf_counter()
            # hysteresis: a true-Hessian step that follows negative curvature may raise the
            # residual for a while (it lowers the energy); the projected Hessian, stiffer along
            # exactly those directions, would crawl there
            true_mode = r < self.true_below or (true_mode and r < self.true_until)
            use_true = self.hessian == "true" or (self.hessian == "auto" and true_mode)
            K = true_stiffness(model, x) if use_true else model.stiffness(x)
            system = self._system(model, K)
            g = system.restrict(f)
            stats["assembly_s"] += time.perf_counter() - ta

            accepted = False
            e_noise = None
            guard.at(x)
            if use_true and self.indefinite == "trust":
                if not was_true:
                    self._delta = np.inf
                step = self._trust_step(model, x, E, r, K, system, factor, g, guard, res_scale, stats)
                if step is not None:
                    x_try, P, alpha, factor = step
                    accepted = True
                else:
                    use_true = False
                    stats["projected_fallbacks"] += 1
                    K = model.stiffness(x)
            while not accepted:
                tl = time.perf_counter()
                h_eff = h_true if use_true else h
                system.assemble(K, 1.0, 1.0 / (h_eff * h_eff))
                p = None
                try:
                    A = system.matrix()
                    if factor is None or factor.backend != self.backend:
                        factor = factorize(A, self.backend)
                    else:
                        # a failed try keeps the factor object (and its symbolic analysis)
                        factor.refactor(A, expect_indefinite=use_true)
                    stats["factorizations"] += 1
                    p = factor.solve(g, rtol=min(self.forcing_max, self.forcing * r))
                    if not finite(p) or float(g @ p) <= 0.0:
                        p = None
                except FactorizationError:
                    stats["factorization_failures"] += 1
                stats["linear_solve_s"] += time.perf_counter() - tl
                if p is None and use_true and h_true > self.shift_floor:
                    # indefinite (compressed, buckling-prone regions, a fold that wants to
                    # turn): shift the true Hessian by more mass, M/h_true², until it is
                    # positive definite; the step then still follows negative curvature,
                    # which the projected Hessian cannot see
                    h_true /= 10.0
                    stats["shift_increases"] += 1
                    continue
                if p is None and use_true:
                    # no shift made it definite: this step with the PSD-projected Hessian
                    use_true = False
                    stats["projected_fallbacks"] += 1
                    K = model.stiffness(x)
                    continue
                if p is None:
                    h /= 10.0
                    if h < self.h_min:
                        break
                    continue
                P = system.prolong(p, n)
                alpha = min(1.0, max_step / max(float(np.max(np.abs(P))), 1e-300))
                slope = float(g @ p)  # -dE/dalpha at 0
                ta = time.perf_counter()
                for _ in range(self.max_backtracks):
                    x_try = x + alpha * P
                    if guard.refuses(x_try):
                        # through the body's surface: shorter
                        alpha *= 0.5
                        stats["backtracks"] += 1
                        stats["surface_backtracks"] = stats.get("surface_backtracks", 0) + 1
                        continue
                    E_try = model.energy(x_try)
                    stats["energy_evals"] += 1
                    if np.isfinite(E_try) and E_try <= E - self.armijo * alpha * slope:
                        accepted = True
                        break
                    # near equilibrium the whole predicted decrease (alpha * slope) is below
                    # the energy's round-off (e_noise): the energy cannot rank points. Rank
                    # by the forces instead: accept when the slope along P has dropped to at
                    # most 0.9 of its start (strong-Wolfe curvature: the step does not
                    # overshoot the line minimum) or the residual drops
                    if e_noise is None:
                        e_noise = energy_round_off(model, x, E)
                    if np.isfinite(E_try) and alpha * slope <= e_noise:
                        f_try = model.forces(x_try)
                        if finite(f_try) and (
                            abs(float(np.vdot(f_try, P))) <= 0.9 * slope or res_scale(x_try, f_try) < r
                        ):
                            stats["slope_steps"] += 1
                            accepted = True
                            break
                    alpha *= 0.5
                    stats["backtracks"] += 1
                stats["assembly_s"] += time.perf_counter() - ta
                if not accepted and use_true and h_true > self.shift_floor:
                    h_true /= 10.0
                    stats["shift_increases"] += 1
                    continue
                if not accepted and use_true:
                    use_true = False
                    stats["projected_fallbacks"] += 1
                    K = model.stiffness(x)
                    continue
                if not accepted:
                    stats["line_search_failures"] += 1
                    h /= 10.0
                    if h < self.h_min:
                        break
            if not accepted:
                diag = (
                    f"stalled: no descent step at iteration {it} even with Levenberg term M/h², "
                    f"h = {h:.3g} s (residual {r:.3g})"
                )
                break
            # pseudo-transient continuation: (K + M/h²) p = f is one implicit Euler
            # step from rest of length h; lengthen h after full steps (towards pure
            # Newton), shorten it when the step had to be cut (far from equilibrium)
            if use_true:
                # the shift relaxes towards pure Newton after full steps, slowly: a shift
                # that is too small costs a failed factorization
                if alpha >= 1.0:
                    h_true = min(h_true * 3.0, self.h0)
                elif alpha < 0.5:
                    h_true = max(h_true / 3.0, self.shift_floor)
            elif alpha >= 1.0:
                h = min(h * 10.0, self.h0)
            elif alpha < 0.1:
                h = max(h / 10.0, self.h_min)
            stats["true_hessian_steps"] += int(use_true)
            was_true = use_true
            log.debug(
                "newton it %d: r %.3e E %.9e alpha %.3g h %.3g ht %.3g true %s |P| %.3g",
                it,
                r,
                E,
                alpha,
                h,
                h_true,
                use_true,
                float(np.max(np.abs(P))),
            )
            x = x_try
            it += 1
            ta = time.perf_counter()
            f = model.forces(x)
            r = res_scale(x, f)
            recent.append(r)
            # a crawl: the residual has not halved over the last crawl_window steps while
            # the cloth is near rest (r < true_until) -- a soft mode (a garment sliding or
            # turning on the body, a fold rolling) that the projected Hessian, stiffer than
            # the true one along it, follows in tiny steps: turn to the true Hessian, and
            # let friction hold the cloth where it is if the scene has friction
            stuck = len(recent) > self.crawl_window and r > 0.5 * recent[-1 - self.crawl_window]
            crawling = stuck and r < self.true_until
            if crawling and not true_mode:
                true_mode = True
                stats["crawl_switches"] = stats.get("crawl_switches", 0) + 1
            if fric.after_step(it, x, r, crawling, stuck):
                watch.restart(it)
                f = model.forces(x)
                r = res_scale(x, f)
            E = model.energy(x)
            stats["assembly_s"] += time.perf_counter() - ta

        if converged and from_placement and (through := edges_through_body(model, x)):
            # the path from the placement carried a thin part of the body (an ankle)
            # through the cloth between vertices, where contact cannot see it, and the
            # drape balanced around it (titan trousers on cisMaleAdult46: seams closing
            # at a relative residual of 1e6 dragged the hem across the ankle in 20-30 mm
            # moves; the fine level then pressed two vertices 1.4 mm into the ankle).
            # Damped dynamics from the placement take another path; their drape is
            # taken when it has fewer such edges (converged or not)
            now = time.perf_counter() - t_start
            stats["edges_through_body"] = through
            if now < max_seconds:
                state = getattr(model, "friction_state", None)
                anchors = state() if state is not None else None
                sub = None if callback is None else (lambda i, xs, rs, it0=it: callback(it0 + i, xs, rs))
                dyn = self._dynamics.solve(
                    model,
                    pinned_positions(model, x0),
                    tol=tol,
                    max_seconds=max_seconds - now,
                    callback=sub,
                    friction_after=friction_after,
                )
                stats["dynamics_from_placement_steps"] = dyn.iterations
                history.extend((now + t, rr) for t, rr in dyn.history)
                it += dyn.iterations
                through_dyn = edges_through_body(model, dyn.x)
                stats["edges_through_body_dynamics"] = through_dyn
                if through_dyn < through:
                    log.info(
                        "newton: %d edges through the body; damped dynamics from the placement: %d",
                        through,
                        through_dyn,
                    )
                    x, r = dyn.x, dyn.residual
                    if not dyn.converged:
                        # out of time: their state, unconverged, so that a caller that
                        # gives more time (SolveService.extend_by) goes on from there
                        converged = False
                        diag = (
                            f"the body passed through the cloth between vertices ({through} edges); damped "
                            f"dynamics from the placement left {through_dyn}, unconverged: {dyn.diagnosis}"
                        )
                        best = BestState(model)
                        best.offer(x, r, it)
                else:
                    put = getattr(model, "set_friction_state", None)
                    if put is not None:
                        put(anchors)
        stats["steps"] = it
        stats["levenberg_h"] = h
        stats.update(friction_checks=fric.checks, slipped=fric.slipped, friction_excess_N=fric.excess)
        self._factor = factor
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


def steihaug(A, B, g: np.ndarray, factor: Factor, delta: float, eta: float, max_iter: int):
    """Steihaug-Toint truncated CG for min -g·p + ½ pᵀA p within ‖p‖_B ≤ delta,
    preconditioned by ``factor`` (B⁻¹, B SPD). Returns (p, hit, iterations): hit is
    '' (solved to ``eta``‖g‖), 'boundary' or 'negative' (direction of negative
    curvature followed to the boundary; with delta = inf, the CG iterate so far,
    or the preconditioned gradient if there is none)."""
    p = np.zeros_like(g)
    res = g.copy()
    z = factor.solve(res, rtol=1.0)
    d = z.copy()
    rz = float(res @ z)
    g_norm = float(np.linalg.norm(g))
    pBp = 0.0
    k = 0
    for k in range(1, max_iter + 1):
        Ad = A @ d
        dAd = float(d @ Ad)
        Bd = B @ d
        dBd = float(d @ Bd)
        pBd = float(p @ Bd)
        if dAd <= 1e-14 * dBd:
            if not np.isfinite(delta):
                return (p if k > 1 else z), "negative", k
            return p + _to_boundary(pBp, pBd, dBd, delta) * d, "negative", k
        a = rz / dAd
        if pBp + 2 * a * pBd + a * a * dBd >= delta * delta:
            return p + _to_boundary(pBp, pBd, dBd, delta) * d, "boundary", k
        p = p + a * d
        pBp = pBp + 2 * a * pBd + a * a * dBd
        res -= a * Ad
        if float(np.linalg.norm(res)) <= eta * g_norm:
            return p, "", k
        z = factor.solve(res, rtol=1.0)
        rz_new = float(res @ z)
        d = z + (rz_new / rz) * d
        rz = rz_new
    return p, "", k


def _to_boundary(pBp: float, pBd: float, dBd: float, delta: float) -> float:
    """tau >= 0 with ‖p + tau d‖_B = delta."""
    disc = pBd * pBd + dBd * (delta * delta - pBp)
    return (-pBd + np.sqrt(max(disc, 0.0))) / dBd

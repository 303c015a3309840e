"""Explicit solver: Störmer-Verlet dynamic relaxation of the shared cloth model.

It answers the question Newton and kinetic answer: the equilibrium of the
same :class:`couture.cloth.ClothModel` (membrane, bending, seams, contact,
friction anchors), reached by explicit time steps of ``model.forces`` alone:
no stiffness factorization, no linear solve. ``converged`` is decided at
return by ``common.verdict`` from fresh forces, as for every solver.

Steps (semi-implicit Euler, the velocity form of Störmer-Verlet):
``v += dt M⁻¹ f(x); x += dt v``, with FIRE damping (Bitzek et al. 2006,
"Structural relaxation made simple"; the half-step correction of FIRE 2.0,
Guénolé et al. 2020): while the power f·v is positive the velocity is turned
towards the acceleration by a fraction alpha that decays, and dt grows; when
it turns negative (the cloth overshot) the velocity is zeroed, half a step
undone and dt halved. FIRE is kinetic damping (zero the velocity past an
energy minimum along the path) with a steering term.

Masses: fictitious (dynamic relaxation, Underwood 1983). A static answer does
not depend on the masses, and explicit steps with the real lumped masses are
useless here: measured from the largest eigenvalue of M⁻¹K at placement
(1.6k-vertex skirt of ``couture bench extremes``), the stable step is 9.9e-6 s
(seams, 5000 mu, set it), 4.4e-7 s at stretch 1e4 N/m, 9.9e-7 s with seams
x100, 3.6e-6 s at 0.02 kg/m² (0.7 ms a force evaluation: 70 s of computing
per simulated second of the default skirt). Each vertex instead gets
``mass_safety / 4`` times its Gershgorin bound, the sum of |K_ij| over its
three rows of the (projected) stiffness, plus the contact and friction
penalty stiffness it would have on touching the body, so a unit step is
stable (dt ω_max <= 2 / sqrt(mass_safety)); the masses are refreshed every
``mass_every`` steps (the stiffness changes as the cloth moves), and a step
that produces non-finite forces is undone from the last checkpoint with
heavier masses.

Friction follows ``common.FrictionSchedule`` (as in Newton and kinetic),
stopped solves return ``common.BestState``'s state, and ``common.finish``
writes the verdict.

What it costs: each step is one force evaluation (0.7 ms on 1.6k vertices),
but it needs a step count of the order of the square root of the stiffness
ratio (seams 5000 x the fabric, fabric x gravity) per decade of residual:
it converges SC Fig. 5's strip in about 2 s, and a garment from its
placement only slowly (bench/README.md, extremes).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from .base import ProgressCallback, SolveResult
from .common import BestState, FrictionSchedule, ResidualScale, Watch, bad_start, finish, finite, pinned_positions


def fictitious_masses(model, x: np.ndarray, safety: float, contact_margin: float = np.inf) -> np.ndarray:
    """[kg] per vertex, shape (n,): masses for which a unit time step (1 s) of
    explicit Störmer-Verlet is stable at x: ``safety / 4`` times the vertex's
    Gershgorin bound (largest sum of |K_ij| over its three rows [N/m]), plus the
    contact and friction penalty stiffness for every vertex closer to the body
    than the contact offset + ``contact_margin`` [m] (one that touches it before
    the next refresh must not make the step unstable)."""
    K = model.stiffness(x)
    rows = np.asarray(abs(K).sum(axis=1)).ravel().reshape(-1, 3).max(axis=1)
    body = getattr(model, "body", None)
    if body is not None:
        k = float(getattr(model, "contact_stiffness", 0.0))
        if "friction" in getattr(model, "terms", ()):
            k += float(getattr(model, "friction_stiffness", 0.0) or 0.0)
        if np.isfinite(contact_margin):
            phi, _ = body.phi_grad(np.ascontiguousarray(x, dtype=np.float64))
            near = phi < float(getattr(model, "contact_offset", 0.0)) + contact_margin
            rows = rows + np.where(near, k, 0.0)
        else:
            rows = rows + k
    floor = 1e-12 * max(float(rows.max()), 1e-300)
    return 0.25 * safety * np.maximum(rows, floor)


class VerletSolver:
    name = "verlet"

    def __init__(
        self,
        *,
        mass_safety: float = 2.0,
        mass_every: int = 50,
        contact_margin: float = 0.02,
        max_move: float = 0.2,
        dt_max: float = 1.0,
        dt_min: float = 1e-3,
        fire_delay: int = 5,
        fire_grow: float = 1.1,
        fire_shrink: float = 0.5,
        fire_alpha: float = 0.1,
        fire_alpha_decay: float = 0.99,
        friction_every: int = 20,
        friction_after: float = 1e-2,
        crawl_window: int = 2000,
        stall_window: int = 50_000,
        check_every: int = 10,
    ):
        """mass_safety: fictitious masses are this many times the stability bound
        (>= 1; 2 leaves dt ω_max <= 1.41); mass_every: steps between mass refreshes;
        max_move: the largest move of a vertex in one step, in mean rest edge lengths (the
        masses bound the linear stiffness; a seam open by a panel's width pulls a vertex
        across several elements in one unit step, where the membrane's stiffening makes
        it unstable); contact_margin [m]: vertices this far outside the contact layer get the contact
        stiffness in their mass (``fictitious_masses``); dt_max, dt_min [s]: FIRE's step bounds (masses are scaled for dt = 1 s);
        fire_*: FIRE's delay (steps of positive power before dt grows), dt growth
        and shrink factors, initial steering alpha and its decay; friction_every,
        friction_after, crawl_window [steps]: ``common.FrictionSchedule`` (anchors
        once the residual is below friction_after, or the residual has not halved
        over crawl_window steps); stall_window [steps] without 1 % progress
        before giving up; check_every: steps between best-state offers and
        history samples."""
        if mass_safety < 1.0:
            raise ValueError(f"mass_safety {mass_safety} < 1: explicit steps would be unstable")
        if not 0.0 < dt_min <= dt_max:
            raise ValueError(f"need 0 < dt_min <= dt_max, got dt_min={dt_min}, dt_max={dt_max}")
        self.mass_safety = float(mass_safety)
        self.mass_every = max(1, int(mass_every))
        self.contact_margin = float(contact_margin)
        self.max_move = float(max_move)
        self.dt_max = float(dt_max)
        self.dt_min = float(dt_min)
        self.fire_delay = int(fire_delay)
        self.fire_grow = float(fire_grow)
        self.fire_shrink = float(fire_shrink)
        self.fire_alpha = float(fire_alpha)
        self.fire_alpha_decay = float(fire_alpha_decay)
        self.friction_every = max(1, int(friction_every))
        self.friction_after = friction_after
        self.crawl_window = max(1, int(crawl_window))
        self.stall_window = int(stall_window)
        self.check_every = max(1, int(check_every))

    def solve(
        self,
        model,
        x0: np.ndarray,
        *,
        tol: float = 1e-4,
        max_iters: int = 1_000_000,
        max_seconds: float = 60.0,
        callback: ProgressCallback | None = None,
        friction_after: float | None = None,
        from_placement: bool = False,  # unit steps with stable masses: nothing to guard
    ) -> SolveResult:
        t_start = time.perf_counter()
        x = pinned_positions(model, x0)
        stats: dict[str, Any] = dict(
            assembly_s=0.0,
            mass_s=0.0,
            friction_s=0.0,
            steps=0,
            velocity_resets=0,
            mass_refreshes=0,
            undone_steps=0,
            clamped_moves=0,
            dt_final=float("nan"),
        )
        if not finite(x):
            return bad_start(self.name, x, stats)
        free = np.asarray(model.free, bool)
        fmask = free[:, None]
        safety = self.mass_safety
        margin = self.contact_margin
        tm = time.perf_counter()
        m = fictitious_masses(model, x, safety, margin)
        stats["mass_s"] += time.perf_counter() - tm
        v = np.zeros_like(x)
        edges = model.mesh.tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        h = float(np.mean(np.linalg.norm(model.X[edges[:, 1]] - model.X[edges[:, 0]], axis=1)))
        step_cap = self.max_move * h
        ta = time.perf_counter()
        f = model.forces(x)
        stats["assembly_s"] += time.perf_counter() - ta
        best = BestState(model)
        if not finite(f):
            best.offer(x, np.inf, 0)
            return finish(
                model,
                x,
                np.inf,
                "diverged: non-finite forces at the start",
                best,
                tol,
                method=self.name,
                iterations=0,
                t_start=t_start,
                history=[],
                stats=stats,
            )
        res_scale = ResidualScale(model, x, f)
        watch = Watch(self.stall_window)
        history: list[tuple[float, float]] = []
        recent: list[float] = []
        fric: FrictionSchedule | None = None
        x_ck = x.copy()
        dt = self.dt_max
        alpha = self.fire_alpha
        n_pos = 0
        it = 0
        r = np.inf
        diag = ""
        converged = False
        while True:
            r = res_scale(x, f)
            if it % self.check_every == 0:
                history.append((time.perf_counter() - t_start, r))
                recent.append(r)
            # a crawl: the residual has not halved over crawl_window steps (sampled
            # every check_every), as kinetic's rule; stuck: the same at any residual
            lag = self.crawl_window // self.check_every
            stuck = len(recent) > lag and r > 0.5 * recent[-1 - lag]
            tf = time.perf_counter()
            if fric is None:
                after = self.friction_after if friction_after is None else friction_after
                fric = FrictionSchedule(model, x, r, tol, after, self.friction_every)
                changed = fric.present
            else:
                changed = fric.after_step(it, x, r, stuck and r < 1.0, stuck)
            if changed:
                watch.restart(it)
                f = model.forces(x)
                r = res_scale(x, f)
            rounds = 0
            while r <= tol and rounds < 3 and fric.at_balance(x):
                rounds += 1  # as in Newton and kinetic: until a balance holds as it is
                watch.restart(it)
                f = model.forces(x)
                r = res_scale(x, f)
            stats["friction_s"] += time.perf_counter() - tf
            if it % self.check_every == 0 or r <= tol:
                best.offer(x, r, it)
            if r <= tol and fric.holds():
                converged = True
                break
            if callback is not None and callback(it, x, r):
                diag = "stopped by callback"
                break
            d = watch.check(it, r)
            if d:
                diag = d
                break
            if it >= max_iters:
                diag = f"max_iters {max_iters} reached (residual {r:.3g} > tol {tol:.3g})"
                break
            now = time.perf_counter() - t_start
            if now >= max_seconds:
                diag = f"max_seconds {max_seconds:g} reached after {it} steps (residual {r:.3g} > tol {tol:.3g})"
                break
            if it % self.mass_every == 0 and it > 0:
                # the stiffness changed as the cloth moved: stable masses where it now is
                tm = time.perf_counter()
                m_new = fictitious_masses(model, x, safety, margin)
                # keep the momentum's direction, not its size: lighter masses with the
                # old velocities would carry more energy than the step can hold
                v *= np.sqrt(np.minimum(m / m_new, 1.0))[:, None]
                m = m_new
                x_ck[:] = x
                stats["mass_refreshes"] += 1
                stats["mass_s"] += time.perf_counter() - tm
            ta = time.perf_counter()
            if float(np.sum(f * v)) > 0.0:
                n_pos += 1
                if n_pos > self.fire_delay:
                    dt = min(dt * self.fire_grow, self.dt_max)
                    alpha *= self.fire_alpha_decay
            elif it > 0:
                # past the minimum along the path: back up half a step, stop, go slower
                x -= (0.5 * dt) * v
                v[:] = 0.0
                dt = max(dt * self.fire_shrink, self.dt_min)
                alpha = self.fire_alpha
                n_pos = 0
                stats["velocity_resets"] += 1
            a = np.where(fmask, f / m[:, None], 0.0)
            v += dt * a
            vn = float(np.linalg.norm(v))
            an = float(np.linalg.norm(a))
            if an > 0.0:
                v *= 1.0 - alpha
                v += (alpha * vn / an) * a
            step = dt * v
            big = np.einsum("ij,ij->i", step, step) > step_cap * step_cap
            if big.any():
                shrink = step_cap / np.sqrt(np.einsum("ij,ij->i", step[big], step[big]))
                v[big] *= shrink[:, None]
                step[big] *= shrink[:, None]
                stats["clamped_moves"] += int(big.sum())
            x += step
            f = model.forces(x)
            stats["assembly_s"] += time.perf_counter() - ta
            it += 1
            if not (finite(f) and finite(x)):
                # an instability the masses did not bound: undo to the checkpoint, heavier
                stats["undone_steps"] += 1
                if np.isfinite(margin):
                    margin = np.inf  # first: the contact stiffness in every vertex's mass
                else:
                    safety *= 4.0
                if safety > 1e4 * self.mass_safety:
                    diag = f"diverged: non-finite forces at step {it} with masses {safety:g}x the bound"
                    x = x_ck.copy()
                    break
                x[:] = x_ck
                v[:] = 0.0
                dt = self.dt_max
                m = fictitious_masses(model, x, safety, margin)
                f = model.forces(x)

        stats["steps"] = it
        stats["dt_final"] = dt
        stats["mass_safety_final"] = safety
        if fric is not None:
            stats.update(friction_checks=fric.checks, slipped=fric.slipped, friction_excess_N=fric.excess)
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

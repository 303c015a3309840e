"""Helpers shared by the solvers: residual bookkeeping, stall/divergence watch, pins."""

from __future__ import annotations

import time

import numpy as np

from .base import SolveResult


def pinned_positions(model, x: np.ndarray) -> np.ndarray:
    """A copy of x with pinned vertices put back where the model holds them
    (``model.mesh.x0``; the contract: pins are held at their x0)."""
    x = np.array(x, dtype=np.float64, copy=True)
    mesh = getattr(model, "mesh", None)
    if mesh is not None and getattr(mesh, "x0", None) is not None:
        pin = ~model.free
        x[pin] = mesh.x0[pin]
    return x


class ResidualScale:
    """Relative residual from a force vector already at hand.

    ``model.relative_residual(x)`` is ||f_free|| / ||F_gravity|| (see
    couture.solvers.base); with gravity the denominator does not depend on x,
    so one call recovers it and every later residual costs a norm, not a force
    evaluation. A model whose ``residual_scale_constant`` is False (a scene
    without gravity) is asked every time.
    """

    def __init__(self, model, x: np.ndarray, f: np.ndarray):
        self.free = model.free
        num = float(np.linalg.norm(f[self.free]))
        rr = float(model.relative_residual(x))
        self.den: float | None
        if getattr(model, "residual_scale_constant", True) and num > 0 and rr > 0 and np.isfinite(rr):
            self.den = num / rr
        else:
            self.den = None
            self.model = model

    def __call__(self, x: np.ndarray, f: np.ndarray) -> float:
        if self.den is None:
            return float(self.model.relative_residual(x))
        return float(np.linalg.norm(f[self.free]) / self.den)


class Watch:
    """Stall and divergence watch over a residual sequence.

    Stalled: the best residual did not improve by ``stall_factor`` over the last
    ``window`` iterations. Diverged: non-finite values, or the residual grew
    ``blowup`` times above its best.
    """

    def __init__(self, window: int, stall_factor: float = 0.99, blowup: float = 1e6):
        self.window = window
        self.stall_factor = stall_factor
        self.blowup = blowup
        self.best = np.inf
        self.best_at = 0
        self.mark = np.inf
        self.mark_at = 0

    def progress(self, it: int) -> None:
        """Progress seen by another measure (a solver's energy): restart the window."""
        self.mark = min(self.mark, self.best)
        self.mark_at = it

    def restart(self, it: int) -> None:
        """Forget the best residual: the force field changed (friction anchors slipped),
        so residuals before and after are not comparable."""
        self.best = np.inf
        self.mark = np.inf
        self.mark_at = it

    def check(self, it: int, r: float) -> str:
        if not np.isfinite(r):
            return f"diverged: non-finite residual at iteration {it}"
        if r < self.best:
            self.best = r
            self.best_at = it
        if r > self.blowup * max(self.best, 1e-300) and self.best < np.inf:
            return f"diverged: residual {r:.3g} is {r / self.best:.3g}x its best {self.best:.3g}"
        if self.best < self.stall_factor * self.mark:
            self.mark = self.best
            self.mark_at = it
        elif it - self.mark_at >= self.window:
            return (
                f"stalled: residual best {self.best:.3g} did not improve by "
                f"{100 * (1 - self.stall_factor):.0f}% over {self.window} iterations"
            )
        return ""


def finite(a: np.ndarray) -> bool:
    return bool(np.all(np.isfinite(a)))


def energy_and_forces(model, x: np.ndarray) -> tuple[float, np.ndarray]:
    """(E, f) in one pass where the model offers it (ClothModel), else two calls."""
    both = getattr(model, "energy_and_forces", None)
    if both is not None:
        return both(x)
    return model.energy(x), model.forces(x)


def true_stiffness(model, x: np.ndarray):
    """The unprojected Hessian where the model offers one (``stiffness(x, project=False)``),
    else its (PSD) stiffness."""
    try:
        return model.stiffness(x, project=False)
    except TypeError:
        return model.stiffness(x)


def energy_round_off(model, x: np.ndarray, E: float) -> float:
    """Round-off of energy differences at x [J]: 1e-9 of the terms' magnitudes.

    Measured on the default 10k skirt near equilibrium: membrane 0.032 J,
    gravity -0.027 J, and differences below ~1e-11 J are noise (20k triangles'
    Green strains FᵀF - I cancel), while a full Newton step that takes the
    residual from 7e-3 to 7e-8 lowers E by 3e-13 J."""
    terms = getattr(model, "terms", None)
    if not terms:
        return 1e-9 * (abs(E) + 1e-300)
    return 1e-9 * sum(abs(model.energy(x, [t])) for t in terms)


class BestState:
    """The state with the lowest relative residual seen, with the friction anchors
    it was measured against (a residual means nothing without its anchors)."""

    def __init__(self, model):
        self.model = model
        self.x: np.ndarray | None = None
        self.r = np.inf
        self.it = -1
        self.anchors = None

    def offer(self, x: np.ndarray, r: float, it: int) -> None:
        if np.isfinite(r) and r < self.r:
            self.x = np.array(x, dtype=np.float64, copy=True)
            self.r, self.it = float(r), it
            state = getattr(self.model, "friction_state", None)
            self.anchors = state() if state is not None else None

    def restore(self) -> np.ndarray:
        """The best positions, with the model's anchors put back to what they were then."""
        if self.x is None:
            raise RuntimeError("no state was offered")
        put = getattr(self.model, "set_friction_state", None)
        if put is not None:
            put(self.anchors)
        return self.x


def friction_allowance(model, x: np.ndarray, tol: float) -> float:
    """[N] by how much an anchor may exceed its static Coulomb limit at a converged
    state: one vertex's share, tol * denominator / sqrt(n), of the force the residual
    tolerance allows (the limit is a force, like the residual)."""
    den = getattr(model, "residual_denominator", None)
    d = float(den(x)) if den is not None else 1.0
    return tol * d / np.sqrt(max(int(model.n), 1))


def deepest_inside(model, x: np.ndarray) -> float:
    """[m] how far the deepest free vertex lies inside the body's surface (phi < 0),
    0 when none does or the model has no body. A penalty contact balances forces
    inside the offset layer (phi in [0, offset)); a vertex below the surface
    itself went through it (a long step carried it between the legs, where the
    distance field pushes out through the far side)."""
    body = getattr(model, "body", None)
    if body is None:
        return 0.0
    free = np.asarray(model.free, bool)
    if not free.any():
        return 0.0
    phi, _ = body.phi_grad(np.ascontiguousarray(x[free], dtype=np.float64))
    return float(max(0.0, -np.min(phi)))


THROUGH_SAMPLES = 3
"""interior points per edge at which ``edges_through_body`` queries the body"""


def edges_through_body(model, x: np.ndarray) -> int:
    """How many cloth edges have both ends outside the body's surface (phi >= 0)
    while a point between them (``THROUGH_SAMPLES`` evenly spaced) lies deeper
    below it than the contact layer is thick: a part of the body passes through
    the cloth between two vertices. Contact acts on vertices, so neither it nor
    ``deepest_inside`` sees this; it happens where a thin part (an ankle, a
    wrist) is no wider than a few coarse edges, and a drape then balances with
    the part through a stretched triangle (titan trousers on cisMaleAdult46:
    the coarse Newton drape from the placement, four edges across the ankle
    up to 22 mm deep; bench/inside.py). 0 for a model without a body."""
    body = getattr(model, "body", None)
    if body is None or not len(model.tris):
        return 0
    x = np.ascontiguousarray(x, dtype=np.float64)
    t = model.tris
    e = np.unique(np.sort(np.vstack([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1), axis=0)
    phi, _ = body.phi_grad(x)
    a, b = x[e[:, 0]], x[e[:, 1]]
    depth = float(getattr(model, "contact_offset", 0.0) or 0.0)
    # phi is a distance (1-Lipschitz): along an edge of length L it stays above
    # (phi_a + phi_b - L) / 2, so only edges with phi_a + phi_b < L - 2 depth can
    # reach that deep (half the depth kept as a margin for the interpolated field)
    length = np.sqrt(((b - a) ** 2).sum(axis=1))
    pa, pb = phi[e[:, 0]], phi[e[:, 1]]
    cand = np.nonzero((pa >= 0.0) & (pb >= 0.0) & (pa + pb < length - depth))[0]
    if not len(cand):
        return 0
    deep = np.zeros(len(cand), bool)
    for s in np.linspace(0.0, 1.0, THROUGH_SAMPLES + 2)[1:-1]:
        p, _ = body.phi_grad(np.ascontiguousarray((1.0 - s) * a[cand] + s * b[cand]))
        deep |= p < -depth
    return int(deep.sum())


class SurfaceGuard:
    """Keeps a line search from jumping cloth through the body: a trial state is
    refused when a free vertex that was outside the body's surface (phi >= 0)
    ends below it after moving farther than the contact layer is thick (a long
    step through a thin part, an arm or between the legs, where the distance
    field then pushes out through the far side and a balance is reached
    inside). Shorter moves into the body are left to the contact force, which
    acts across the layer: seams pulling a piece onto the body from a placement
    press vertices against it, and refusing every crossing would freeze them
    there. A model without a body is never refused."""

    def __init__(self, model):
        """model None: a guard that refuses nothing."""
        body = getattr(model, "body", None)
        free = np.asarray(model.free, bool) if model is not None else np.zeros(0, bool)
        self.body = body if body is not None and free.any() else None
        self.free = free
        self.layer = float(getattr(model, "contact_offset", 0.0) or 0.0)
        self.x: np.ndarray | None = None
        self.phi: np.ndarray | None = None

    def _phi(self, x: np.ndarray) -> np.ndarray:
        phi, _ = self.body.phi_grad(np.ascontiguousarray(x[self.free], dtype=np.float64))
        return phi

    def at(self, x: np.ndarray) -> None:
        """The state a step starts from."""
        if self.body is not None:
            self.x = x[self.free]
            self.phi = self._phi(x)

    def refuses(self, x_try: np.ndarray) -> bool:
        if self.body is None:
            return False
        if self.phi is None or self.x is None:
            raise RuntimeError("SurfaceGuard.at(x) was not called for the step's start")
        crossed = (self._phi(x_try) < 0.0) & (self.phi >= 0.0)
        if not crossed.any():
            return False
        move = x_try[self.free][crossed] - self.x[crossed]
        return bool(np.any((move * move).sum(axis=1) > self.layer * self.layer))


def verdict(model, x: np.ndarray, tol: float) -> tuple[bool, float, str]:
    """(converged, relative residual, why not) decided from fresh forces at x,
    independently of how the solver's loop got there: the relative residual is
    at most ``tol``, no free vertex lies inside the body's surface
    (``deepest_inside``: a balance reached through the body is a wrong answer),
    and every friction anchor holds within its static Coulomb cone,
    |f_t| <= mu_s f_n (to ``friction_allowance``)."""
    r = float(model.relative_residual(x))
    if not np.isfinite(r):
        return False, r, "non-finite residual"
    if r > tol:
        return False, r, f"residual {r:.3g} > tol {tol:.3g}"
    inside = deepest_inside(model, x)
    if inside > 0.0:
        return (
            False,
            r,
            (
                f"in body: a vertex lies {inside * 1e3:.3g} mm inside the body surface, beyond the "
                f"{getattr(model, 'contact_offset', 0.0) * 1e3:.3g} mm contact layer (the cloth passed through)"
            ),
        )
    excess_fn = getattr(model, "friction_excess", None)
    excess = float(excess_fn(x)) if excess_fn is not None else 0.0
    allowed = friction_allowance(model, x, tol)
    if excess > allowed:
        return (
            False,
            r,
            (
                f"friction: an anchor holds {excess:.3g} N beyond its static Coulomb limit "
                f"mu_s f_n (allowed {allowed:.3g} N): the cloth would slide there"
            ),
        )
    return True, r, ""


def finish(
    model,
    x: np.ndarray,
    r: float,
    loop_diag: str,
    best: BestState,
    tol: float,
    *,
    method: str,
    iterations: int,
    t_start: float,
    history: list[tuple[float, float]],
    stats: dict,
) -> SolveResult:
    """What a solver returns: its last state, or the best one seen when that is
    better (a stall, a cap, a divergence, a friction update that made things
    worse), with ``converged`` decided by ``verdict`` from fresh forces.
    ``loop_diag``: empty when the loop converged, else why it stopped."""
    note = ""
    stopped = loop_diag.startswith("stopped by callback") and finite(x)  # the caller's own choice of state
    if loop_diag and not stopped and best.x is not None and (not finite(x) or not np.isfinite(r) or best.r < r):
        note = f"; returned the best state seen (residual {best.r:.3g} at iteration {best.it}, last {r:.3g})"
        x = best.restore()
    ok, r_fresh, why = verdict(model, x, tol)
    diag = ""
    if not ok:
        diag = loop_diag or why
        if loop_diag and why and not why.startswith("residual"):
            diag = f"{loop_diag}; {why}"
        diag += note
    return SolveResult(
        x=x,
        residual=float(r_fresh),
        iterations=iterations,
        wall_time=time.perf_counter() - t_start,
        converged=ok,
        method=method,
        diagnosis=diag,
        history=history,
        stats=stats,
    )


def bad_start(method: str, x: np.ndarray, stats: dict) -> SolveResult:
    """The result for a start that is not finite (NaN or inf positions)."""
    return SolveResult(
        x=np.nan_to_num(x),
        residual=float("inf"),
        iterations=0,
        wall_time=0.0,
        converged=False,
        method=method,
        diagnosis="diverged: non-finite initial positions",
        stats=stats,
    )


class FrictionSchedule:
    """When a solver touches the friction anchors (one policy for every solver).

    1. Frictionless settling while the relative residual is above ``after``: a
       fresh placement starts inside the contact layer with large normal forces,
       and anchors made there would pin the cloth where it was placed.
    2. ``engage``: anchors where the cloth rests (``update_friction``), once the
       residual is below ``after`` or the solver reports a crawl (a garment
       sliding or turning on the body: friction is what stops it).
    3. ``during``, every ``every`` iterations: anchors pulled beyond mu_s f_n slip
       (``slip_friction``: kinetic friction as a constant force), so a slide spreads
       within one solve, and the kinetic friction of slipping vertices is resized
       to mu_k f_n where they now are (``rescale_slipping``). Anchors never move
       otherwise: re-anchoring sliding vertices at the kinetic limit as the cloth
       moves creeps without end.
    4. ``at_balance`` (residual <= tol): slipping vertices stick where they came to
       rest, new contacts are anchored, anchors off the body let go; if an anchor
       still holds more than mu_s f_n (beyond ``friction_allowance``) it slips and
       the solve goes on. Returns True when the forces changed.
    """

    def __init__(self, model, x: np.ndarray, r: float, tol: float, after: float, every: int):
        self.model = model
        self.present = "friction" in getattr(model, "terms", ()) and hasattr(model, "slip_friction")
        self.every = max(1, int(every))
        self.after = after
        self.on = False
        self.allowance = friction_allowance(model, x, tol) if self.present else 0.0
        self.slipped = 0
        self.checks = 0
        self.excess = 0.0
        if self.present:
            if r <= after:
                self.engage(x)  # a warm start keeps the anchors it balanced against
            else:
                model.release_friction()

    def engage(self, x: np.ndarray) -> None:
        self.model.update_friction(x)
        self.on = True

    def after_step(self, it: int, x: np.ndarray, r: float, crawling: bool, stuck: bool = False) -> bool:
        """Between iterations; True when the forces changed. ``crawling``: the residual
        has not halved over the solver's window while below 1; ``stuck``: the same at
        any residual. With 'huber' friction a stuck solve engages friction: cloth that
        slides off the body it landed on (a sheet falling onto a sphere, nothing
        pinned, residual about 1 as it goes) never balances without it, and the
        smooth potential adds no slip events to pay for engaging early. The slip-event
        anchors keep the crawl rule (below 1) that garment drapes were measured with."""
        if not self.present:
            return False
        if not self.on:
            smooth = getattr(self.model, "friction_model", "anchors") == "huber"
            if r <= self.after or crawling or (stuck and smooth):
                self.engage(x)
                return True
            return False
        if it % self.every == 0 and r <= self.after:
            # far from a balance the anchors carry transients, not the cloth's pull
            n = self.model.slip_friction(x)
            self.slipped += n
            # kinetic friction follows the normal force where the vertex now is
            rescaled = self.model.rescale_slipping(x) if hasattr(self.model, "rescale_slipping") else 0.0
            return n > 0 or rescaled > 0.0
        return False

    def holds(self) -> bool:
        """No vertex is slipping (a balance with slipping vertices is a moment of a slide)."""
        return not (self.present and self.model.slipping.any())

    def at_balance(self, x: np.ndarray) -> bool:
        """At a state balanced for the current anchors; True when the forces changed."""
        if not (self.present and self.on):
            return False
        self.checks += 1
        m = self.model
        if getattr(m, "friction_model", "anchors") == "huber":
            # lagged limits refreshed where the cloth now rests; a balance holds when
            # that changes no friction force by more than the allowance
            change, released = m.lag_friction(x)
            self.excess = float(m.friction_excess(x))
            return released > 0 or change > self.allowance
        changed = bool(m.stick_slipping(x)) | bool(m.refresh_contacts(x))
        self.excess = float(m.friction_excess(x))
        if self.excess > self.allowance:
            self.slipped += m.slip_friction(x)
            changed = True
        return changed

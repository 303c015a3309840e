"""How far a predicted drape is from the true equilibrium: a slip-aware estimate.

``Predictor.distance_of`` asks :func:`estimate_distance`. The cheap estimate is
one chord-Newton step from the prediction x, ``t K⁻¹ F(x; X(d))`` with the
factor K of the equilibrium the prediction started from and t near the
energy's minimum along the step at the edited rest shape X(d) (``_line_min``).
It holds the friction anchors: an edit that pulls anchors beyond their static
Coulomb cone (|f_t| > mu_s f_n) makes the true re-solve slide the cloth there,
which held anchors cannot show (``couture bench preview_error``: the true
re-solves slip 3 to 155 anchors per edit).

The slip-aware rounds, taken only when some anchor is beyond its cone after
the chord step, each:

1. releases the anchors beyond their cone as the solvers do
   (``ClothModel.slip_friction``: kinetic friction mu_k f_n as a constant
   force, no tangential spring);
2. solves the corrected chord system (K - ΔK) dy = F(y) at the current state
   y, ΔK the springs k_t (I - n nᵀ) of every anchor released so far, by
   conjugate gradients preconditioned with the factor of K (the
   preconditioned operator is the identity plus a rank-2-per-anchor update;
   at most ``cg_iters`` iterations; it stops at negative curvature);
3. steps to the energy's minimum along dy (kinetic friction included);
4. rescales the kinetic forces to the normal force where the vertices now are.

The rounds stop when a round releases no new anchor and its step moved no
vertex more than ``settle`` times the distance so far (the corrected chord
iteration has settled), or after ``rounds`` rounds. The estimate is the
largest vertex motion from x to the last state. Forces and energy are
measured relative to the equilibrium's own unbalance f_eq (see
``Predictor.set_equilibrium``). The model's friction state is restored on
return. Pure: no bus code, no per-scene constants.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .factor import FactorizationError, _factorize


@dataclass
class DistanceEstimate:
    """What :func:`estimate_distance` found."""

    distance: float
    """largest vertex motion [m] from the prediction to the estimate's last state"""
    chord: float
    """the cheap (held-friction) estimate [m]: one chord step"""
    slipped: int = 0
    """anchors released over all rounds"""
    rounds: int = 0
    """slip-aware rounds taken (0: nothing slipped after the chord step)"""
    cg_iterations: int = 0
    """conjugate-gradient iterations over all rounds"""
    factorizations: int = 0
    """factorizations of the stiffness less the released springs (``refactor_after``)"""
    evaluations: int = 0
    """energy or force evaluations of the cloth model (the cost besides
    ``cg_iterations + rounds + 1`` back-substitutions with the factor)"""
    x: np.ndarray | None = None
    """the estimate's last state (n, 3) [m]: the prediction corrected by the steps"""


def _line_min(energy, energy_and_forces, x, dx, e0, slope, *, t_max=1.0, refine=5, t_min=1e-9) -> float:
    """Step length near the energy's minimum along dx from x (slope = -dE/dt at 0
    > 0), at most ``t_max``: shrink from t_max until the energy is below e0
    (each time to the minimum of the parabola through e0, the slope and the
    energy there, kept within [0.01, 0.5] of the step), then ``refine``
    bisections (geometric in a wide bracket) on the sign of the directional
    derivative in the bracket that holds its root. A backtracking (Armijo) search alone accepts any step that
    lowers the energy enough: up to twice past the minimum of a quadratic, and
    anywhere in a flat valley (a chord step along a soft mode is often 10⁴
    times too long, and the energy along it flat over tens of mm)."""
    if slope <= 0:
        return 0.0

    def dE(t):
        e, f = energy_and_forces(x + t * dx)
        h = -float(np.vdot(f, dx))
        if not (np.isfinite(e) and np.isfinite(h)):
            return np.inf, np.inf
        return e, h

    t = t_max
    e = energy(x + t * dx)
    above: float | None = None  # the last step tried with a higher energy
    while not e <= e0 and t > t_min:
        above = t
        curv = (e - e0 + slope * t) / (t * t) if np.isfinite(e) else np.inf
        t_par = slope / (2.0 * curv) if curv > 0 else 0.5 * t
        t = min(max(t_par, 0.01 * t), 0.5 * t)
        e = energy(x + t * dx)
    if not e <= e0:
        return 0.0
    e, h = dE(t)
    flat = 0.01 * slope  # |dE/dt| this small: at the minimum, as far as the distance goes
    if abs(h) <= flat or (h < 0.0 and above is None):
        return t  # at the minimum, or still descending at the longest step allowed
    if h < 0.0:
        assert above is not None  # returned above otherwise
        lo, hi = t, above
    else:
        lo, hi = 0.0, t
    for _ in range(refine):
        mid = np.sqrt(lo * hi) if lo > 0.0 and hi > 4.0 * lo else 0.5 * (lo + hi)
        em, hm = dE(mid)
        if abs(hm) <= flat and em <= e0:
            return mid
        if hm < 0.0 and em <= e0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


class _Reduced:
    """The factor's own coordinates: free dofs without its gauge dofs, null modes
    projected out (``SensitivityFactor.solve_free``)."""

    def __init__(self, factor):
        self.f = factor
        self.n = factor.n
        self.dofs = factor.dofs
        self.keep = factor.keep
        self.N = factor.N
        self.A = factor._A.tocsr()

    def to(self, v: np.ndarray) -> np.ndarray:
        b = np.asarray(v, dtype=np.float64).reshape(-1)[self.dofs]
        if self.N.shape[1]:
            b = b - self.N @ (self.N.T @ b)
            b = b[self.keep]
        return b

    def back(self, z: np.ndarray) -> np.ndarray:
        y = np.zeros(len(self.dofs))
        if self.N.shape[1]:
            y[self.keep] = z
            y = y - self.N @ (self.N.T @ y)
        else:
            y = z
        out = np.zeros(3 * self.n)
        out[self.dofs] = y
        return out.reshape(self.n, 3)

    pre = None
    """a factor of A - D for the anchors released when it was made (``refactor``),
    else None: the equilibrium's own factor preconditions"""
    pre_released = 0
    """how many anchors ``pre`` has released"""

    def precondition(self, z: np.ndarray) -> np.ndarray:
        return (self.pre if self.pre is not None else self.f._fac).solve(z)

    def refactor(self, D: sp.csr_matrix, released: int) -> bool:
        """Factor A - D (the stiffness less the released springs) as the
        preconditioner: one factorization instead of a CG iteration per released
        anchor (the preconditioned operator's rank-2-per-anchor update). False,
        keeping the old one, where A - D is not positive definite."""
        try:
            self.pre = _factorize((self.A - D).tocsc())
        except (FactorizationError, np.linalg.LinAlgError, RuntimeError, ValueError):
            return False
        self.pre_released = released
        return True

    def anchor_springs(self, verts: np.ndarray, normals: np.ndarray, k_t: float) -> sp.csr_matrix:
        """ΔK of the anchor springs k_t (I - n nᵀ) at ``verts``, in these coordinates."""
        n3 = 3 * self.n
        blocks = k_t * (np.eye(3)[None] - normals[:, :, None] * normals[:, None, :])
        rows = (3 * verts[:, None, None] + np.arange(3)[None, :, None]).repeat(3, axis=2)
        cols = (3 * verts[:, None, None] + np.arange(3)[None, None, :]).repeat(3, axis=1)
        D = sp.csr_matrix((blocks.ravel(), (rows.ravel(), cols.ravel())), shape=(n3, n3))
        D = D[self.dofs][:, self.dofs]
        if self.N.shape[1]:
            D = D[self.keep][:, self.keep]
        return D.tocsr()


def _pcg(red: _Reduced, D: sp.csr_matrix, b: np.ndarray, iters: int, rtol: float) -> tuple[np.ndarray, int]:
    """Approximate (A - D)⁻¹ b by CG preconditioned with A's factor; stops at
    ``iters``, at ||r||_M < rtol ||b||_M or at non-positive curvature (then the
    iterate so far, or the preconditioned residual when there is none)."""
    z = np.zeros_like(b)
    r = b.copy()
    s = red.precondition(r)
    rs = float(r @ s)
    if rs <= 0 or not np.isfinite(rs):
        return s, 0
    rs0 = rs
    p = s.copy()
    it = 0
    for it in range(1, iters + 1):
        q = red.A @ p - D @ p
        pq = float(p @ q)
        if pq <= 0 or not np.isfinite(pq):
            if not z.any():
                z = p
            it -= 1
            break
        a = rs / pq
        z += a * p
        r -= a * q
        s = red.precondition(r)
        rs_new = float(r @ s)
        if rs_new <= rtol * rtol * rs0:
            break
        p = s + (rs_new / rs) * p
        rs = rs_new
    return z, it


def _over_cone(model, x: np.ndarray) -> bool:
    """Does any anchor hold more than mu_s f_n at x (``ClothModel.friction_excess``)?"""
    return "friction" in model.terms and bool(model.anchored.any()) and model.friction_excess(x) > 0.0


def estimate_distance(
    model,
    factor,
    x: np.ndarray,
    f_eq: np.ndarray,
    *,
    rounds: int = 8,
    settle: float = 0.1,
    cg_iters: int = 50,
    cg_rtol: float = 1e-2,
    refactor_after: int | None = 10,
) -> DistanceEstimate:
    """Estimated distance of the predicted drape x (n, 3) from the equilibrium of
    ``model`` at its (edited) rest shape, ``model`` holding the friction state
    that balances the equilibrium ``factor`` was built at (``hold_friction``);
    f_eq: the forces of that model at that equilibrium (see the module
    docstring). ``rounds``: at most this many corrected steps after the chord
    step, taken only when the chord step left an anchor beyond its cone (0:
    the chord step alone); they stop when a step releases no new anchor and
    moved no vertex more than ``settle`` times the distance so far.
    ``cg_iters``, ``cg_rtol``: the CG budget of each step; ``refactor_after``:
    when more than this many anchors (and more than half as many as before)
    were released since the preconditioner was made, factor the stiffness
    less their springs anew (None: always the
    equilibrium's factor; at 10k vertices a thousand anchors slip, and CG
    with the equilibrium's factor took 300 back-substitutions). ``model``'s
    friction state is left as it was."""
    x = np.asarray(x, dtype=np.float64)
    if x.shape != (model.n, 3):
        raise ValueError(f"x must have shape ({model.n}, 3), got {x.shape}")
    if rounds < 0 or cg_iters < 1 or not settle >= 0:
        raise ValueError("rounds and settle must be >= 0 and cg_iters >= 1")
    if not len(x):
        return DistanceEstimate(0.0, 0.0, x=x.copy())

    def energy(y):
        out.evaluations += 1
        return model.energy(y) + float(np.vdot(f_eq, y))

    def energy_and_forces(y):
        out.evaluations += 1
        e, f = model.energy_and_forces(y)
        return e + float(np.vdot(f_eq, y)), f - f_eq

    out = DistanceEstimate(0.0, 0.0)

    e0, r = energy_and_forces(x)
    dx = factor.correction(r)
    t = _line_min(energy, energy_and_forces, x, dx, e0, float(np.vdot(r, dx)))
    y = x + t * dx
    out.distance = out.chord = float(np.max(np.linalg.norm(y - x, axis=1)))
    out.x = y
    if rounds == 0 or not _over_cone(model, y):
        return out

    red = _Reduced(factor)
    held = model.friction_state()
    anchored0 = model.anchored.copy()
    last = 0.0
    try:
        for _ in range(rounds):
            n_slip = model.slip_friction(y)
            if out.rounds and not n_slip and last <= settle * np.max(np.linalg.norm(y - x, axis=1)):
                break
            out.slipped += n_slip
            out.rounds += 1
            released = np.nonzero(anchored0 & ~model.anchored)[0]
            D = red.anchor_springs(released, held[3][released], model.friction_stiffness)
            new = len(released) - red.pre_released
            if refactor_after is not None and new > max(refactor_after, red.pre_released // 2):
                out.factorizations += red.refactor(D, len(released))
            e, r = energy_and_forces(y)
            z, its = _pcg(red, D, red.to(r), cg_iters, cg_rtol)
            out.cg_iterations += its
            dy = red.back(z)
            t = _line_min(energy, energy_and_forces, y, dy, e, float(np.vdot(r, dy)))
            if t == 0.0:
                break
            y = y + t * dy
            last = t * float(np.max(np.linalg.norm(dy, axis=1)))
            model.rescale_slipping(y)  # kinetic friction follows the normal force, as in the solvers
        out.distance = float(np.max(np.linalg.norm(y - x, axis=1)))
        out.x = y
    finally:
        model.set_friction_state(held)
    return out

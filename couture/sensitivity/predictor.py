"""The sensitivity node's state machine as a plain class (SC §7.2).

    new equilibrium  -> set_equilibrium(model, x_eq, d)   (cheap; marks stale)
    idle time        -> refactor()                         (worker thread)
    press(psi)       -> response columns S (n, 3, 2); the cache restarts
                        with the anchor sample (d0, x_eq, S)
    drag(d)          -> Prediction(x, method, error_estimate)
    solver result during a drag -> add_sample(d_m, x_m)   (worker thread:
                        refactor at x_m, columns there, new GMLS sample)
    release(d)       -> warm start for the solver

d is the pointer motion of the active edit [m of pattern space] (or a sloper
parameter change), and the rest shape follows it linearly:
X(d) = X_0 + Ψ (d - d_0).
"""

from __future__ import annotations

import copy
import threading
import time
from dataclasses import dataclass

import numpy as np

from couture.cloth.model import ClothModel

from .distance import DistanceEstimate, estimate_distance
from .factor import FactorInfo, SensitivityFactor
from .friction import FrictionHeld, hold_friction
from .gmls import GMLSCache

METHODS = ("linear", "gmls", "mls")


@dataclass
class Prediction:
    x: np.ndarray
    """predicted drape [m], shape (n, 3), float64"""
    d: np.ndarray
    """design point (2,)"""
    method: str
    """'linear' | 'gmls' | 'mls' | 'none' (no sensitivity yet: the equilibrium itself)"""
    error_estimate: float
    """relative force residual of x at the edited rest shape X(d) (NaN when not computed)"""
    predict_s: float
    """wall time of the prediction itself [s]"""
    residual_s: float = 0.0
    """wall time of the error estimate [s]"""
    samples: int = 0
    """samples in the cache"""
    error_m: float = float("nan")
    """estimated distance of x from the true equilibrium at X(d) [m]: the largest
    vertex motion of a chord-Newton correction that lets over-pulled friction
    anchors slip (:meth:`Predictor.distance_of`; NaN when not computed)"""


def default_model_at(model: ClothModel, X: np.ndarray) -> ClothModel:
    """A model like ``model`` with rest positions X (n, 2), without mutating it:
    a shallow copy with ``set_rest_positions`` (which replaces, never mutates,
    the rest-dependent arrays); its in-place stiffness buffer is copied so the
    two never share state."""
    m = copy.copy(model)
    m._K = m._K.copy()
    if "friction" in m.terms:  # a solve on the copy moves its anchors, never the original's
        for name in ("anchored", "sliding", "anchor", "anchor_normal", "slipping", "slip_force"):
            setattr(m, name, getattr(m, name).copy())
    m.set_rest_positions(X)
    return m


class Predictor:
    """Sensitivity predictor for one mesh generation at a time. Thread-safe:
    ``refactor`` and ``add_sample`` may run in a worker thread while ``drag``
    runs at pointer rate."""

    def __init__(
        self,
        *,
        method: str = "gmls",
        bend_floor: bool = False,
        cache_bytes: int = 64 << 20,
        cache_samples: int = 16,
        eps2: float = 1e-3,
        d_scale: float = 1.0,
        max_active: int = 6,
        dtype=np.float32,
        error_estimate: bool = True,
        model_at=default_model_at,
        factor_kwargs: dict | None = None,
        friction: bool = True,
        consistent: bool = True,
        defect_scale: float = 0.1,
    ):
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}")
        self.method = method
        self.bend_floor = bend_floor
        self.cache_kw = dict(
            max_bytes=cache_bytes,
            max_samples=cache_samples,
            eps2=eps2,
            d_scale=d_scale,
            max_active=max_active,
            dtype=dtype,
            consistent=consistent,
            defect_scale=defect_scale,
        )
        """``consistent``, ``defect_scale``: GMLS with columns corrected to agree with the
        cached drapes (``couture.sensitivity.gmls.consistent_derivatives``)"""
        self.error_estimate = error_estimate
        self.model_at = model_at
        self.factor_kwargs = factor_kwargs or {}
        self.friction = friction
        """rebuild the friction state that balances each equilibrium (``hold_friction``)
        before linearising there: the solver's anchors as springs, vertices at
        the Coulomb limit as sliding; False keeps the model's state as it is"""
        self.friction_held = FrictionHeld()
        """what the latest equilibrium's friction state is"""
        self._lock = threading.RLock()
        self.model: ClothModel | None = None
        self.x_eq: np.ndarray | None = None
        self.f_eq = np.zeros((0, 3))
        self.d_eq = np.zeros(2)
        self.factor: SensitivityFactor | None = None
        self._factor_for: np.ndarray | None = None
        self.cache: GMLSCache | None = None
        self.psi: np.ndarray | None = None
        self.d0 = np.zeros(2)
        self.S0: np.ndarray | None = None
        self.last: Prediction | None = None
        self._edit_lock = threading.RLock()
        self._edit_model: ClothModel | None = None
        self._edit_d: np.ndarray | None = None

    # -- equilibrium and factorization -------------------------------------
    def set_equilibrium(self, model: ClothModel, x_eq: np.ndarray, d=None) -> None:
        """A new equilibrium (new mesh or a converged solve): remember it; the
        factorization is stale until ``refactor`` runs."""
        with self._lock:
            if self.model is not model or self.cache is None or self.cache.n != model.n:
                self.cache = GMLSCache(model.n, **self.cache_kw)
            self.model = model
            self.x_eq = np.array(x_eq, dtype=np.float64, copy=True)
            if self.friction:
                self.friction_held = hold_friction(model, self.x_eq)
            # what this model leaves unbalanced at the solver's equilibrium: the solver's
            # anchor springs lie in the tangent plane where each anchor was made, so at
            # x_eq they also push along the contact normal, which the rebuilt anchors
            # (tangent plane at x_eq) do not (on the default skirt a relative residual
            # of 1.4 at the equilibrium, an estimate of 0.07 mm for no edit at all)
            self.f_eq = model.forces(self.x_eq)
            self.d_eq = np.zeros(2) if d is None else np.asarray(d, dtype=np.float64).reshape(2)
            self._edit_model = None

    @property
    def stale(self) -> bool:
        return self.factor is None or self._factor_for is not self.x_eq

    def _equilibrium(self) -> tuple[ClothModel, np.ndarray, GMLSCache]:
        """The latest (model, x_eq, cache); an error before ``set_equilibrium``.
        Callers that need them consistent hold ``_lock``."""
        if self.model is None or self.x_eq is None or self.cache is None:
            raise RuntimeError("Predictor: no equilibrium yet (set_equilibrium first)")
        return self.model, self.x_eq, self.cache

    def _pressed(self) -> np.ndarray:
        """The pointer Jacobian Ψ of the active edit; an error before ``press``."""
        if self.psi is None:
            raise RuntimeError("Predictor: no edit pressed yet (press first)")
        return self.psi

    def refactor(self) -> FactorInfo:
        """Factor the stiffness at the latest equilibrium (idle time; worker thread)."""
        with self._lock:
            model, x, _ = self._equilibrium()
        f = SensitivityFactor(model, x, bend_floor=self.bend_floor, **self.factor_kwargs)
        with self._lock:
            if self.x_eq is x:
                self.factor, self._factor_for = f, x
        return f.info

    # -- edit phases --------------------------------------------------------
    def press(self, psi: np.ndarray, d0=None) -> np.ndarray:
        """Pointer pressed on an element whose pointer Jacobian is psi (n, 2, 2)
        (a sloper parameter: dX/dg in column 0, column 1 zero): the two response
        columns S (n, 3, 2); restarts the cache at (d0, x_eq, S). d0 defaults to
        the design point given with the equilibrium."""
        if self.stale:
            self.refactor()
        with self._lock:
            model = self._equilibrium()[0]
            f = self.factor
            assert f is not None, "no factorization: the equilibrium changed while it was factored"
            self.psi = psi = np.asarray(psi, dtype=np.float64)
            self.d0 = self.d_eq.copy() if d0 is None else np.asarray(d0, dtype=np.float64).reshape(2)
            self.X0 = np.array(model.X, dtype=np.float64)
        S = f.columns(psi)
        with self._lock:
            self.S0 = S
            cache = self._equilibrium()[2]
            cache.clear()
            cache.add(self.d0, f.x_eq, S, anchor=True)
            self._edit_model = None
        return S

    def rest_at(self, d) -> np.ndarray:
        """Rest positions X(d) = X_0 + Ψ (d - d0), shape (n, 2)."""
        dd = np.asarray(d, dtype=np.float64).reshape(2) - self.d0
        return self.X0 + self._pressed() @ dd

    def model_for(self, d):
        """The cloth model at the edited rest shape X(d): one private copy per
        press, its rest positions updated in place (a rest update costs about
        as much as a force evaluation; see the benchmark)."""
        d = np.asarray(d, dtype=np.float64).reshape(2)
        with self._edit_lock:
            if self._edit_model is None:
                self._edit_model = self.model_at(self._equilibrium()[0], self.rest_at(d))
                self._edit_d = d.copy()
            elif not np.array_equal(d, self._edit_d):
                self._edit_model.set_rest_positions(self.rest_at(d))
                self._edit_d = d.copy()
            return self._edit_model

    def error_of(self, x: np.ndarray, d) -> float:
        """Relative force residual of a predicted drape x at the rest shape X(d)
        (the prediction's error estimate). At 10k vertices it costs tens of ms:
        the node computes it for the latest prediction in idle time."""
        with self._edit_lock:
            m = self.model_for(d)
            f = m.forces(x) - self._f_eq()
            return float(np.linalg.norm(f[m.free])) / m.residual_denominator(x)

    def _f_eq(self) -> np.ndarray:
        """Forces of the node's model at the equilibrium (``set_equilibrium``); the
        error estimates measure a prediction's forces relative to them."""
        with self._lock:
            self._equilibrium()
            return self.f_eq

    slip_rounds = 8
    """at most this many slip-aware rounds in :meth:`distance_of` (0: the held-friction chord step alone)"""
    last_distance: DistanceEstimate | None = None
    """what the latest :meth:`distance_of` found (anchors released, CG iterations)"""

    def distance_of(self, x: np.ndarray, d) -> float:
        """Estimated distance [m] of a predicted drape x from the true equilibrium
        at X(d) (``couture.sensitivity.distance``): the largest vertex motion of
        one chord-Newton step from x, ``t K⁻¹ F(x; X(d))`` with the factor at the
        equilibrium and t near the energy's minimum along it at X(d); when that
        step pulls friction anchors beyond their Coulomb cone, up to
        ``slip_rounds`` rounds that release them (kinetic friction, as the
        solvers do) and step along the corrected system (K - the released
        springs), solved by CG preconditioned with the factor, until no anchor
        slips and the steps settle.

        The line minimum matters: the bare correction (t = 1) overshoots by
        orders of magnitude where the prediction loads a soft mode (a light
        fabric's wrinkles, a sheet's new contacts; measured up to 1000x on SC's
        Fig. 5 strip, 10⁴x on the default skirt), and a backtracking search
        lands anywhere in the flat valley along it. The slip rounds matter
        where an edit makes the cloth slide on the body (``couture bench
        preview_error``). :attr:`last_distance` keeps the details. NaN before
        a factorization."""
        f = self.factor
        if f is None:
            return float("nan")
        with self._edit_lock:
            m = self.model_for(d)
            est = estimate_distance(m, f, x, self._f_eq(), rounds=self.slip_rounds)
        self.last_distance = est
        return est.distance

    def drag(self, d, method: str | None = None, error_estimate: bool | None = None) -> Prediction:
        """Prediction at pointer position d (2,) by 'gmls' (default), 'mls' or
        'linear'; with the error estimate unless disabled (``error_estimate``
        here or in the constructor; see :meth:`error_of` for its cost)."""
        method = method or self.method
        d = np.asarray(d, dtype=np.float64).reshape(2)
        t0 = time.perf_counter()
        with self._lock:
            cache = self.cache
            if cache is None or not len(cache):
                x, used = self._equilibrium()[1].copy(), "none"
            elif method == "linear":
                x, used = cache.predict_linear(d), "linear"
            else:
                x, used = cache.predict(d, method), method
            nsamp = len(cache) if cache is not None else 0
        t1 = time.perf_counter()
        err, err_m, tr = float("nan"), float("nan"), 0.0
        if (self.error_estimate if error_estimate is None else error_estimate) and self.psi is not None:
            err = self.error_of(x, d)
            err_m = self.distance_of(x, d)
            tr = time.perf_counter() - t1
        p = Prediction(
            x=x, d=d, method=used, error_estimate=err, error_m=err_m, predict_s=t1 - t0, residual_s=tr, samples=nsamp
        )
        self.last = p
        return p

    def add_sample(self, d_m, x_m: np.ndarray, *, sensitivity: bool = True) -> FactorInfo | None:
        """A solver equilibrium x_m at design point d_m during a drag: refactor
        there, compute its columns and add a first-order sample (zeroth order
        only with ``sensitivity=False``). Idle time / worker thread."""
        d_m = np.asarray(d_m, dtype=np.float64).reshape(2)
        x_m = np.asarray(x_m, dtype=np.float64)
        info, S = None, None
        if sensitivity:
            model_m = self.model_at(self._equilibrium()[0], self.rest_at(d_m))
            if self.friction:
                hold_friction(model_m, x_m)
            # one set of columns here: matrix-free ∂F/∂X is cheaper than assembling it
            kw = {"press_matrix": False, "keep_columns": 0, **self.factor_kwargs}
            f = SensitivityFactor(model_m, x_m, bend_floor=self.bend_floor, **kw)
            S = f.columns(self._pressed())
            info = f.info
        with self._lock:
            self._equilibrium()[2].add(d_m, x_m, S)
        return info

    def release(self, d) -> np.ndarray:
        """Warm start for the solver at the final pointer position d: the prediction there."""
        return self.drag(d, error_estimate=False).x

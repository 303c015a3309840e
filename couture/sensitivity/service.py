"""The sensitivity node's state machine, free of bus code (nodes/sensitivity adapts it).

SC §7.2, one gesture at a time:

- a fine mesh, matched with the design it was drafted from
  (:class:`couture.designs.MeshMatcher`), becomes a cloth model
  (:meth:`SensitivityService.take`); a final solver drape on it becomes the
  predictor's equilibrium and the stiffness is refactored
  (:meth:`~SensitivityService.equilibrium`, idle time);
- **press** (:meth:`~SensitivityService.press`) opens a gesture, if it was
  made on the design whose mesh is held (a press on an older design or on a
  number not held here is rejected: logged with both generations, counted
  ``stale_edits`` / ``foreign_edits``); the
  remesher's Ψ for it (:meth:`~SensitivityService.psi`) gives the two response
  columns. A 2D drag uses Ψ of the dragged element; a 3D tug of the drape uses
  Ψ of ``param:<name>`` (dX/dg) and the picked point's sensitivity s = ∂x/∂g;
- **drag** (:meth:`~SensitivityService.drag`): a prediction (GMLS once samples
  exist, linear before); its error estimate, the prediction's relative force
  residual, follows in idle time (:meth:`~SensitivityService.estimate`);
- **pause** (:meth:`~SensitivityService.pause`): the pointer rests, so a short
  solve at the current design point (:meth:`~SensitivityService.enrich`) adds
  a sample to the GMLS cache (SC's progressive nonlinear model);
- **held**: a press that arrives before the equilibrium on its mesh (the
  final drape came, its refactorization is under way) is held, not dropped:
  its Ψ, its latest drag and its release wait (counted ``gestures_held``), and
  :meth:`~SensitivityService.resume` serves them once the equilibrium is
  there; one held past ``hold_s`` is given up, logged and counted
  ``gestures_expired`` (:meth:`~SensitivityService.expire`). Drags and a
  release that come before the gesture's Ψ wait the same way.
  :meth:`~SensitivityService.readiness` says whether a press would be served
  at once (the node publishes it in its status);
- **release** (:meth:`~SensitivityService.release`): the final prediction (the
  solver's warm start); a 3D tug also yields its new design, committed through
  :func:`couture.pattern.edit.apply_edit` like a 2D handle drag, unless another
  design was meshed during the gesture (then the tug edited a stale design: no
  new design, counted ``stale_edits``).

The adapter decides which thread runs what: callbacks call the cheap methods
(``offer_*``, ``press``, ``moved``, ``pause``), worker threads the rest.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from couture.cloth.model import ClothModel
from couture.designs import Matched, MeshArrival, MeshMatcher, MeshOutcome, judge
from couture.mesh import GarmentMesh
from couture.pattern.edit import apply_edit
from couture.pattern.errors import PatternError
from couture.pattern.limits import check_simulation_values
from couture.sensitivity.drag3d import drag_to_param
from couture.sensitivity.factor import FactorInfo
from couture.sensitivity.predictor import Prediction, Predictor
from couture.solvers import get_solver
from couture.solvers.base import Solver
from couture.solvers.service import scene_from_design
from schemas.design import Design

log = logging.getLogger(__name__)


class NoEquilibrium(RuntimeError):
    """Ψ does not fit the mesh the gesture was pressed on: no prediction."""


@dataclass(frozen=True)
class Readiness:
    """Whether a press is served at once: the predictor holds the refactored
    equilibrium of the fine mesh held."""

    ready: bool
    generation: int = -1
    """the design (the remesher's number) of that equilibrium's mesh, -1 when not ready"""
    mesh_generation: int = -1
    """that fine mesh's number, -1 when not ready"""
    regularization: str = ""
    """what the factorization added to the exact linearisation ('none'; '' before one)"""


@dataclass
class SensitivityConfig:
    method: str = "gmls"
    """'gmls', 'mls' or 'linear'"""
    pause_s: float = 0.3
    """[s] without pointer motion before the idle solve that enriches the cache"""
    enrich_seconds: float = 2.0
    """[s] budget of one idle solve"""
    enrich_tol: float = 1e-3
    """relative residual the idle solve aims for"""
    enrich_solver: str = "newton"
    """solver of the idle solves (couture.solvers.get_solver)"""
    hold_s: float = 5.0
    """[s] a gesture held for want of its equilibrium (or its release for want
    of Ψ) waits at most this long, then it is expired"""


@dataclass
class Press:
    """An edit press, as the service needs it."""

    edit_id: str
    element: str = ""
    """element id of couture.pattern.edit for a 2D drag ('' for a 3D tug)"""
    generation: int = 0
    """the remesher's number for the design the edit was made on (the edit message's)"""
    param: str = ""
    """3D tug: the sloper option it drives"""
    picked_vertex: int = -1
    """3D tug: the fine-mesh vertex grabbed, -1 for a 2D drag"""
    view_proj: np.ndarray | None = None
    """3D tug: camera view-projection (world [m] -> clip), shape (4, 4)"""
    viewport: tuple[int, int] = (1, 1)
    """3D tug: viewport [px]"""

    @property
    def is_tug(self) -> bool:
        return self.picked_vertex >= 0 and bool(self.param)


@dataclass
class Gesture:
    """One press .. release, and what the service learnt during it."""

    press: Press
    mesh_generation: int
    """the fine mesh the gesture's equilibrium lives on"""
    generation: int
    """the generation (the remesher's number) of that mesh's design"""
    design: Design | None
    """that design: a 3D tug edits it"""
    last_motion: float
    """[s] clock time of the latest pointer motion"""
    ready: bool = False
    """the response columns are computed (Ψ arrived)"""
    s_point: np.ndarray | None = None
    """3D tug: ∂x/∂g at the picked vertex [m per unit of g], shape (3,)"""
    d: np.ndarray = field(default_factory=lambda: np.zeros(2))
    """latest design point (2,): the pointer motion [m], or (Δg, 0) for a tug"""
    enriched_at: np.ndarray | None = None
    """design point of the latest idle solve (None: none yet)"""
    psi: np.ndarray | None = None
    """Ψ (n, 2, 2) once it arrived (kept until the equilibrium is there)"""
    held_since: float | None = None
    """[s] clock time the gesture began to wait (for its equilibrium, or its
    release for Ψ); None: it never waited"""
    pending_d: np.ndarray | None = None
    """the latest drag (raw, as received) that came before the columns"""
    pending_release: np.ndarray | None = None
    """the release (raw) that came before the columns"""

    @property
    def edit_id(self) -> str:
        return self.press.edit_id


@dataclass
class PredictionOut:
    """A prediction to publish on ``drape/predicted``."""

    edit_id: str
    generation: int
    mesh_generation: int
    x: np.ndarray
    """predicted drape [m], shape (n, 3), float64"""
    d: np.ndarray
    """design point (2,)"""
    method: str
    error_estimate: float | None
    """relative force residual of x at the edited rest shape (None: not computed yet)"""
    error_estimate_m: float | None = None
    """estimated distance of x from the true equilibrium [m] (None: not computed yet)"""
    release: bool = False
    """the gesture's final prediction (the solver's warm start)"""
    prediction: Prediction | None = field(default=None, repr=False)
    """the predictor's own record (identifies the newest prediction)"""


@dataclass
class ReleaseOut:
    prediction: PredictionOut | None
    design: Design | None = None
    """3D tug: the design with the driven option moved by Δg (None otherwise)"""
    generation: int = 0
    """the generation to ask for when publishing ``design`` (the remesher numbers it)"""
    design_id: str = ""
    """the new design's identity (unique)"""


class SensitivityService:
    """See the module docstring. ``clock`` [s] is injectable for tests; ``count``
    receives counter names (the node adds them to its status)."""

    def __init__(
        self,
        config: SensitivityConfig | None = None,
        *,
        predictor: Predictor | None = None,
        solver: Solver | None = None,
        clock: Callable[[], float] = time.monotonic,
        count: Callable[[str], object] = lambda name: None,
    ) -> None:
        self.config = config or SensitivityConfig()
        self.count = count
        """called with a counter's name on events worth counting ('insensitive_drags')"""
        self.predictor = predictor or Predictor(method=self.config.method, error_estimate=False)
        self.solver = solver or get_solver(self.config.enrich_solver)
        self.clock = clock
        self.matcher: MeshMatcher[GarmentMesh] = MeshMatcher()
        self.mesh: GarmentMesh | None = None
        self.mesh_generation = -1
        self.generation = -1
        self.model: ClothModel | None = None
        self.design: Design | None = None
        """the design the held mesh was drafted from"""
        self.gesture: Gesture | None = None
        self.eq_mesh_generation = -1
        """the fine mesh of the predictor's equilibrium (-1: none)"""
        self.eq_generation = -1
        """that mesh's design (the remesher's number)"""
        self._lock = threading.RLock()
        self._predict_lock = threading.Lock()
        """held while the equilibrium is replaced or the columns are computed"""

    # -- designs and meshes ---------------------------------------------------
    def offer_design(self, generation: int, design: Design, design_id: str = "") -> list[Matched[GarmentMesh]]:
        """A ``pattern``; returns the meshes that waited for it (to :meth:`take`)."""
        return self.matcher.add_design(generation, design, design_id)

    def offer_mesh(
        self, generation: int, mesh_generation: int, mesh: GarmentMesh, design_id: str = ""
    ) -> MeshOutcome[GarmentMesh]:
        """A fine mesh: matched with its design (then :meth:`take` it), parked, or dropped."""
        return self.matcher.add_mesh(MeshArrival("fine", generation, mesh_generation, mesh, design_id))

    def take(self, matched: Matched[GarmentMesh]) -> None:
        """Build the cloth model of a matched mesh (idle time: it costs a model
        build). Raises PatternError naming the field for a fabric outside its
        physical range (the remesher rejects those first); nothing is changed
        (the matcher does not count the mesh as taken)."""
        m = matched.mesh
        try:
            check_simulation_values(matched.design)
        except PatternError:
            self.matcher.refuse(m)
            raise
        model = ClothModel(m.payload, matched.design.fabric, scene_from_design(matched.design))
        with self._lock:
            self.mesh, self.mesh_generation, self.generation, self.model = (
                m.payload,
                m.mesh_generation,
                m.generation,
                model,
            )
            self.design = matched.design
        log.info("mesh generation %d: %d vertices", m.mesh_generation, m.payload.n_vertices)

    def equilibrium(self, mesh_generation: int, x: np.ndarray) -> FactorInfo | None:
        """A final solver drape x (n, 3) [m] on the fine mesh: the predictor's new
        equilibrium, refactored now (idle time). None when x is not on the mesh
        held, or a gesture has its columns (it keeps the equilibrium it started
        from). A gesture held for want of it is served by :meth:`resume`."""
        with self._predict_lock:
            with self._lock:
                model, generation, g = self.model, self.generation, self.gesture
                if (
                    model is None
                    or mesh_generation != self.mesh_generation
                    or x.shape != (model.n, 3)
                    or (g is not None and g.ready)
                ):
                    return None
                self.eq_mesh_generation = -1
            self.predictor.set_equilibrium(model, np.asarray(x, dtype=np.float64))
            info = self.predictor.refactor()
            with self._lock:
                self.eq_mesh_generation, self.eq_generation = mesh_generation, generation
        held = self.predictor.friction_held
        log.info(
            "refactored at mesh generation %d in %.0f ms (%s); friction: %d sticking, %d sliding; regularization: %s",
            mesh_generation,
            1e3 * info.refactor_s,
            info.backend,
            held.sticking,
            held.sliding,
            info.regularization,
        )
        return info

    def readiness(self) -> Readiness:
        """Whether a press on the mesh held is served at once (cheap; any thread)."""
        with self._lock:
            if self.model is None or self.eq_mesh_generation != self.mesh_generation:
                return Readiness(False)
            info = self.predictor.factor.info if self.predictor.factor is not None else None
            return Readiness(
                True, self.eq_generation, self.eq_mesh_generation, info.regularization if info is not None else ""
            )

    # -- gesture ----------------------------------------------------------------
    def press(self, press: Press) -> Gesture | None:
        """Open a gesture (it waits for its Ψ); replaces any open one. None,
        logged and counted, when the press was made on another design than
        the one whose mesh is held."""
        with self._lock:
            verdict = judge(press.generation, self.generation)
            if verdict != "current":
                self.count(f"{verdict}_edits")
                log.warning(
                    "edit %s: press on generation %d, the mesh held is of generation %d (%s): rejected",
                    press.edit_id,
                    press.generation,
                    self.generation,
                    verdict,
                )
                return None
            g = Gesture(
                press=press,
                mesh_generation=self.mesh_generation,
                generation=self.generation,
                design=self.design,
                last_motion=self.clock(),
            )
            self.gesture = g
            if self.eq_mesh_generation != self.mesh_generation:
                self._hold(g, "its equilibrium (the drape's refactorization)")
        return g

    def _hold(self, g: Gesture, what: str) -> None:
        if g.held_since is not None:
            return
        g.held_since = self.clock()
        self.count("gestures_held")
        log.info("edit %s: held until %s is there (at most %g s)", g.edit_id, what, self.config.hold_s)

    def current(self, edit_id: str) -> Gesture | None:
        """The open gesture if it is ``edit_id``'s."""
        g = self.gesture
        return g if g is not None and g.edit_id == edit_id else None

    def psi(self, edit_id: str, psi: np.ndarray) -> Gesture | None:
        """Ψ (n, 2, 2) for a gesture: compute its response columns (worker thread)
        once the equilibrium on its mesh is held; until then Ψ waits on the
        gesture (see :meth:`resume`). None when the gesture is no longer open;
        raises NoEquilibrium when Ψ does not fit the gesture's mesh."""
        g = self.current(edit_id)
        if g is None:
            return None
        with self._lock:
            model = self.model if self.mesh_generation == g.mesh_generation else None
        if model is not None and model.n != psi.shape[0]:
            raise NoEquilibrium(
                f"edit {edit_id}: Ψ has {psi.shape[0]} vertices, the mesh pressed on "
                f"(mesh generation {g.mesh_generation}) has {model.n}; no prediction"
            )
        g.psi = psi
        self._columns(g)
        return g

    def _columns(self, g: Gesture) -> bool:
        """Compute g's columns if its Ψ and the equilibrium on its mesh are here."""
        with self._predict_lock:
            if g.ready:
                return True
            if g.psi is None or self.eq_mesh_generation != g.mesh_generation or self.gesture is not g:
                return False
            p = self.predictor
            if p.model is None or p.model.n != g.psi.shape[0]:
                raise NoEquilibrium(f"edit {g.edit_id}: no equilibrium on this mesh yet; no prediction")
            t0 = time.perf_counter()
            S = p.press(g.psi)
            if g.press.picked_vertex >= 0:
                g.s_point = S[g.press.picked_vertex, :, 0]
            g.ready = True
        log.info(
            "press %s on %s: columns in %.0f ms%s",
            g.edit_id,
            g.press.element or g.press.param,
            1e3 * (time.perf_counter() - t0),
            "" if g.held_since is None else f" (held {self.clock() - g.held_since:.2f} s)",
        )
        return True

    def resume(self) -> PredictionOut | ReleaseOut | None:
        """Serve what waited on the open gesture (worker thread; call it after an
        equilibrium or Ψ arrived): its columns, then its release (a ReleaseOut)
        or else the prediction of its latest drag. None when nothing is due."""
        g = self.gesture
        if g is None or not self._columns(g):
            return None
        if g.pending_release is not None:
            return self.release(g.edit_id, g.pending_release)
        if g.pending_d is not None:
            d, g.pending_d = g.pending_d, None
            return self.drag(g.edit_id, d)
        return None

    def expire(self) -> Gesture | None:
        """The open gesture, closed, if it waited more than ``hold_s`` (logged,
        counted ``gestures_expired``); None otherwise. Cheap: it does not wait
        while columns are being computed."""
        g = self.gesture
        if g is None or g.ready or g.held_since is None or self.clock() - g.held_since <= self.config.hold_s:
            return None
        if not self._predict_lock.acquire(blocking=False):
            return None
        try:
            with self._lock:
                if self.gesture is not g or g.ready:
                    return None
                self.gesture = None
        finally:
            self._predict_lock.release()
        self.count("gestures_expired")
        log.warning(
            "edit %s: held %.1f s without %s; given up (no prediction%s)",
            g.edit_id,
            self.clock() - g.held_since,
            "Ψ" if self.eq_mesh_generation == g.mesh_generation else f"an equilibrium on mesh {g.mesh_generation}",
            ", its release is lost" if g.pending_release is not None else "",
        )
        return g

    def moved(self, edit_id: str) -> bool:
        """The pointer moved in gesture ``edit_id`` (call it when the drag arrives,
        before the prediction is queued): False if that gesture is not open."""
        g = self.current(edit_id)
        if g is None:
            return False
        g.last_motion = self.clock()
        return True

    def design_point(self, g: Gesture, d_raw: np.ndarray) -> np.ndarray | None:
        """The design point (2,) of a drag: the pointer motion itself for a 2D drag;
        for a 3D tug (d_raw in pixels) Δg by SC §4.1 in column 0 (0 where the
        picked point is insensitive). None before the tug's columns exist."""
        if g.press.picked_vertex < 0:
            return np.asarray(d_raw, dtype=np.float64).reshape(2)
        x_eq = self.predictor.x_eq
        if g.s_point is None or g.press.view_proj is None or x_eq is None:
            return None
        x_point = x_eq[g.press.picked_vertex]
        r = drag_to_param(g.s_point, g.press.view_proj, g.press.viewport, x_point, d_raw)
        if r.ignored:
            self.count("insensitive_drags")
        return np.array([float(r.dg[0]), 0.0])

    def drag(self, edit_id: str, d_raw: np.ndarray, *, release: bool = False) -> PredictionOut | None:
        """The prediction for a pointer motion d_raw (2,) since press [m, or px for
        a tug] (worker thread); None for another gesture, and before the
        columns exist (then the latest drag waits for :meth:`resume`)."""
        g = self.current(edit_id)
        if g is None:
            return None
        if not g.ready:
            g.pending_d = np.asarray(d_raw, dtype=np.float64).copy()
            return None
        d = self.design_point(g, d_raw)
        if d is None:
            return None
        g.d = d
        p = self.predictor.drag(d, error_estimate=False)
        return self._out(g, p, None, release)

    def estimate(self, out: PredictionOut) -> PredictionOut | None:
        """The same prediction with its error estimate (idle time); None when a
        newer prediction or gesture has superseded it."""
        g = self.current(out.edit_id)
        p = out.prediction
        if g is None or p is None or self.predictor.last is not p:
            return None
        err = self.predictor.error_of(p.x, p.d)
        err_m = self.predictor.distance_of(p.x, p.d)
        return self._out(g, p, err, False, err_m if np.isfinite(err_m) else None)

    def _out(
        self, g: Gesture, p: Prediction, err: float | None, release: bool, err_m: float | None = None
    ) -> PredictionOut:
        return PredictionOut(
            edit_id=g.edit_id,
            generation=g.generation,
            mesh_generation=g.mesh_generation,
            x=p.x,
            d=p.d,
            method=p.method,
            error_estimate=err,
            error_estimate_m=err_m,
            release=release,
            prediction=p,
        )

    def pause(self) -> Gesture | None:
        """The gesture to enrich now, if the pointer has rested ``pause_s`` at a
        design point not yet enriched (it is marked enriched: one solve per rest)."""
        g = self.gesture
        if (
            g is None
            or not g.ready
            or self.clock() - g.last_motion <= self.config.pause_s
            or (g.enriched_at is not None and np.array_equal(g.enriched_at, g.d))
        ):
            return None
        g.enriched_at = g.d.copy()
        return g

    def enrich(self, g: Gesture) -> PredictionOut | None:
        """A short solve at the gesture's design point from the latest prediction
        (idle time; it stops as soon as the pointer moves). A result better than
        that prediction's error estimate becomes a GMLS sample, and the
        prediction there is returned with the solve's residual as its estimate."""
        p = self.predictor
        if self.gesture is not g or p.last is None:
            return None
        d = g.d.copy()
        model_d = p.model_at(p.model, p.rest_at(d))
        cfg = self.config
        r = self.solver.solve(
            model_d,
            p.last.x,
            tol=cfg.enrich_tol,
            max_seconds=cfg.enrich_seconds,
            callback=lambda *_: self.gesture is not g or self.clock() - g.last_motion < cfg.pause_s,
        )
        if self.gesture is not g or not np.isfinite(r.residual):
            return None
        bar = p.last.error_estimate if np.isfinite(p.last.error_estimate) else np.inf
        if r.residual >= bar:
            return None
        p.add_sample(d, r.x)
        g.enriched_at = d
        log.info(
            "cache sample at d=%s (residual %.1e) -> %d samples",
            np.round(d, 4),
            r.residual,
            len(p.cache) if p.cache is not None else 0,
        )
        pred = p.drag(d, error_estimate=False)
        return self._out(g, pred, float(r.residual), False)

    def release(self, edit_id: str, d_raw: np.ndarray) -> ReleaseOut | None:
        """End gesture ``edit_id``: its final prediction and, for a 3D tug, the new
        design. Raises PatternError when the tug's design edit is invalid. Before
        the columns exist the release waits (None; :meth:`resume` ends the
        gesture, or :meth:`expire` after ``hold_s``)."""
        g = self.current(edit_id)
        if g is None:
            return None
        if not g.ready:
            g.pending_release = np.asarray(d_raw, dtype=np.float64).copy()
            self._hold(g, "its Ψ")
            if not self._columns(g):
                return None
        out = self.drag(edit_id, d_raw, release=True)
        with self._lock:
            self.gesture = None
            held = max(self.generation, self.matcher.newest)  # a mesh matched but not built yet counts
        if out is None or not g.press.is_tug or g.design is None:
            return ReleaseOut(out)
        if held != g.generation:
            self.count("stale_edits")
            log.warning(
                "3D tug %s edited generation %d, generation %d was meshed since: its design is not published",
                edit_id,
                g.generation,
                held,
            )
            return ReleaseOut(out)
        new = apply_edit(g.design, f"param:{g.press.param}", g.d)
        generation = g.generation + 1  # asked for; the remesher numbers the design
        log.info("3D tug: %s %+.4f (asks for generation %d)", g.press.param, float(g.d[0]), generation)
        return ReleaseOut(out, new, generation, uuid.uuid4().hex)


__all__ = [
    "Gesture",
    "NoEquilibrium",
    "PatternError",
    "Press",
    "PredictionOut",
    "Readiness",
    "ReleaseOut",
    "SensitivityConfig",
    "SensitivityService",
]

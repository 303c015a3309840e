"""The solver node's state machine, free of bus code (nodes/solver adapts it).

It pairs each incoming mesh with the design it was drafted from
(:class:`couture.designs.MeshMatcher`: a mesh that arrives before its pattern
waits for it, stale meshes are dropped), holds the design's fabric and scene, the meshes of each level and a cloth
model per level (rebuilt only when topology changes; a followed mesh only
resets rest positions), picks warm starts, and runs the cascadic
coarse -> fine refinement of SC §7.1 with progress and abort callbacks.

Warm start, in order of preference, for a level's new mesh:
1. the sensitivity prediction made for it (release of the last drag),
2. this solver's previous state on the same vertices (a mesh that followed
   a pattern edit keeps its vertices, SC §6),
3. for the fine level: the new coarse equilibrium prolongated (cascadic) and
   polished (``cascadic.polish_prolongated``: fine seams closed, contact depths),
4. the mesh's own x0 (initial placement, or state the remesher transferred).

A level that starts from its placement has friction from its first iteration
(``FRICTION_AT_ONCE``): frictionless settling lets a garment that only friction
holds up (trousers, a dress on the shoulders) slide and turn for as long as the
solve lasts, and the fine level then starts on a coarse drape that friction
never shaped. Anchors made at the placement are not a pin: each one slips as
soon as it holds more than mu_s f_n, with a kinetic friction that follows the
normal force.

A warm start on a model that carries its drape's anchors (a prediction or
the previous state after a pattern edit: same mesh, fabric, scene and body)
keeps them from the first iteration too (``carries_anchors``): the edited
cloth holds where friction holds it and slips only where an anchor is pulled
beyond mu_s f_n, so an edit of nothing moves nothing (it slid the default
skirt 14 mm when every anchor was let go). Every other start (a prolongated
coarse drape, a new body, another fabric) keeps the solvers' own schedule:
anchors act once the relative residual is below 1e-2, and before that the
cloth settles frictionless (a prolongated drape carries seam and contact
transients that anchors would pin; a drape inside a new body must come out).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from couture import bodies
from couture.cloth.material import FabricError, check_fabric, check_panel_names, reference_lame
from couture.cloth.model import CONTACT_STIFFNESS_PER_MU, SEAM_STIFFNESS_PER_MU, ClothModel, Scene
from couture.designs import Matched, MeshArrival, MeshMatcher, MeshOutcome, Verdict, judge
from couture.mesh import GarmentMesh
from couture.pattern.errors import PatternError
from couture.pattern.limits import check_simulation_values
from couture.solvers import get_solver
from couture.solvers.base import SolveResult
from couture.solvers.cascadic import carry_friction, polish_prolongated
from couture.tryon import TryOn
from schemas.design import Design

log = logging.getLogger(__name__)

TRYON_GUIDES = ("proxy", "body")
"""what a try-on drag slides along (SolveService.tryon_guide)"""


def _load_proxy(name: str):
    from couture.cloth.proxy import load_body_proxy

    return load_body_proxy(name, verbose=False)


FRICTION_AT_ONCE = ("placement",)
"""warm starts (``SolveService._warm``) from which friction acts at the first iteration (module docstring)"""


def carries_anchors(model) -> bool:
    """The model holds the friction anchors of the drape it last converged (same
    mesh, fabric, scene and body): a warm start on it keeps them from the first
    iteration, each slipping only beyond mu_s f_n. Its relative residual cannot
    decide that: anchors are stiff springs, so a start 15 nm from the drape
    (a prediction at zero drag) already reads 0.07, and releasing them let the
    default skirt slide 14 mm after an edit of nothing."""
    anchored = getattr(model, "anchored", None)
    return anchored is not None and bool(np.any(anchored))


def scene_from_design(design: Design) -> Scene:
    """The terms a design's scene needs (absent terms are never built), with
    each panel's own fabric (``Design.panel_fabrics``) and its seam and contact
    stiffnesses: the model's defaults (``*_PER_MU`` x the
    fabric's shear modulus mu) times the scene's factors. Raises ValueError
    for a factor that is not positive and finite (a decoded design cannot
    hold one: ``schemas.design.StiffnessScale``)."""
    flags = design.scene
    for name in ("seam_stiffness_scale", "contact_stiffness_scale"):
        v = getattr(flags, name)
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"scene.{name}: {v!r} is not a positive finite factor")
    # the default body keeps its old name; a graded body goes by its own (couture.bodies)
    body = ("mannequin" if design.body.name == "default" else bodies.use(design.body)) if flags.body else None
    mu, _ = reference_lame(design.fabric)  # the model's own mu (isotropic: the fabric's)
    # a factor of 1 leaves the model's own default in charge (None)
    seam = None if flags.seam_stiffness_scale == 1.0 else flags.seam_stiffness_scale * SEAM_STIFFNESS_PER_MU * mu
    contact = (
        None if flags.contact_stiffness_scale == 1.0 else flags.contact_stiffness_scale * CONTACT_STIFFNESS_PER_MU * mu
    )
    return Scene(
        body=body,
        gravity=flags.gravity,
        seams=flags.seams,
        friction=bool(flags.friction and flags.body),
        seam_stiffness=seam,
        contact_stiffness=contact,
        friction_model=flags.friction_model,
        panel_fabrics=dict(design.panel_fabrics),
    )


def check_materials(design: Design, mesh: GarmentMesh | None = None) -> None:
    """The cloth model can be built of the design's fabrics (positive definite
    membrane, positive bending hinges: ``couture.cloth.material.check_fabric``)
    and, given the mesh, every panel named in ``panel_fabrics`` is one of its
    panels; raises PatternError naming the field (``panel_fabrics.<panel>.<field>``)."""
    try:
        check_fabric(design.fabric)
        for name, fabric in design.panel_fabrics.items():
            check_fabric(fabric, f"panel_fabrics.{name}")
        if mesh is not None:
            check_panel_names(design.panel_fabrics, list(mesh.panel_names))
    except FabricError as e:
        raise PatternError(e.field, e.message) from None


def same_vertices(a: GarmentMesh, b: GarmentMesh) -> bool:
    """Whether b is a followed/flipped version of a (vertex identity kept)."""
    return (
        a.n_vertices == b.n_vertices
        and a.panel_names == b.panel_names
        and np.array_equal(a.seam_emitters, b.seam_emitters)
        and np.array_equal(a.seam_edges, b.seam_edges)
    )


@dataclass
class LevelModel:
    mesh: GarmentMesh
    mesh_generation: int
    model: ClothModel
    x: np.ndarray | None = None
    """latest state on this mesh [m], (n, 3)"""
    converged: bool = False


@dataclass
class LevelRun:
    level: str
    mesh_generation: int
    result: SolveResult
    warm_start: str


@dataclass
class IncomingMesh:
    """What the solver keeps of a ``mesh/<level>`` message."""

    mesh: GarmentMesh
    prolongation: tuple[np.ndarray, np.ndarray] | None = None
    """fine level: (coarse parent triangle (n,) int32, barycentric coordinates (n, 3))"""


DEFAULT_TOL: dict[str, float] = {"coarse": 1e-3, "fine": 1e-4}
"""level -> residual tolerance a solver node stops at unless told otherwise"""


@dataclass
class SolveService:
    method: str = "kinetic"
    tol: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_TOL))
    max_seconds: dict[str, float] = field(default_factory=lambda: {"coarse": 30.0, "fine": 120.0})
    design: Design | None = None
    levels: dict[str, LevelModel] = field(default_factory=dict)
    predictions: dict[str, tuple[int, np.ndarray]] = field(default_factory=dict)
    """level -> (mesh_generation the prediction was made on, x)"""
    prolongation: tuple[np.ndarray, np.ndarray] | None = None
    matcher: MeshMatcher[IncomingMesh] = field(default_factory=MeshMatcher)
    friction_at_once: tuple[str, ...] = FRICTION_AT_ONCE
    """warm starts from which friction acts at once"""
    tryon: dict[str, TryOn] | None = None
    """level -> the try-on in progress (couture.tryon), None when there is none"""
    tryon_op_id: str = ""
    """op_id of the last try-on op applied ('' outside a try-on): the drapes
    solved after it carry it as their edit_id, so a recording matches them per op"""
    tryon_guide: str = "proxy"
    """what a try-on drag slides along: 'proxy', the design's body's ellipsoid
    proxy (couture.cloth.proxy, Meng §4: a bound of the body, 3.5x faster to
    query than the exact mesh; the end of the drag is pushed out of the
    model's body once more), or 'body', the model's body itself"""
    proxy_loader: Callable[[str], object] = _load_proxy
    """body name -> its proxy (default couture.cloth.proxy.load_body_proxy,
    cached on disk per body mesh)"""
    extend_by: float = 1.0
    """a level below the last that ends unconverged at its cap (``max_seconds``)
    goes on for this many caps more, from where it stopped, before the next level
    starts from it (0: never)"""
    _proxy: tuple[str, object] | None = field(default=None, repr=False)
    """(body name, proxy) of the last drag: another body gets its own"""

    def __post_init__(self) -> None:
        if self.tryon_guide not in TRYON_GUIDES:
            raise ValueError(f"tryon_guide {self.tryon_guide!r}; use one of {TRYON_GUIDES}")
        self.solver = get_solver(self.method)

    # -- inputs from the bus: designs and meshes are matched before they are taken
    def offer_design(self, generation: int, design: Design, design_id: str = "") -> list[Matched[IncomingMesh]]:
        """A ``pattern``: only remembered (a pattern the remesher rejects must
        not disturb the current solve; valid ones come back as meshes).
        Returns the meshes that waited for it, to :meth:`take`."""
        return self.matcher.add_design(generation, design, design_id)

    def offer_mesh(
        self, level: str, generation: int, mesh_generation: int, incoming: IncomingMesh, design_id: str = ""
    ) -> MeshOutcome[IncomingMesh]:
        """A ``mesh/<level>``: matched with its design (then :meth:`take` it),
        parked until its pattern arrives, or dropped as stale or a repeat."""
        return self.matcher.add_mesh(MeshArrival(level, generation, mesh_generation, incoming, design_id))

    @property
    def generation(self) -> int:
        """The remesher's number for the newest design whose mesh this solver
        matched (it solves that one next), -1 before any."""
        return self.matcher.newest

    def judge_edit(self, generation: int) -> Verdict:
        """Whether an edit (or a prediction) made on the design of ``generation``
        is on this solver's newest design."""
        return judge(generation, self.matcher.newest)

    def take(self, matched: Matched[IncomingMesh]) -> bool:
        """Adopt a matched mesh and its design; True when both levels of one
        generation are held (a solve can run). Raises PatternError (nothing
        adopted; the matcher does not count the mesh as taken) for a design
        this solver cannot simulate."""
        m = matched.mesh
        try:
            check_simulation_values(matched.design)  # ranges first: they name the field the designer set
            check_materials(matched.design, m.payload.mesh)
            self.set_design(matched.design)
        except PatternError:
            self.matcher.refuse(m)
            raise
        self.set_mesh(m.level, m.payload.mesh, m.mesh_generation, m.payload.prolongation)
        return self.ready()

    # -- state
    def set_design(self, design: Design) -> bool:
        """Returns True when fabric, scene or body changed (models must be rebuilt;
        each level keeps its state, so a new body re-drapes from the current drape).
        Raises PatternError naming the field (``fabric.area_density``, ...)
        for a fabric outside its physical range, keeping the current design."""
        check_simulation_values(design)
        check_materials(design)
        changed = (
            self.design is None
            or design.fabric != self.design.fabric
            or design.panel_fabrics != self.design.panel_fabrics
            or design.scene != self.design.scene
            or design.body != self.design.body
        )
        self.design = design
        if changed:
            for level, lm in self.levels.items():
                lm.model = ClothModel(self._model_mesh(level), design.fabric, scene_from_design(design))
                lm.converged = False
        return changed

    def set_mesh(
        self,
        level: str,
        mesh: GarmentMesh,
        mesh_generation: int,
        prolongation: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        if self.design is None:
            raise RuntimeError("no design yet (pattern message) to take fabric and scene from")
        old = self.levels.get(level)
        if old is not None and old.mesh_generation == mesh_generation:
            return
        if self.tryon is not None:
            self.end_tryon()
        x_prev = None
        if old is not None and same_vertices(old.mesh, mesh):
            x_prev = old.x
            # a turned grain changes the material: a new model
            if np.array_equal(old.mesh.tris, mesh.tris) and np.array_equal(old.mesh.panel_grain, mesh.panel_grain):
                old.model.set_rest_positions(mesh.X)
                model = old.model
            else:
                model = ClothModel(mesh, self.design.fabric, scene_from_design(self.design))
        else:
            model = ClothModel(mesh, self.design.fabric, scene_from_design(self.design))
        self.levels[level] = LevelModel(mesh=mesh, mesh_generation=mesh_generation, model=model, x=x_prev)
        if level == "fine" and prolongation is not None:
            self.prolongation = prolongation

    def set_prediction(self, level: str, mesh_generation: int, x: np.ndarray) -> None:
        self.predictions[level] = (mesh_generation, np.asarray(x, dtype=np.float64))

    def ready(self) -> bool:
        return (
            self.design is not None
            and "coarse" in self.levels
            and "fine" in self.levels
            and (self.levels["coarse"].mesh.generation == self.levels["fine"].mesh.generation)
        )

    # -- work
    def _warm(self, level: str, coarse_x: np.ndarray | None) -> tuple[np.ndarray, str]:
        lm = self.levels[level]
        pred = self.predictions.get(level)
        if pred is not None and pred[1].shape == lm.mesh.x0.shape and lm.x is not None:
            return pred[1], "prediction"
        if lm.x is not None:
            return lm.x, "previous"
        if level == "fine" and coarse_x is not None and self.prolongation is not None:
            parent, bary = self.prolongation
            coarse = self.levels["coarse"]
            x = np.einsum("nk,nkd->nd", bary, coarse_x[coarse.mesh.tris[parent]])
            x = polish_prolongated(lm.model, x, coarse.model, coarse_x, parent, bary)
            carry_friction(lm.model, coarse.model, parent, bary, x)
            return x, "prolongated"
        return lm.mesh.x0, "placement"

    def run(
        self,
        *,
        levels: tuple[str, ...] = ("coarse", "fine"),
        should_abort: Callable[[], bool] = lambda: False,
        on_progress: Callable[[str, int, np.ndarray, float], None] | None = None,
        on_level: Callable[[LevelRun], None] | None = None,
        progress_period_s: float = 0.5,
    ) -> list[LevelRun]:
        """Cascadic refinement: each level from its warm start to its tolerance."""
        runs: list[LevelRun] = []
        coarse_x = None
        for level in levels:
            lm = self.levels[level]
            x0, how = self._warm(level, coarse_x)
            last = [time.monotonic()]

            def cb(it: int, x: np.ndarray, res: float, level: str = level, last: list[float] = last) -> bool:
                if should_abort():
                    return True
                now = time.monotonic()
                if on_progress is not None and now - last[0] >= progress_period_s:
                    last[0] = now
                    on_progress(level, it, x, res)
                return False

            at_once = how in self.friction_at_once or (
                how in ("prediction", "previous", "prolongated") and carries_anchors(lm.model)
            )
            result = self.solver.solve(
                lm.model,
                x0,
                tol=self.tol[level],
                max_seconds=self.max_seconds[level],
                callback=cb,
                friction_after=math.inf if at_once else None,
                from_placement=how == "placement",
            )
            last_level = level == levels[-1]
            if not (result.converged or last_level or should_abort() or stopped(result)) and self.extend_by > 0:
                # a level below the last one that did not converge in its cap gets more
                # time, said in its diagnosis: the next level must not start silently
                # from an unconverged drape (a busy machine stopped the demo's first
                # coarse skirt at residual 1.24 and the fine level took it)
                more = self.solver.solve(
                    lm.model,
                    result.x,
                    tol=self.tol[level],
                    max_seconds=self.extend_by * self.max_seconds[level],
                    callback=cb,
                    friction_after=math.inf,
                )
                result = extended(result, more, self.max_seconds[level])
            if how == "prolongated" and runs and not runs[-1].result.converged:
                how = f"prolongated from an unconverged coarse drape (residual {runs[-1].result.residual:.3g})"
                if not result.converged:
                    result.diagnosis = f"{result.diagnosis}; started {how}"
            lm.x = result.x
            lm.converged = result.converged
            if self.tryon is not None and level in self.tryon:
                self.tryon[level].x = np.array(result.x, dtype=np.float64)
            self.predictions.pop(level, None)
            run = LevelRun(level, lm.mesh_generation, result, how)
            runs.append(run)
            if on_level is not None:
                on_level(run)
            if should_abort():
                break
            coarse_x = result.x if level == "coarse" else coarse_x
        return runs

    # -- try-on (couture.tryon, Meng 2010 §6): operations on the held state
    def _model_mesh(self, level: str) -> GarmentMesh:
        """The mesh a level's model is built on: the try-on's (sewn seams,
        fixed panels pinned at the current positions) during one."""
        if self.tryon is not None and level in self.tryon:
            return self.tryon[level].model_mesh()
        return self.levels[level].mesh

    def end_tryon(self) -> None:
        """Back to the plain drape of the held meshes (models with every seam)."""
        self.tryon = None
        self.tryon_op_id = ""
        if self.design is None:
            return
        for lm in self.levels.values():
            lm.model = ClothModel(lm.mesh, self.design.fabric, scene_from_design(self.design))
            lm.converged = False

    def apply_tryon(
        self,
        op: str,
        *,
        panel: str = "",
        vector=None,
        angle: float = 0.0,
        seam: int = -1,
        sewn: bool = True,
        op_id: str = "",
    ) -> None:
        """Apply a try-on op to every held level (each from its latest state,
        or its warm start before any solve) and rebuild their models; the next
        :meth:`run` solves from there. ``start`` (re)begins a try-on with
        every seam sewn or none; another op starts one with every seam sewn
        when none runs. Raises couture.tryon.TryOnError (state unchanged)
        for an op that cannot apply."""
        from couture.tryon import TryOnError

        if self.design is None or not self.ready():
            raise TryOnError("no garment held yet (pattern and meshes) to try on")
        current = self.tryon
        if op == "start" or current is None:
            current = {}
            for level, lm in self.levels.items():
                x = lm.x if lm.x is not None else lm.mesh.x0
                current[level] = TryOn.start(lm.mesh, x, sewn=sewn if op == "start" else True)
        if op != "start":
            trial = {level: _copy_tryon(t) for level, t in current.items()}
            guide = self.drag_guide() if op == "drag" else None
            for level, t in trial.items():
                model = self.levels[level].model
                t.apply(
                    op,
                    panel=panel,
                    vector=vector,
                    angle=angle,
                    seam=None if seam < 0 else seam,
                    body=model.body,
                    offset=model.contact_offset,
                    guide=guide if model.body is not None else None,
                )
            current = trial
        self.tryon = current
        self.tryon_op_id = op_id
        for level, lm in self.levels.items():
            lm.model = ClothModel(current[level].model_mesh(), self.design.fabric, scene_from_design(self.design))
            lm.x = current[level].x.copy()
            lm.converged = False
        self.predictions.clear()

    def drag_guide(self):
        """What a try-on drag slides along: the held design's body's proxy
        (loaded once per body: a design on another body loads that body's),
        or None (slide along the model's body: ``tryon_guide='body'``, or
        a scene without a body)."""
        if self.tryon_guide != "proxy" or self.design is None or not self.design.scene.body:
            return None
        name = self.design.body.name
        if self._proxy is None or self._proxy[0] != name:
            self._proxy = (name, self.proxy_loader(name))
        return self._proxy[1]


def stopped(result: SolveResult) -> bool:
    """The solve was stopped from outside (a newer edit, the node closing)."""
    return "stopped by callback" in result.diagnosis or "abort" in result.diagnosis.lower()


def extended(first: SolveResult, more: SolveResult, cap: float) -> SolveResult:
    """One result for a level solved in two goes: its cap, then an extension."""
    said = f"needed more than its {cap:g} s cap (residual {first.residual:.3g} then)"
    stats = dict(more.stats)
    for k, v in first.stats.items():
        if isinstance(v, (int, float)) and not isinstance(v, bool) and isinstance(stats.get(k), (int, float)):
            stats[k] = stats[k] + v
    stats["extended"] = True
    t0 = first.wall_time
    return SolveResult(
        x=more.x,
        residual=more.residual,
        iterations=first.iterations + more.iterations,
        wall_time=first.wall_time + more.wall_time,
        converged=more.converged,
        method=more.method,
        diagnosis=f"{said}; converged in the extension" if more.converged else f"{said}; {more.diagnosis}",
        history=list(first.history) + [(t0 + t, r) for t, r in more.history],
        stats=stats,
    )


def solve_tryon(state: TryOn, fabric, scene, solver="newton", **opts) -> SolveResult:
    """Solve the try-on ``state`` (couture.tryon: sewn seams only, fixed panels
    pinned) to equilibrium from its positions with a solver of couture.solvers
    (a registry name or an instance; ``opts`` go to its ``solve``); the state
    takes the result's x. Returns the SolveResult."""
    s = get_solver(solver) if isinstance(solver, str) else solver
    model = ClothModel(state.model_mesh(), fabric, scene)
    r = s.solve(model, state.x.copy(), **opts)
    state.x = np.array(r.x, dtype=np.float64)
    return r


def _copy_tryon(t: TryOn) -> TryOn:
    return TryOn(mesh=t.mesh, x=t.x.copy(), groups=t.groups, sewn=t.sewn.copy(), fixed=set(t.fixed))


def solve_once(solver, model, x_warm: np.ndarray | None = None, **opts) -> SolveResult:
    """One solve of ``model`` outside the levels (a solve request, an adjustment's
    re-simulation) from ``x_warm``, or from the placement when it is None. A warm
    start equal to the mesh's placement is a solve from the placement
    (``from_placement``: the Newton solver's surface guard and its check for the
    body between vertices, as the levels have): pattern adjustment sends its
    source drape's placement as the warm start, and without the guard Newton's
    shirt at 1600 vertices balanced with a vertex 2.05 mm inside the arm (refused,
    so every adjustment of it edited an unsettled drape); with it, 124
    iterations, none inside. (Its re-simulations send each mesh with the warm
    start as its placement, ``couture.adjust.fixed_point.with_rest``, so they
    are solved from the placement too.) Friction follows the request as before:
    from the first iteration only when no warm start was sent."""
    x0 = model.mesh.x0 if x_warm is None else np.asarray(x_warm, dtype=np.float64)
    placement = x_warm is None or (x0.shape == model.mesh.x0.shape and np.array_equal(x0, model.mesh.x0))
    opts.setdefault("friction_after", math.inf if x_warm is None else None)
    return solver.solve(model, np.array(x0, dtype=np.float64), from_placement=placement, **opts)

"""A solver node: mesh/* -> drape/coarse, drape/fine; answers solve queries.

A thin adapter over :class:`couture.solvers.service.SolveService`. Any of the
methods (kinetic, newton, verlet; style3d, the peer, with couture[peer]) runs behind the same topics, with its
own node name on every drape, so two can run at once for comparison.

Behaviour (DESIGN §2): a new pattern generation aborts the running solve; a
press aborts it too and no solve runs while a drag is in progress (the
sensitivity node previews); after release the next meshes warm-start from
the last prediction, and a solve the press cut off (or a mesh that arrived
mid-drag) is resumed even when no newer design follows (counted
``resumed_solves``). Progress drapes go out every ``progress_period_s``.
A mesh whose design has a fabric outside its physical range (the remesher
rejects those first) is rejected on ``rejected`` (with the design's identity
and the generation the remesher gave it) and the solver keeps its state; a
solve request with one is answered with the error.
A press made on another design than the newest this solver holds, and a
prediction numbered above it, are ignored with a log line naming both
generations and counted (``stale_edits``, ``foreign_edits``,
``foreign_predictions``).

A try-on op (``tryon``, couture.tryon) is queued and applied by the worker
between solves (it aborts the running one), to the state each level holds,
then both levels re-solve from there; their drapes carry the op's ``op_id``
as ``edit_id``. A new pattern generation ends the try-on.

A solver pool (``--serve-session S``, repeatable): the node serves those
design sessions, each with its own service, drape publishers and solve
queryable, through one worker thread (one solve at a time); the members of
the pool see each other in the node's own session and share the sessions out
(:class:`PoolShare`). Without it the node serves its own session, as before.
"""

from __future__ import annotations

import inspect
import logging
import os
import threading
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Callable

import numpy as np

from couture.bus import Bus, BusConfig, Node, open_session
from couture.bus.worker import LatestWorker
from couture.cloth.model import ClothModel
from couture.designs import Matched
from couture.pattern.errors import PatternError
from couture.pattern.limits import check_simulation_values
from couture.solvers import SOLVERS, get_solver, solver_class
from couture.solvers.service import IncomingMesh, LevelRun, SolveService, scene_from_design, solve_once
from couture.tryon import TryOnError
from schemas import (
    Array,
    DrapeMsg,
    EditMsg,
    MeshMsg,
    PatternMsg,
    RejectedMsg,
    SolveRequestMsg,
    SolveResultMsg,
    TryOnMsg,
)
from schemas.arrays import as_array
from schemas.convert import msg_to_mesh

log = logging.getLogger("solver")

BACKEND_ENV = "COUTURE_SOLVER_BACKEND"


@dataclass
class Config:
    bus: BusConfig = field(default_factory=BusConfig)
    name: str = "solver-newton"
    """node name, unique in the session (liveliness key status/<name>)"""
    solver: str = field(default="newton", metadata={"choices": lambda: sorted(SOLVERS)})
    """the solver (couture.solvers.SOLVERS: 'kinetic', 'newton', 'verlet', 'style3d', the peer, couture[peer])"""
    progress_period_s: float = 0.5
    """[s] between progress drapes during a solve"""
    max_seconds: float | None = None
    """[s] cap on each level's solve (coarse and fine alike); None: the
    service's defaults. A capped level is published unconverged, with its
    diagnosis, like any other stopped solve."""
    backend: str = field(
        default_factory=lambda: os.environ.get(BACKEND_ENV, ""),
        metadata={"choices": ("", "auto", "pardiso", "pardiso32", "cholmod", "splu")},
    )
    """direct linear-solver backend of the kinetic and Newton solvers ('pardiso',
    'pardiso32', 'cholmod', 'splu'); '' keeps the solver's own choice ('auto').
    Defaults to $COUTURE_SOLVER_BACKEND, so a test can run every solver node of a
    session on SuperLU without a flag per node."""
    sessions: list[str] = field(default_factory=list, metadata={"flag": "--serve-session"})
    """design sessions this node serves as a member of a solver pool ([]: its
    own session alone). With sessions, the node's own session is the pool's:
    its members see each other there (liveliness) and share the sessions out
    (:class:`PoolShare`); each session sees the member's drapes under its name."""


def solver_options(config: Config) -> dict:
    """Constructor options for ``get_solver(config.solver, ...)``: the backend,
    for a solver whose constructor takes one (no list of names here: the
    registry's classes say it)."""
    if config.backend and "backend" in inspect.signature(solver_class(config.solver)).parameters:
        return {"backend": config.backend}
    return {}


def make_service(config: Config) -> SolveService:
    service = SolveService(method=config.solver)
    if solver_options(config):
        # SolveService builds its solver with defaults; a backend chosen for this
        # node replaces it before any solve (no service option exists for it)
        service.solver = get_solver(config.solver, **solver_options(config))
        log.info("%s solver on the %r backend", config.solver, config.backend)
    if config.max_seconds is not None:
        service.max_seconds = {level: float(config.max_seconds) for level in service.max_seconds}
    return service


class PoolShare:
    """Which of the served sessions a pool member solves: the i-th session (in
    the order every member is given) goes to the (i mod k)-th of the k live
    members, by name. Members are the live ``solver*`` nodes of the pool's
    own session; when one dies its sessions pass to the others."""

    def __init__(self, me: str, sessions: list[str]) -> None:
        self.me, self.sessions = me, list(sessions)
        self.members = {me}
        self._lock = threading.Lock()

    def owns(self, session: str) -> bool:
        with self._lock:
            members = sorted(self.members)
        return members[self.sessions.index(session) % len(members)] == self.me

    def update(self, node: str, alive: bool) -> list[str]:
        """A member came or went: the sessions this member owns now and did not before."""
        if not node.startswith("solver") or node == self.me:
            return []
        before = {s for s in self.sessions if self.owns(s)}
        with self._lock:
            if alive:
                self.members.add(node)
            else:
                self.members.discard(node)
        return [s for s in self.sessions if self.owns(s) and s not in before]


def main(config: Config) -> None:
    with Node(config.name, config.bus, kind="solver") as node:
        worker = LatestWorker("solve", on_error=node.error)
        extra: list[Bus] = []
        served: list[SolverAdapter] = []
        try:
            if not config.sessions:
                served.append(SolverAdapter(node.bus, node, config, worker))
            else:
                share = PoolShare(config.name, config.sessions)
                by_session: dict[str, SolverAdapter] = {}
                for s in config.sessions:
                    b = open_session(replace(config.bus, session=s), name=config.name)
                    extra.append(b)
                    b.stats = node.bus.stats  # one status counts for every session served
                    b.declare_token(config.name)
                    by_session[s] = SolverAdapter(b, node, config, worker, slot=f"{s}:", owns=partial(share.owns, s))
                served = list(by_session.values())
                PoolAdapter(node.bus, share, by_session)
                log.info("solver pool member %s serving sessions %s", config.name, ", ".join(config.sessions))
            node.run()
        finally:
            for sv in served:
                sv.abort()
            worker.close()
            for b in extra:
                b.close()


class PoolAdapter:
    """A solver pool member's watch on the other members (liveliness in the
    pool's own session): when one comes or goes, the sessions this member now
    owns are solved here."""

    def __init__(self, bus: Bus, share: PoolShare, by_session: dict[str, SolverAdapter]) -> None:
        self.share, self.by_session = share, by_session
        bus.watch_nodes(self.on_member)

    def on_member(self, name: str, alive: bool) -> None:
        for s in self.share.update(name, alive):
            log.info("pool member %s %s: this member now solves session %s", name, "up" if alive else "gone", s)
            self.by_session[s].resubmit()


def _always() -> bool:
    return True


class SolverAdapter:
    """Solves one session's designs on ``bus``: a handler per input (pattern,
    mesh/*, edit, drape/predicted, tryon, the solve queryable), drapes and
    rejections out. ``slot`` prefixes this session's jobs on the node's shared
    worker; ``owns()`` says whether this node solves the session now (a pool
    shares sessions out)."""

    def __init__(
        self,
        bus: Bus,
        node: Node,
        config: Config,
        worker: LatestWorker,
        *,
        slot: str = "",
        owns: Callable[[], bool] = _always,
    ) -> None:
        self.node, self.config, self.worker, self.slot, self.owns = node, config, worker, slot, owns
        self.service = make_service(config)
        self.pubs = {lv: bus.publisher(f"drape/{lv}", DrapeMsg) for lv in ("coarse", "fine")}
        self.rejected_pub = bus.publisher("rejected", RejectedMsg)
        self._lock = threading.Lock()
        self.gesture = ""
        """edit_id of the gesture pressed last"""
        self.dragging = False
        """a gesture is between its press and its release: no solve runs"""
        self.aborting = False
        """the running solve must stop (a press, a new mesh, a try-on op, shutdown)"""
        self.unfinished = False
        """the last solve was cut off (a press, a new mesh, a try-on op); a
        release that brings no new design resumes it"""
        self.tryon_ops: list[TryOnMsg] = []
        """try-on ops received, applied in order by the worker before its next solve"""
        bus.subscribe("pattern", self.on_pattern)
        bus.subscribe("mesh/coarse", self.on_mesh)
        bus.subscribe("mesh/fine", self.on_mesh)
        bus.subscribe("edit", self.on_edit)
        bus.subscribe("drape/predicted", self.on_prediction)
        bus.subscribe("tryon", self.on_tryon)
        bus.serve_solve(config.name, self.handle_solve)

    def resubmit(self) -> None:
        """Queue a solve of the session's current design (a pool member that took the session over)."""
        self.worker.submit(f"{self.slot}solve", self.solve_job)

    def abort(self) -> None:
        self.aborting = True

    # -- out
    def drape_msg(
        self,
        level: str,
        x: np.ndarray,
        res: float,
        it: int,
        wall: float,
        converged: bool = False,
        diagnosis: str = "",
        final: bool = True,
    ) -> DrapeMsg:
        lm = self.service.levels[level]
        return DrapeMsg(
            level="fine" if level == "fine" else "coarse",
            x=Array.from_numpy(x, "float32"),
            residual=float(res),
            iterations=int(it),
            solver=self.config.name,
            method=self.config.solver,
            wall_time_s=float(wall),
            converged=converged,
            diagnosis=diagnosis,
            generation=lm.mesh.generation,
            mesh_generation=lm.mesh_generation,
            final=final,
            edit_id=self.service.tryon_op_id,
            terms=list(getattr(lm.model, "terms", ())),
        )

    def should_abort(self) -> bool:
        return self.aborting or self.node.stopping

    def on_progress(self, level: str, it: int, x: np.ndarray, res: float) -> None:
        self.pubs[level].put(self.drape_msg(level, x, res, it, 0.0, final=False))

    def on_level(self, run: LevelRun) -> None:
        r = run.result
        self.pubs[run.level].put(
            self.drape_msg(run.level, r.x, r.residual, r.iterations, r.wall_time, r.converged, r.diagnosis)
        )
        self.node.count(f"solves/{run.level}")
        log.info(
            "gen %d %s: residual %.2e after %d its in %.2f s (%s, from %s)%s",
            self.service.levels[run.level].mesh.generation,
            run.level,
            r.residual,
            r.iterations,
            r.wall_time,
            self.config.solver,
            run.warm_start,
            f" [{r.diagnosis}]" if r.diagnosis else "",
        )
        if r.diagnosis and not r.converged and "abort" not in r.diagnosis.lower():
            self.node.error(f"{run.level}: {r.diagnosis}")

    # -- work (the worker thread)
    def solve_job(self) -> None:
        if not self.owns():
            return  # another member of the pool solves this session
        service = self.service
        with self._lock:
            if self.dragging or not service.ready():
                # a mesh that arrives mid-drag waits for the release
                self.unfinished = self.unfinished or (self.dragging and service.ready())
                return
            self.aborting = False
            ops = list(self.tryon_ops)
            self.tryon_ops.clear()
        for op in ops:
            self.apply_tryon(op)
        self.unfinished = True
        service.run(
            should_abort=self.should_abort,
            on_progress=self.on_progress,
            on_level=self.on_level,
            progress_period_s=self.config.progress_period_s,
        )
        self.unfinished = self.aborting

    def take(self, matched: Matched[IncomingMesh]) -> None:
        try:
            ready = self.service.take(matched)
        except PatternError as e:
            m = matched.mesh
            self.node.count("bad_designs")
            self.node.error(f"mesh/{m.level} of generation {m.generation} (design {m.design_id or '?'}) rejected: {e}")
            self.rejected_pub.put(
                RejectedMsg(
                    node=self.config.name,
                    generation=m.generation,
                    design_id=m.design_id,
                    element=e.element,
                    reason=str(e),
                )
            )
            return
        self.node.count("meshes_taken")
        if ready:
            self.worker.submit(f"{self.slot}solve", self.solve_job)

    def apply_tryon(self, msg: TryOnMsg) -> None:
        service = self.service
        if service.judge_edit(msg.generation) != "current":
            self.node.count("stale_tryon")
            log.warning(
                "try-on %s %s on generation %d ignored: this solver's design is %d",
                msg.op,
                msg.op_id,
                msg.generation,
                service.generation,
            )
            return
        try:
            service.apply_tryon(
                msg.op,
                panel=msg.panel,
                vector=msg.vector.numpy(),
                angle=msg.angle,
                seam=msg.seam,
                sewn=msg.sewn,
                op_id=msg.op_id,
            )
        except TryOnError as e:
            self.node.count("bad_tryon")
            self.node.error(f"try-on {msg.op} {msg.op_id}: {e}")
            # the sender waits for a drape answering the op: tell it there will be none
            self.rejected_pub.put(
                RejectedMsg(
                    node=self.config.name,
                    generation=msg.generation,
                    element=f"tryon.{msg.op}",
                    reason=f"try-on {msg.op} refused: {e}",
                    op_id=msg.op_id,
                    source="tryon",
                )
            )
            return
        self.node.count("tryon")
        log.info("try-on %s %s applied (panel %r, seam %d)", msg.op, msg.op_id, msg.panel, msg.seam)

    # -- in (Zenoh threads: judge and queue)
    def on_pattern(self, msg: PatternMsg) -> None:
        for m in self.service.offer_design(msg.generation, msg.design, msg.identity()):
            self.worker.submit(f"{self.slot}mesh/{m.mesh.level}", partial(self.take, m))

    def on_mesh(self, msg: MeshMsg) -> None:
        prolong = None
        if msg.fine_parent_tri is not None and msg.fine_bary is not None:
            prolong = (msg.fine_parent_tri.numpy().copy(), msg.fine_bary.numpy().copy())
        out = self.service.offer_mesh(
            msg.level, msg.generation, msg.mesh_generation, IncomingMesh(msg_to_mesh(msg), prolong), msg.design_id
        )
        if out.status == "stale":
            self.node.count("stale_meshes")
        matched = out.matched
        if matched is None:
            return
        self.aborting = True  # a new mesh supersedes the running solve
        self.worker.submit(f"{self.slot}mesh/{msg.level}", partial(self.take, matched))

    def on_edit(self, msg: EditMsg) -> None:
        if msg.phase == "press":
            verdict = self.service.judge_edit(msg.generation)
            if verdict != "current":
                self.node.count(f"{verdict}_edits")
                log.warning(
                    "edit %s: press on generation %d, this solver's design is %d (%s): ignored",
                    msg.edit_id,
                    msg.generation,
                    self.service.generation,
                    verdict,
                )
                return
            self.gesture = msg.edit_id
            self.dragging = True
            self.aborting = True
            self.node.count("presses")
        elif msg.phase == "release" and msg.edit_id == self.gesture:
            self.dragging = False
            if self.unfinished:
                # the press cut a solve off; a gesture that ends where it began (or a
                # design the remesher refuses) brings no new mesh to restart it
                self.node.count("resumed_solves")
                self.worker.submit(f"{self.slot}solve", self.solve_job)

    def on_prediction(self, msg: DrapeMsg) -> None:
        # a prediction lives on a mesh this solver matched (the release's is
        # the warm start of the next design's mesh, numbered later)
        if self.service.judge_edit(msg.generation) == "foreign":
            self.node.count("foreign_predictions")
            log.warning(
                "prediction for edit %s of generation %d ignored: this solver's newest design is %d",
                msg.edit_id,
                msg.generation,
                self.service.generation,
            )
            return
        self.service.set_prediction(msg.mesh_level, msg.mesh_generation, msg.x.numpy())

    def on_tryon(self, msg: TryOnMsg) -> None:
        # applied by the worker thread, between solves (the models change)
        with self._lock:
            self.tryon_ops.append(msg)
        self.aborting = True
        self.worker.submit(f"{self.slot}solve", self.solve_job)

    def handle_solve(self, req: SolveRequestMsg) -> SolveResultMsg:
        config = self.config
        design = req.design or self.service.design
        if design is None:
            raise RuntimeError("request has no design and this solver has seen no pattern")
        check_simulation_values(design)  # PatternError naming the field: the result's error
        if req.mesh is not None:
            mesh = msg_to_mesh(req.mesh)
        else:
            lm = self.service.levels.get(req.level)
            if lm is None or lm.mesh_generation != req.mesh_generation:
                raise RuntimeError(f"no {req.level} mesh of mesh_generation {req.mesh_generation} here")
            mesh = lm.mesh
        model = ClothModel(mesh, design.fabric, scene_from_design(design))
        # friction from the first iteration from a placement, the solver's own schedule from a warm start,
        # as this node solves its levels (couture.solvers.service.FRICTION_AT_ONCE); a warm start equal
        # to the placement is solved from the placement (solve_once)
        r = solve_once(
            get_solver(config.solver, **solver_options(config)),
            model,
            req.x_warm.numpy() if req.x_warm is not None else None,
            tol=req.tol,
            max_iters=req.max_iters,
            max_seconds=req.max_seconds,
        )
        return SolveResultMsg(
            method=config.solver,
            level=req.level,
            mesh_generation=req.mesh_generation,
            x=as_array(r.x),
            residual=r.residual,
            iterations=r.iterations,
            wall_time_s=r.wall_time,
            converged=r.converged,
            diagnosis=r.diagnosis,
        )

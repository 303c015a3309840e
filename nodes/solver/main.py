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

import logging
import math
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
from couture.solvers import get_solver
from couture.solvers.service import IncomingMesh, LevelRun, SolveService, scene_from_design
from couture.tryon import TryOnError
from schemas import DrapeMsg, EditMsg, MeshMsg, PatternMsg, RejectedMsg, SolveRequestMsg, SolveResultMsg, TryOnMsg
from schemas.convert import msg_to_mesh

log = logging.getLogger("solver")

BACKEND_ENV = "COUTURE_SOLVER_BACKEND"


@dataclass
class Config:
    bus: BusConfig = field(default_factory=BusConfig)
    name: str = "solver-newton"
    """node name, unique in the session (liveliness key status/<name>)"""
    solver: str = "newton"
    """'kinetic', 'newton', 'verlet' or 'style3d' (the peer, couture[peer])"""
    progress_period_s: float = 0.5
    """[s] between progress drapes during a solve"""
    max_seconds: float | None = None
    """[s] cap on each level's solve (coarse and fine alike); None: the
    service's defaults. A capped level is published unconverged, with its
    diagnosis, like any other stopped solve."""
    backend: str = field(default_factory=lambda: os.environ.get(BACKEND_ENV, ""))
    """direct linear-solver backend of the kinetic and Newton solvers ('pardiso',
    'pardiso32', 'cholmod', 'splu'); '' keeps the solver's own choice ('auto').
    Defaults to $COUTURE_SOLVER_BACKEND, so a test can run every solver node of a
    session on SuperLU without a flag per node."""
    sessions: list[str] = field(default_factory=list)
    """design sessions this node serves as a member of a solver pool ([]: its
    own session alone). With sessions, the node's own session is the pool's:
    its members see each other there (liveliness) and share the sessions out
    (:class:`PoolShare`); each session sees the member's drapes under its name."""


def solver_options(config: Config) -> dict:
    """Constructor options for ``get_solver(config.solver, ...)``."""
    if config.backend and config.solver in ("kinetic", "newton"):
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


@dataclass
class Served:
    """One design session a solver node serves."""

    resubmit: Callable[[], None]
    """queue a solve of the session's current design (a pool member that took the session over)"""
    abort: Callable[[], None]


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
        served: list[Served] = []
        try:
            if not config.sessions:
                served.append(serve(node.bus, node, config, worker))
            else:
                share = PoolShare(config.name, config.sessions)
                by_session: dict[str, Served] = {}
                for s in config.sessions:
                    b = open_session(replace(config.bus, session=s), name=config.name)
                    extra.append(b)
                    b.stats = node.bus.stats  # one status counts for every session served
                    b.declare_token(config.name)
                    by_session[s] = serve(b, node, config, worker, slot=f"{s}:", owns=partial(share.owns, s))
                served = list(by_session.values())

                def on_member(name: str, alive: bool) -> None:
                    for s in share.update(name, alive):
                        log.info(
                            "pool member %s %s: this member now solves session %s", name, "up" if alive else "gone", s
                        )
                        by_session[s].resubmit()

                node.bus.watch_nodes(on_member)
                log.info("solver pool member %s serving sessions %s", config.name, ", ".join(config.sessions))
            node.run()
        finally:
            for sv in served:
                sv.abort()
            worker.close()
            for b in extra:
                b.close()


def serve(
    bus: Bus,
    node: Node,
    config: Config,
    worker: LatestWorker,
    *,
    slot: str = "",
    owns: Callable[[], bool] = lambda: True,
) -> Served:
    """Solve one session's designs on ``bus``: drapes, rejections, the solve queryable.
    ``slot`` prefixes this session's jobs on the shared worker; ``owns()`` says
    whether this node solves the session now (a pool shares sessions out)."""
    service = make_service(config)
    pubs = {lv: bus.publisher(f"drape/{lv}", DrapeMsg) for lv in ("coarse", "fine")}
    rejected_pub = bus.publisher("rejected", RejectedMsg)
    lock = threading.Lock()
    state: dict = {"gesture": "", "dragging": False, "abort": False, "unfinished": False}
    """unfinished: the last solve was cut off (a press, a new mesh, a try-on op);
    a release that brings no new design resumes it"""
    tryon_ops: list[TryOnMsg] = []
    """try-on ops received, applied in order by the worker before its next solve"""

    def drape_msg(
        level: str,
        x: np.ndarray,
        res: float,
        it: int,
        wall: float,
        converged: bool = False,
        diagnosis: str = "",
        final: bool = True,
    ) -> DrapeMsg:
        lm = service.levels[level]
        return DrapeMsg(
            level=level,
            x=x.astype(np.float32),
            residual=float(res),
            iterations=int(it),
            solver=config.name,
            method=config.solver,
            wall_time_s=float(wall),
            converged=converged,
            diagnosis=diagnosis,
            generation=lm.mesh.generation,
            mesh_generation=lm.mesh_generation,
            final=final,
            edit_id=service.tryon_op_id,
            terms=list(getattr(lm.model, "terms", ())),
        )

    def should_abort() -> bool:
        return state["abort"] or node.stopping

    def on_progress(level: str, it: int, x: np.ndarray, res: float) -> None:
        pubs[level].put(drape_msg(level, x, res, it, 0.0, final=False))

    def on_level(run: LevelRun) -> None:
        r = run.result
        pubs[run.level].put(drape_msg(run.level, r.x, r.residual, r.iterations, r.wall_time, r.converged, r.diagnosis))
        node.count(f"solves/{run.level}")
        log.info(
            "gen %d %s: residual %.2e after %d its in %.2f s (%s, from %s)%s",
            service.levels[run.level].mesh.generation,
            run.level,
            r.residual,
            r.iterations,
            r.wall_time,
            config.solver,
            run.warm_start,
            f" [{r.diagnosis}]" if r.diagnosis else "",
        )
        if r.diagnosis and not r.converged and "abort" not in r.diagnosis.lower():
            node.error(f"{run.level}: {r.diagnosis}")

    def solve_job() -> None:
        if not owns():
            return  # another member of the pool solves this session
        with lock:
            if state["dragging"] or not service.ready():
                # a mesh that arrives mid-drag waits for the release
                state["unfinished"] = state["unfinished"] or (state["dragging"] and service.ready())
                return
            state["abort"] = False
            ops = list(tryon_ops)
            tryon_ops.clear()
        for op in ops:
            apply_tryon(op)
        state["unfinished"] = True
        service.run(
            should_abort=should_abort,
            on_progress=on_progress,
            on_level=on_level,
            progress_period_s=config.progress_period_s,
        )
        state["unfinished"] = bool(state["abort"])

    def take(matched: Matched[IncomingMesh]) -> None:
        try:
            ready = service.take(matched)
        except PatternError as e:
            m = matched.mesh
            node.count("bad_designs")
            node.error(f"mesh/{m.level} of generation {m.generation} (design {m.design_id or '?'}) rejected: {e}")
            rejected_pub.put(
                RejectedMsg(
                    node=config.name,
                    generation=m.generation,
                    design_id=m.design_id,
                    element=e.element,
                    reason=str(e),
                )
            )
            return
        node.count("meshes_taken")
        if ready:
            worker.submit(f"{slot}solve", solve_job)

    def on_pattern(msg: PatternMsg) -> None:
        for m in service.offer_design(msg.generation, msg.design, msg.identity()):
            worker.submit(f"{slot}mesh/{m.mesh.level}", lambda m=m: take(m))

    def on_mesh(msg: MeshMsg) -> None:
        prolong = None
        if msg.fine_parent_tri is not None and msg.fine_bary is not None:
            prolong = (msg.fine_parent_tri.numpy().copy(), msg.fine_bary.numpy().copy())
        out = service.offer_mesh(
            msg.level, msg.generation, msg.mesh_generation, IncomingMesh(msg_to_mesh(msg), prolong), msg.design_id
        )
        if out.status == "stale":
            node.count("stale_meshes")
        matched = out.matched
        if matched is None:
            return
        state["abort"] = True  # a new mesh supersedes the running solve
        worker.submit(f"{slot}mesh/{msg.level}", lambda: take(matched))

    def on_edit(msg: EditMsg) -> None:
        if msg.phase == "press":
            verdict = service.judge_edit(msg.generation)
            if verdict != "current":
                node.count(f"{verdict}_edits")
                log.warning(
                    "edit %s: press on generation %d, this solver's design is %d (%s): ignored",
                    msg.edit_id,
                    msg.generation,
                    service.generation,
                    verdict,
                )
                return
            state["gesture"] = msg.edit_id
            state["dragging"] = True
            state["abort"] = True
            node.count("presses")
        elif msg.phase == "release" and msg.edit_id == state["gesture"]:
            state["dragging"] = False
            if state["unfinished"]:
                # the press cut a solve off; a gesture that ends where it began (or a
                # design the remesher refuses) brings no new mesh to restart it
                node.count("resumed_solves")
                worker.submit(f"{slot}solve", solve_job)

    def on_prediction(msg: DrapeMsg) -> None:
        # a prediction lives on a mesh this solver matched (the release's is
        # the warm start of the next design's mesh, numbered later)
        if service.judge_edit(msg.generation) == "foreign":
            node.count("foreign_predictions")
            log.warning(
                "prediction for edit %s of generation %d ignored: this solver's newest design is %d",
                msg.edit_id,
                msg.generation,
                service.generation,
            )
            return
        service.set_prediction(msg.mesh_level, msg.mesh_generation, msg.x.numpy())

    def apply_tryon(msg: TryOnMsg) -> None:
        if service.judge_edit(msg.generation) != "current":
            node.count("stale_tryon")
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
            node.count("bad_tryon")
            node.error(f"try-on {msg.op} {msg.op_id}: {e}")
            # the sender waits for a drape answering the op: tell it there will be none
            rejected_pub.put(
                RejectedMsg(
                    node=config.name,
                    generation=msg.generation,
                    element=f"tryon.{msg.op}",
                    reason=f"try-on {msg.op} refused: {e}",
                    op_id=msg.op_id,
                    source="tryon",
                )
            )
            return
        node.count("tryon")
        log.info("try-on %s %s applied (panel %r, seam %d)", msg.op, msg.op_id, msg.panel, msg.seam)

    def on_tryon(msg: TryOnMsg) -> None:
        # applied by the worker thread, between solves (the models change)
        with lock:
            tryon_ops.append(msg)
        state["abort"] = True
        worker.submit(f"{slot}solve", solve_job)

    def handle_solve(req: SolveRequestMsg) -> SolveResultMsg:
        design = req.design or service.design
        if design is None:
            raise RuntimeError("request has no design and this solver has seen no pattern")
        check_simulation_values(design)  # PatternError naming the field: the result's error
        if req.mesh is not None:
            mesh = msg_to_mesh(req.mesh)
        else:
            lm = service.levels.get(req.level)
            if lm is None or lm.mesh_generation != req.mesh_generation:
                raise RuntimeError(f"no {req.level} mesh of mesh_generation {req.mesh_generation} here")
            mesh = lm.mesh
        model = ClothModel(mesh, design.fabric, scene_from_design(design))
        x0 = req.x_warm.numpy() if req.x_warm is not None else mesh.x0
        # friction from the first iteration from a placement, the solver's own schedule from a warm start,
        # as this node solves its levels (couture.solvers.service.FRICTION_AT_ONCE)
        r = get_solver(config.solver, **solver_options(config)).solve(
            model,
            np.array(x0),
            tol=req.tol,
            max_iters=req.max_iters,
            max_seconds=req.max_seconds,
            friction_after=math.inf if req.x_warm is None else None,
        )
        return SolveResultMsg(
            method=config.solver,
            level=req.level,
            mesh_generation=req.mesh_generation,
            x=r.x,
            residual=r.residual,
            iterations=r.iterations,
            wall_time_s=r.wall_time,
            converged=r.converged,
            diagnosis=r.diagnosis,
        )

    bus.subscribe("pattern", on_pattern)
    bus.subscribe("mesh/coarse", on_mesh)
    bus.subscribe("mesh/fine", on_mesh)
    bus.subscribe("edit", on_edit)
    bus.subscribe("drape/predicted", on_prediction)
    bus.subscribe("tryon", on_tryon)
    bus.serve_solve(config.name, handle_solve)

    def abort() -> None:
        state["abort"] = True

    return Served(resubmit=lambda: worker.submit(f"{slot}solve", solve_job), abort=abort)

"""The adjust node: direct 3D edits (hem, waist) -> physics-adjusted patterns.

A thin adapter over :func:`couture.adjust.service.run_adjustment`. Each
``adjust`` request (:class:`schemas.AdjustMsg`) runs on one worker thread,
never on a Zenoh callback thread; a request that arrives while another runs
waits, and a newer one replaces it (the replaced one is answered ``failed``,
"superseded"). Its solves go to the session's solver nodes through the
``solve`` queryable (:class:`couture.client.SolveFanout`, round robin over
every live ``solver-*`` node or the ones configured), so the other nodes keep
serving edits and drapes between them. Progress goes out on
``adjust/status`` (:class:`schemas.AdjustStatusMsg`: running, one message per
re-simulated pattern, then done or failed; done carries the verdict against
the goal: met or not, and why); on success the adjusted design
is published on ``pattern`` (source ``adjust``), so the remesher meshes it,
the solvers drape it and every ui shows it. The settings are
``couture.adjust.settings.DEFAULTS``, those of ``couture adjust``, unless
the request names its ``max_iters``; for the same design, edit and vertices
the node and the command compute the same adjusted pattern and design. On failure nothing is published:
the current design stays, and the status says why. A malformed request is
dropped by the bus with the reason in this node's status (``last_error``).
"""

from __future__ import annotations

import logging
import threading
import uuid
from dataclasses import dataclass, field

from couture.bus import BusConfig, Node
from couture.bus.worker import LatestWorker
from schemas import AdjustMsg, AdjustStatusMsg, PatternMsg

log = logging.getLogger("adjust")


@dataclass
class Config:
    bus: BusConfig = field(default_factory=BusConfig)
    name: str = "adjust"
    """node name, unique in the session (liveliness key status/<name>)"""
    vertices: int = 400
    """coarse mesh size [vertices] of a request that names none (0)"""
    solvers: list[str] = field(default_factory=list, metadata={"flag": "--solver"})
    """solver node names to ask (repeatable); empty: every live ``solver-*`` node"""
    max_seconds: float = 60.0
    """[s] cap on each solve"""


class AdjustAdapter:
    """Wires :func:`run_adjustment` to one node's bus (tests may build it on their own Node)."""

    def __init__(self, node: Node, config: Config):
        self.node, self.config = node, config
        bus = node.bus
        self.status_pub = bus.publisher("adjust/status", AdjustStatusMsg)
        self.pattern_pub = bus.publisher("pattern", PatternMsg)
        self.worker = LatestWorker("adjust", on_error=node.error)
        self._lock = threading.Lock()
        self._queued: AdjustMsg | None = None
        self._asked = 0
        self.busy = False
        self.live: dict[str, bool] = {}
        """node name -> alive, from the liveliness tokens (a subscription: no query per request)"""
        bus.watch_nodes(self.on_liveliness)
        bus.subscribe("adjust", self.on_request)

    def on_liveliness(self, name: str, alive: bool) -> None:
        self.live[name] = alive

    def solvers(self) -> list[str]:
        """The solver nodes to ask: the configured ones, else every live ``solver-*``."""
        if self.config.solvers:
            return list(self.config.solvers)
        names = sorted(n for n, alive in self.live.items() if alive and n.startswith("solver"))
        return names or sorted(n for n in self.node.bus.live_nodes(timeout=2.0) if n.startswith("solver"))

    # -- in (Zenoh thread: queue and return)
    def on_request(self, msg: AdjustMsg) -> None:
        self.node.count("adjust_in")
        if not msg.request_id:
            msg.request_id = uuid.uuid4().hex[:12]
        with self._lock:
            old, self._queued = self._queued, msg
        if old is not None:
            self.say(old, "failed", error=f"superseded by request {msg.request_id} before it started")
        self.worker.submit("adjust", lambda: self.run(msg))

    # -- out
    def say(self, req: AdjustMsg, state: str, iteration: int = 0, text: str = "", **kw) -> None:
        self.status_pub.put(
            AdjustStatusMsg(
                request_id=req.request_id,
                node=self.config.name,
                state=state,  # type: ignore[arg-type]  # one of the Literal's values
                iteration=iteration,
                text=text,
                generation=req.generation,
                **kw,
            )
        )

    def run(self, req: AdjustMsg) -> None:
        from couture.adjust.service import run_adjustment
        from couture.adjust.settings import DEFAULTS
        from couture.client import BusSolves, SolveFanout

        with self._lock:
            if self._queued is req:
                self._queued = None
        self.busy = True
        self.node.state = "busy"
        try:
            names = self.solvers()
            if not names:
                raise RuntimeError("no solver node is live in this session: nothing can simulate the adjusted patterns")
            vertices = req.vertices or self.config.vertices
            self.say(req, "running", text=f"{req.edit} {req.amount:+.3f} m on {vertices} vertices, solves on {names}")
            log.info(
                "request %s: %s %+.3f m, %d vertices, solvers %s", req.request_id, req.edit, req.amount, vertices, names
            )
            solves = BusSolves(self.node.bus)

            def simulate_for(mesh):
                return SolveFanout(solves, mesh, req.design, names, max_seconds=self.config.max_seconds)

            def progress(state: str, k: int, text: str) -> None:
                log.info("request %s: %s", req.request_id, text)
                self.say(req, state, k, text)

            out = run_adjustment(
                req.design,
                req.edit,
                req.amount,
                simulate_for,
                vertices=vertices,
                settings=DEFAULTS.with_(updates=req.max_iters),
                progress=progress,
            )
        except Exception as e:
            why = f"{type(e).__name__}: {e}" if not isinstance(e, ValueError) else str(e)
            self.node.count("adjust_failed")
            self.node.error(f"adjust request {req.request_id} failed: {why}")
            self.say(req, "failed", error=why, text=f"adjustment failed, the design is unchanged: {why}")
            return
        finally:
            self.busy = False
            self.node.state = "running"
        design_id = uuid.uuid4().hex
        with self._lock:
            self._asked = gen = max(self._asked, req.generation) + 1
        self.pattern_pub.put(
            PatternMsg(design=out.design, source=self.config.name, name="adjusted", design_id=design_id, generation=gen)
        )
        self.node.count("adjust_done")
        log.info("request %s done: %s", req.request_id, out.text())
        self.say(
            req,
            "done",
            len(out.case.result.history) - 1,
            out.text(),
            hausdorff_pct=out.hausdorff_pct,
            stretch=out.verdict.stretch,
            solves=out.verdict.solves,
            goal_met=out.verdict.met,
            reasons=list(out.verdict.reasons),
            design_id=design_id,
            options={k: b for k, (_, b) in out.projection.changed.items()},
            fit_rms_m=out.projection.fit_rms_m,
            achieved_m=out.achieved,
        )

    def close(self) -> None:
        self.worker.close()


def main(config: Config) -> None:
    with Node(config.name, config.bus, kind="adjust", announce=False) as node:
        adapter = AdjustAdapter(node, config)
        node.announce()  # live only once it listens
        try:
            node.run()
        finally:
            adapter.close()

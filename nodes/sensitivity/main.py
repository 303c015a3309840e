"""The sensitivity node (SC §4, §7.2): instant 3D response to 2D and 3D edits.

A thin adapter over :class:`couture.sensitivity.service.SensitivityService`:
messages become calls, results become messages. Callbacks only call the
cheap methods and queue the rest on two worker threads: ``edits`` (Ψ columns,
predictions at pointer rate) and ``idle`` (model builds, refactorization,
error estimates, the solves that enrich the cache). On a 3D tug's release it
also publishes the tug's new design as a ``pattern``.

A press that comes before the equilibrium (the final drape's refactorization)
is held by the service and served when it is there; the status says whether
predictions are ready (``ready``, ``ready_generation``,
``ready_mesh_generation``) and counts ``gestures_held`` and
``gestures_expired``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from couture.bus import BusConfig, Node
from couture.bus.worker import LatestWorker
from couture.designs import Matched
from couture.mesh import GarmentMesh
from couture.pattern.errors import PatternError
from couture.sensitivity.service import (
    Gesture,
    NoEquilibrium,
    PredictionOut,
    Press,
    ReleaseOut,
    SensitivityConfig,
    SensitivityService,
)
from schemas import Array, DrapeMsg, EditMsg, MeshMsg, PatternMsg, PsiMsg
from schemas.convert import msg_to_mesh

log = logging.getLogger("sensitivity")


@dataclass
class Config:
    bus: BusConfig = field(default_factory=BusConfig)
    name: str = "sensitivity"
    """node name, unique in the session (liveliness key status/<name>)"""
    method: str = field(default="gmls", metadata={"choices": ("gmls", "mls", "linear")})
    """'gmls', 'mls' or 'linear'"""
    pause_s: float = 0.3
    """[s] without pointer motion before the idle solve that enriches the cache"""
    enrich_seconds: float = 2.0
    """[s] budget of one idle solve"""
    enrich_tol: float = 1e-3
    """relative residual the idle solve aims for"""
    hold_s: float = 5.0
    """[s] a press that came before its equilibrium waits at most this long"""


class SensitivityAdapter:
    """Wires one :class:`SensitivityService` to one bus: a handler per input
    (pattern, mesh/fine, psi/fine, drape/fine, edit) and the idle tick; the
    work goes to the ``edits`` and ``idle`` worker threads. Separate from
    :func:`main` so tests can drive it with their own Node."""

    def __init__(self, node: Node, config: Config) -> None:
        self.node, self.config = node, config
        self.service = SensitivityService(
            SensitivityConfig(
                method=config.method,
                pause_s=config.pause_s,
                enrich_seconds=config.enrich_seconds,
                enrich_tol=config.enrich_tol,
                hold_s=config.hold_s,
            )
        )
        self.service.count = node.count
        node.readiness = self.service.readiness
        bus = node.bus
        self.pred_pub = bus.publisher("drape/predicted", DrapeMsg)
        self.pattern_pub = bus.publisher("pattern", PatternMsg)
        self.idle = LatestWorker("sensitivity-idle", on_error=node.error)
        self.edits = LatestWorker("sensitivity-edit", on_error=node.error)
        bus.subscribe("pattern", self.on_pattern)
        bus.subscribe("mesh/fine", self.on_mesh)
        bus.subscribe("psi/fine", self.on_psi)
        bus.subscribe("drape/fine", self.on_drape)
        bus.subscribe("edit", self.on_edit)

    def close(self) -> None:
        self.edits.close()
        self.idle.close()

    # -- out
    def publish(self, out: PredictionOut | None) -> None:
        if out is None:
            return
        self.pred_pub.put(
            DrapeMsg(
                level="predicted",
                mesh_level="fine",
                mesh_generation=out.mesh_generation,
                x=Array.from_numpy(out.x, "float32"),
                d=Array.from_numpy(out.d, "float64"),
                edit_id=out.edit_id,
                method=out.method,
                error_estimate=out.error_estimate,
                error_estimate_m=out.error_estimate_m,
                generation=out.generation,
                final=True,
                diagnosis="release" if out.release else "",
            )
        )

    def take(self, m: Matched[GarmentMesh]) -> None:
        self.idle.submit("mesh", lambda: self.service.take(m))

    # -- in (Zenoh threads: the cheap calls, the rest queued)
    def on_pattern(self, msg: PatternMsg) -> None:
        for m in self.service.offer_design(msg.generation, msg.design, msg.identity()):
            self.take(m)

    def on_mesh(self, msg: MeshMsg) -> None:
        if msg.level != "fine":
            return
        out = self.service.offer_mesh(msg.generation, msg.mesh_generation, msg_to_mesh(msg), msg.design_id)
        if out.status == "stale":
            self.node.count("stale_meshes")
        if out.matched is not None:
            self.take(out.matched)

    def on_psi(self, msg: PsiMsg) -> None:
        psi = msg.psi.numpy().copy()
        self.edits.submit("press", lambda: self.press_columns(msg.edit_id, psi))

    def on_drape(self, msg: DrapeMsg) -> None:
        if not msg.final or msg.level != "fine":
            return
        x = msg.x.numpy().astype(np.float64)

        def job() -> None:
            if self.service.equilibrium(msg.mesh_generation, x) is not None:
                self.node.count("refactors")
                self.edits.submit("held", self.resume)

        self.idle.submit("equilibrium", job)

    def on_edit(self, msg: EditMsg) -> None:
        service = self.service
        if msg.phase == "press":
            vp = msg.viewport_px
            g = service.press(
                Press(
                    edit_id=msg.edit_id,
                    element=msg.element,
                    generation=msg.generation,
                    param=msg.param,
                    picked_vertex=msg.picked_vertex,
                    view_proj=None if msg.view_proj is None else msg.view_proj.numpy().copy(),
                    viewport=(vp[0], vp[1]) if len(vp) == 2 else (1, 1),
                )
            )
            if g is not None:
                self.node.count("presses")
            return
        if service.current(msg.edit_id) is None:
            return
        d_raw = msg.d.numpy().copy()
        if msg.phase == "drag":
            service.moved(msg.edit_id)
            self.edits.submit("drag", lambda: self.predict(msg.edit_id, d_raw))
        else:
            self.edits.submit("drag", lambda: self.release(msg.edit_id, d_raw))

    # -- edit work (edits worker)
    def press_columns(self, edit_id: str, psi: np.ndarray) -> None:
        try:
            g = self.service.psi(edit_id, psi)
        except NoEquilibrium as e:
            self.node.error(str(e))
            return
        if g is not None and g.ready:
            self.node.count("press_columns")
            self.resume()

    def resume(self) -> None:
        """Serve what waited on the gesture (its drag, its release)."""
        g = self.service.gesture
        was_ready = g is not None and g.ready
        try:
            out = self.service.resume()
        except (NoEquilibrium, PatternError) as e:
            self.node.error(f"held edit: {e}")
            return
        if g is not None and g.ready and not was_ready:
            self.node.count("press_columns")
        if isinstance(out, ReleaseOut):
            self.released(out)
        elif out is not None:
            self.published(out)

    def predict(self, edit_id: str, d_raw: np.ndarray) -> None:
        out = self.service.drag(edit_id, d_raw)
        if out is not None:
            self.published(out)

    def published(self, out: PredictionOut) -> None:
        self.publish(out)
        self.node.count("predictions")
        self.idle.submit("error", lambda: self.publish(self.service.estimate(out)))

    def release(self, edit_id: str, d_raw: np.ndarray) -> None:
        try:
            r = self.service.release(edit_id, d_raw)
        except PatternError as e:
            self.node.error(f"3D tug {edit_id}: {e}")
            return
        if r is not None:
            self.released(r)

    def released(self, r: ReleaseOut) -> None:
        self.publish(r.prediction)
        if r.prediction is not None:
            self.node.count("predictions")
        if r.design is not None:
            self.pattern_pub.put(
                PatternMsg(
                    design=r.design,
                    generation=r.generation,
                    design_id=r.design_id,
                    source=self.config.name,
                    name="3D tug",
                )
            )

    # -- idle enrichment: a short solve where the pointer pauses
    def enrich(self, g: Gesture) -> None:
        out = self.service.enrich(g)
        if out is not None:
            self.node.count("samples")
            self.publish(out)

    def tick(self) -> None:
        held = self.service.expire()
        if held is not None:
            self.node.error(
                f"edit {held.edit_id}: not ready within {self.config.hold_s:g} s (see the log); gesture given up"
            )
        if self.idle.pending("enrich"):
            return
        g = self.service.pause()
        if g is not None:
            self.idle.submit("enrich", lambda: self.enrich(g))


def main(config: Config) -> None:
    with Node(config.name, config.bus, kind="sensitivity") as node:
        adapter = SensitivityAdapter(node, config)
        try:
            node.run(idle=adapter.tick, period_s=0.05)
        finally:
            adapter.close()

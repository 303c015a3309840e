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
from schemas import DrapeMsg, EditMsg, MeshMsg, PatternMsg, PsiMsg
from schemas.convert import msg_to_mesh

log = logging.getLogger("sensitivity")


@dataclass
class Config:
    bus: BusConfig = field(default_factory=BusConfig)
    name: str = "sensitivity"
    """node name, unique in the session (liveliness key status/<name>)"""
    method: str = "gmls"
    """'gmls', 'mls' or 'linear'"""
    pause_s: float = 0.3
    """[s] without pointer motion before the idle solve that enriches the cache"""
    enrich_seconds: float = 2.0
    """[s] budget of one idle solve"""
    enrich_tol: float = 1e-3
    """relative residual the idle solve aims for"""
    hold_s: float = 5.0
    """[s] a press that came before its equilibrium waits at most this long"""


def main(config: Config) -> None:
    service = SensitivityService(
        SensitivityConfig(
            method=config.method,
            pause_s=config.pause_s,
            enrich_seconds=config.enrich_seconds,
            enrich_tol=config.enrich_tol,
            hold_s=config.hold_s,
        )
    )
    with Node(config.name, config.bus, kind="sensitivity") as node:
        service.count = node.count
        node.readiness = service.readiness
        bus = node.bus
        pred_pub = bus.publisher("drape/predicted", DrapeMsg)
        pattern_pub = bus.publisher("pattern", PatternMsg)
        idle = LatestWorker("sensitivity-idle", on_error=node.error)
        edits = LatestWorker("sensitivity-edit", on_error=node.error)

        def publish(out: PredictionOut | None) -> None:
            if out is None:
                return
            pred_pub.put(
                DrapeMsg(
                    level="predicted",
                    mesh_level="fine",
                    mesh_generation=out.mesh_generation,
                    x=out.x.astype(np.float32),
                    d=out.d,
                    edit_id=out.edit_id,
                    method=out.method,
                    error_estimate=out.error_estimate,
                    error_estimate_m=out.error_estimate_m,
                    generation=out.generation,
                    final=True,
                    diagnosis="release" if out.release else "",
                )
            )

        def take(m: Matched[GarmentMesh]) -> None:
            idle.submit("mesh", lambda: service.take(m))

        # -- inputs -----------------------------------------------------------
        def on_pattern(msg: PatternMsg) -> None:
            for m in service.offer_design(msg.generation, msg.design, msg.identity()):
                take(m)

        def on_mesh(msg: MeshMsg) -> None:
            if msg.level != "fine":
                return
            out = service.offer_mesh(msg.generation, msg.mesh_generation, msg_to_mesh(msg), msg.design_id)
            if out.status == "stale":
                node.count("stale_meshes")
            if out.matched is not None:
                take(out.matched)

        def on_psi(msg: PsiMsg) -> None:
            psi = msg.psi.numpy().copy()
            edits.submit("press", lambda: press_columns(msg.edit_id, psi))

        def on_drape(msg: DrapeMsg) -> None:
            if not msg.final or msg.level != "fine":
                return
            x = msg.x.numpy().astype(np.float64)

            def job() -> None:
                if service.equilibrium(msg.mesh_generation, x) is not None:
                    node.count("refactors")
                    edits.submit("held", resume)

            idle.submit("equilibrium", job)

        def on_edit(msg: EditMsg) -> None:
            if msg.phase == "press":
                g = service.press(
                    Press(
                        edit_id=msg.edit_id,
                        element=msg.element,
                        generation=msg.generation,
                        param=msg.param,
                        picked_vertex=msg.picked_vertex,
                        view_proj=None if msg.view_proj is None else msg.view_proj.numpy().copy(),
                        viewport=(tuple(msg.viewport_px) if len(msg.viewport_px) == 2 else (1, 1)),
                    )
                )  # type: ignore[arg-type]
                if g is not None:
                    node.count("presses")
                return
            if service.current(msg.edit_id) is None:
                return
            d_raw = msg.d.numpy().copy()
            if msg.phase == "drag":
                service.moved(msg.edit_id)
                edits.submit("drag", lambda: predict(msg.edit_id, d_raw))
            else:
                edits.submit("drag", lambda: release(msg.edit_id, d_raw))

        # -- edit work (edits worker) -----------------------------------------
        def press_columns(edit_id: str, psi: np.ndarray) -> None:
            try:
                g = service.psi(edit_id, psi)
            except NoEquilibrium as e:
                node.error(str(e))
                return
            if g is not None and g.ready:
                node.count("press_columns")
                resume()

        def resume() -> None:
            """Serve what waited on the gesture (its drag, its release)."""
            g = service.gesture
            was_ready = g is not None and g.ready
            try:
                out = service.resume()
            except (NoEquilibrium, PatternError) as e:
                node.error(f"held edit: {e}")
                return
            if g is not None and g.ready and not was_ready:
                node.count("press_columns")
            if isinstance(out, ReleaseOut):
                released(out)
            elif out is not None:
                published(out)

        def predict(edit_id: str, d_raw: np.ndarray) -> None:
            out = service.drag(edit_id, d_raw)
            if out is not None:
                published(out)

        def published(out: PredictionOut) -> None:
            publish(out)
            node.count("predictions")
            idle.submit("error", lambda: publish(service.estimate(out)))

        def release(edit_id: str, d_raw: np.ndarray) -> None:
            try:
                r = service.release(edit_id, d_raw)
            except PatternError as e:
                node.error(f"3D tug {edit_id}: {e}")
                return
            if r is not None:
                released(r)

        def released(r: ReleaseOut) -> None:
            publish(r.prediction)
            if r.prediction is not None:
                node.count("predictions")
            if r.design is not None:
                pattern_pub.put(
                    PatternMsg(
                        design=r.design,
                        generation=r.generation,
                        design_id=r.design_id,
                        source=config.name,
                        name="3D tug",
                    )
                )

        # -- idle enrichment: a short solve where the pointer pauses ------------
        def enrich(g: Gesture) -> None:
            out = service.enrich(g)
            if out is not None:
                node.count("samples")
                publish(out)

        def tick() -> None:
            held = service.expire()
            if held is not None:
                node.error(f"edit {held.edit_id}: not ready within {config.hold_s:g} s (see the log); gesture given up")
            if idle.pending("enrich"):
                return
            g = service.pause()
            if g is not None:
                idle.submit("enrich", lambda: enrich(g))

        bus.subscribe("pattern", on_pattern)
        bus.subscribe("mesh/fine", on_mesh)
        bus.subscribe("psi/fine", on_psi)
        bus.subscribe("drape/fine", on_drape)
        bus.subscribe("edit", on_edit)
        try:
            node.run(idle=tick, period_s=0.05)
        finally:
            edits.close()
            idle.close()

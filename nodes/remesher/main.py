"""The remesher node: pattern -> mesh/coarse + mesh/fine, Ψ on press.

A thin adapter over :class:`couture.remesh.service.RemeshService`, which also
numbers the session's designs: meshes carry the generation it gave and the
publisher's ``design_id``. Bus
callbacks only queue work; one worker thread drafts, meshes and publishes,
newest pattern first. A bad pattern (validation error naming the element) is
answered at once on ``rejected`` (:class:`schemas.RejectedMsg`: the element,
the value, the allowed range), also reported in the node's status, and the
last good meshes stay published. A design that fails later, in meshing, is
rejected the same way, with the exception's text.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from couture.bus import BusConfig, Node
from couture.bus.worker import LatestWorker
from couture.pattern.errors import PatternError
from couture.remesh.service import MeshUpdate, RemeshService
from schemas import DrapeMsg, EditMsg, MeshMsg, PatternMsg, RejectedMsg
from schemas.convert import mesh_to_msg

log = logging.getLogger("remesher")


@dataclass
class Config:
    bus: BusConfig = field(default_factory=BusConfig)
    name: str = "remesher"
    """node name, unique in the session (liveliness key status/<name>)"""


def main(config: Config) -> None:
    service = RemeshService()
    with Node(config.name, config.bus, kind="remesher") as node:
        bus = node.bus
        pubs = {lv: bus.publisher(f"mesh/{lv}", MeshMsg) for lv in ("coarse", "fine")}
        rejected_pub = bus.publisher("rejected", RejectedMsg)
        worker = LatestWorker("remesh", on_error=node.error)

        def reject(msg: PatternMsg, element: str, reason: str) -> None:
            node.count("bad_patterns")
            node.error(f"pattern generation {msg.generation} rejected: {reason}")
            rejected_pub.put(
                RejectedMsg(
                    node=config.name,
                    generation=msg.generation,
                    design_id=msg.design_id,
                    element=element,
                    reason=reason,
                    name=msg.name,
                    source=msg.source,
                )
            )

        def publish(up: MeshUpdate, psi: np.ndarray | None = None, edit_id: str = "") -> None:
            # Ψ rides on the mesh the receivers already hold, marked unchanged so
            # that none of them resets its state to this mesh's x0
            msg = mesh_to_msg(
                up.mesh,
                generation=service.generation,
                mesh_generation=up.mesh_generation,
                psi=psi,
                psi_edit_id=edit_id,
                unchanged=psi is not None,
                design_id=service.design_id,
                fine_parent_tri=up.fine_parent_tri,
                fine_bary=up.fine_bary,
            )
            pubs[up.level].put(msg)

        def on_pattern(msg: PatternMsg) -> None:
            def job() -> None:
                generation = service.next_generation(msg.generation)
                try:
                    updates = service.set_design(msg.design, generation, msg.design_id)
                except PatternError as e:
                    reject(msg, e.element, str(e))
                    return
                except Exception as e:  # meshing failed: still an answer, never silence
                    log.exception("pattern generation %d: meshing failed", msg.generation)
                    reject(msg, "", f"the remesher could not mesh this design: {type(e).__name__}: {e}")
                    return
                if generation != msg.generation:
                    node.count("renumbered_patterns")
                    log.warning(
                        "pattern %r from %r asked for generation %d, already used: numbered %d",
                        msg.design_id or msg.name,
                        msg.source,
                        msg.generation,
                        generation,
                    )
                for up in updates:
                    publish(up)
                    log.info(
                        "gen %d %s: %d vertices (%s, %.0f ms)",
                        generation,
                        up.level,
                        up.mesh.n_vertices,
                        up.how,
                        1e3 * up.seconds,
                    )
                node.count("meshes", len(updates))
                worker.submit("warm", service.warm_coordinates)

            worker.submit("pattern", job)

        def on_edit(msg: EditMsg) -> None:
            if msg.phase != "press":
                return
            # a 3D tug drives a sloper parameter: its Ψ is dX/dg (column 0)
            element = f"param:{msg.param}" if msg.picked_vertex >= 0 and msg.param else msg.element
            if not element:
                return

            def job() -> None:
                try:
                    psis = service.psi_for(element)
                except (PatternError, RuntimeError, KeyError) as e:
                    node.error(f"edit {msg.edit_id}: no Ψ for {element!r}: {e}")
                    return
                for level, st in service.levels.items():
                    publish(MeshUpdate(level, st.mesh, st.mesh_generation, "psi"), psi=psis[level], edit_id=msg.edit_id)
                node.count("psi")

            worker.submit("press", job)

        def on_drape(msg: DrapeMsg) -> None:
            service.observe(msg.generation)
            if msg.level in ("coarse", "fine"):
                service.note_drape(msg.level, msg.mesh_generation, msg.x.numpy())

        def on_mesh(msg: MeshMsg) -> None:
            service.observe(msg.generation, msg.mesh_generation)  # a predecessor's, after a restart

        bus.subscribe("pattern", on_pattern)
        bus.subscribe("edit", on_edit)
        bus.subscribe("drape/coarse", on_drape)
        bus.subscribe("drape/fine", on_drape)
        bus.subscribe("mesh/coarse", on_mesh)
        bus.subscribe("mesh/fine", on_mesh)
        try:
            node.run()
        finally:
            worker.close()

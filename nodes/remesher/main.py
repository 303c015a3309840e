"""The remesher node: pattern -> mesh/coarse + mesh/fine; press -> psi/coarse + psi/fine.

A thin adapter over :class:`couture.remesh.service.RemeshService`, which also
numbers the session's designs: meshes carry the generation it gave and the
pattern's identity. Bus callbacks only queue work; one worker thread drafts,
meshes and publishes, newest pattern first. A bad pattern (validation error
naming the element) is answered at once on ``rejected``
(:class:`schemas.RejectedMsg`: the design's identity, the generation it asked
for, the element, the value, the allowed range), also reported in the node's
status (``pattern generation N (design ID) rejected: ...``), and the last good
meshes stay published; a rejected design is given no number. A design that
fails later, in meshing, is rejected the same way, with the exception's text.
Every number that is not the one expected is logged with both
numbers and counted in the status: a pattern renumbered (``renumbered_patterns``,
and ``stale_generations`` or ``foreign_generations`` for what it asked), a press
on another design than the current one (``stale_edits``, ``foreign_edits``: no
Ψ), a mesh or drape numbered above this remesher's own designs
(``foreign_generations``), a pattern superseded before it was meshed
(``superseded_patterns``).
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field

from couture.bus import BusConfig, Node
from couture.bus.worker import LatestWorker
from couture.pattern.errors import PatternError
from couture.remesh.service import MeshUpdate, RemeshService
from schemas import DrapeMsg, EditMsg, MeshMsg, PatternMsg, PsiMsg, RejectedMsg
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
        psi_pubs = {lv: bus.publisher(f"psi/{lv}", PsiMsg) for lv in ("coarse", "fine")}
        rejected_pub = bus.publisher("rejected", RejectedMsg)
        worker = LatestWorker("remesh", on_error=node.error)

        def reject(msg: PatternMsg, element: str, reason: str) -> None:
            key = msg.identity()
            node.count("bad_patterns")
            node.error(f"pattern generation {msg.generation} (design {key}) rejected: {reason}")
            rejected_pub.put(
                RejectedMsg(
                    node=config.name,
                    generation=msg.generation,
                    design_id=key,
                    element=element,
                    reason=reason,
                    name=msg.name,
                    source=msg.source,
                )
            )

        def publish(up: MeshUpdate) -> None:
            msg = mesh_to_msg(
                up.mesh,
                generation=service.generation,
                mesh_generation=up.mesh_generation,
                design_id=service.design_id,
                fine_parent_tri=up.fine_parent_tri,
                fine_bary=up.fine_bary,
            )
            pubs[up.level].put(msg)

        queued: dict[str, str] = {}
        """slot -> identity of the pattern queued and not yet started"""
        queued_lock = threading.Lock()

        def on_pattern(msg: PatternMsg) -> None:
            key = msg.identity()

            def job() -> None:
                with queued_lock:
                    if queued.get("pattern") == key:
                        del queued["pattern"]
                generation = service.next_generation(msg.generation)
                try:
                    updates = service.set_design(msg.design, generation, key)
                except PatternError as e:
                    reject(msg, e.element, str(e))
                    return
                except Exception as e:  # meshing failed: still an answer, never silence
                    log.exception("pattern generation %d (design %s): meshing failed", msg.generation, key)
                    reject(msg, "", f"the remesher could not mesh this design: {type(e).__name__}: {e}")
                    return
                verdict = service.request_verdict(msg.generation, generation)
                if verdict != "granted":
                    node.count("renumbered_patterns")
                    node.count(f"{verdict}_generations")
                    log.warning(
                        "pattern %s from %r asked for generation %d (%s: newest given %d): numbered %d",
                        key,
                        msg.source,
                        msg.generation,
                        "already used" if verdict == "stale" else "too far ahead",
                        generation - 1,
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

            with queued_lock:
                older = queued.get("pattern")
                queued["pattern"] = key
            if older is not None:
                # newest pattern first: the queued one is never meshed nor numbered
                node.count("superseded_patterns")
                log.info("pattern %s superseded by %s before it was meshed", older, key)
            worker.submit("pattern", job)

        def off_design(msg: EditMsg) -> bool:
            """A press made on another design than the current one: logged, counted, no Ψ."""
            verdict = service.judge_edit(msg.generation)
            if verdict == "current":
                return False
            node.count(f"{verdict}_edits")
            log.warning(
                "edit %s: press on generation %d, the current design is %d (%s): no Ψ",
                msg.edit_id,
                msg.generation,
                service.generation,
                verdict,
            )
            return True

        def on_edit(msg: EditMsg) -> None:
            if msg.phase != "press":
                return
            # a 3D tug drives a sloper parameter: its Ψ is dX/dg (column 0)
            element = f"param:{msg.param}" if msg.picked_vertex >= 0 and msg.param else msg.element
            if not element or off_design(msg):  # judged on arrival: a newer press would supersede the job
                return

            def job() -> None:
                if off_design(msg):  # a pattern queued before it has been numbered since
                    return
                try:
                    psis = service.psi_for(element)
                except (PatternError, RuntimeError, KeyError) as e:
                    node.error(f"edit {msg.edit_id}: no Ψ for {element!r}: {e}")
                    return
                # Ψ alone: the receivers hold the meshes it lives on (the fine one first, the
                # sensitivity node's first prediction waits on it)
                for level in sorted(psis, key=lambda lv: lv != "fine"):
                    psi_pubs[level].put(
                        PsiMsg(
                            generation=service.generation,
                            level=level,  # type: ignore[arg-type]
                            mesh_generation=service.levels[level].mesh_generation,
                            design_id=service.design_id,
                            edit_id=msg.edit_id,
                            psi=psis[level],
                        )
                    )
                node.count("psi")

            worker.submit("press", job)

        def observe(what: str, generation: int, mesh_generation: int = 0) -> bool:
            if service.observe(generation, mesh_generation):
                return True
            node.count("foreign_generations")
            log.warning(
                "%s of generation %d ignored: above every design this remesher numbered (newest %d)",
                what,
                generation,
                service.generation,
            )
            return False

        def on_drape(msg: DrapeMsg) -> None:
            # a drape names its mesh too: after a restart the predecessor's meshes are gone with
            # its publisher's history, the solver's drapes are not, and new meshes must number above them
            if observe(
                f"drape/{msg.level} from {msg.solver or 'an unnamed node'}", msg.generation, msg.mesh_generation
            ):
                if msg.level in ("coarse", "fine"):
                    service.note_drape(msg.level, msg.mesh_generation, msg.x.numpy())

        def on_mesh(msg: MeshMsg) -> None:
            observe(f"mesh/{msg.level}", msg.generation, msg.mesh_generation)  # a predecessor's, after a restart

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

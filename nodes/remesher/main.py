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
from schemas import Array, DrapeMsg, EditMsg, MeshMsg, PatternMsg, PsiMsg, RejectedMsg
from schemas.convert import mesh_to_msg

log = logging.getLogger("remesher")


@dataclass
class Config:
    bus: BusConfig = field(default_factory=BusConfig)
    name: str = "remesher"
    """node name, unique in the session (liveliness key status/<name>)"""


class RemesherAdapter:
    """Wires one :class:`RemeshService` to one bus: a handler per input
    (pattern, edit, drape/*, mesh/*); the worker thread drafts, meshes and
    publishes. Separate from :func:`main` so tests can drive it with their own Node."""

    def __init__(self, node: Node, config: Config) -> None:
        self.node, self.name = node, config.name
        self.service = RemeshService()
        bus = node.bus
        self.pubs = {lv: bus.publisher(f"mesh/{lv}", MeshMsg) for lv in ("coarse", "fine")}
        self.psi_pubs = {lv: bus.publisher(f"psi/{lv}", PsiMsg) for lv in ("coarse", "fine")}
        self.rejected_pub = bus.publisher("rejected", RejectedMsg)
        self.worker = LatestWorker("remesh", on_error=node.error)
        self._queued: str | None = None
        """identity of the pattern queued and not yet started"""
        self._queued_lock = threading.Lock()
        bus.subscribe("pattern", self.on_pattern)
        bus.subscribe("edit", self.on_edit)
        bus.subscribe("drape/coarse", self.on_drape)
        bus.subscribe("drape/fine", self.on_drape)
        bus.subscribe("mesh/coarse", self.on_mesh)
        bus.subscribe("mesh/fine", self.on_mesh)

    def close(self) -> None:
        self.worker.close()

    # -- out
    def reject(self, msg: PatternMsg, element: str, reason: str) -> None:
        key = msg.identity()
        self.node.count("bad_patterns")
        self.node.error(f"pattern generation {msg.generation} (design {key}) rejected: {reason}")
        self.rejected_pub.put(
            RejectedMsg(
                node=self.name,
                generation=msg.generation,
                design_id=key,
                element=element,
                reason=reason,
                name=msg.name,
                source=msg.source,
            )
        )

    def publish(self, up: MeshUpdate) -> None:
        service = self.service
        msg = mesh_to_msg(
            up.mesh,
            generation=service.generation,
            mesh_generation=up.mesh_generation,
            design_id=service.design_id,
            fine_parent_tri=up.fine_parent_tri,
            fine_bary=up.fine_bary,
        )
        self.pubs[up.level].put(msg)

    # -- in (Zenoh threads: judge and queue)
    def on_pattern(self, msg: PatternMsg) -> None:
        key = msg.identity()
        with self._queued_lock:
            older, self._queued = self._queued, key
        if older is not None:
            # newest pattern first: the queued one is never meshed nor numbered
            self.node.count("superseded_patterns")
            log.info("pattern %s superseded by %s before it was meshed", older, key)
        self.worker.submit("pattern", lambda: self.mesh_pattern(msg))

    def on_edit(self, msg: EditMsg) -> None:
        if msg.phase != "press":
            return
        # a 3D tug drives a sloper parameter: its Ψ is dX/dg (column 0)
        element = f"param:{msg.param}" if msg.picked_vertex >= 0 and msg.param else msg.element
        if not element or self.off_design(msg):  # judged on arrival: a newer press would supersede the job
            return
        self.worker.submit("press", lambda: self.press(msg, element))

    def on_drape(self, msg: DrapeMsg) -> None:
        # a drape names its mesh too: after a restart the predecessor's meshes are gone with
        # its publisher's history, the solver's drapes are not, and new meshes must number above them
        what = f"drape/{msg.level} from {msg.solver or 'an unnamed node'}"
        if self.observe(what, msg.generation, msg.mesh_generation) and msg.level in ("coarse", "fine"):
            self.service.note_drape(msg.level, msg.mesh_generation, msg.x.numpy())

    def on_mesh(self, msg: MeshMsg) -> None:
        self.observe(f"mesh/{msg.level}", msg.generation, msg.mesh_generation)  # a predecessor's, after a restart

    # -- work (the worker thread)
    def mesh_pattern(self, msg: PatternMsg) -> None:
        service, node, key = self.service, self.node, msg.identity()
        with self._queued_lock:
            if self._queued == key:
                self._queued = None
        generation = service.next_generation(msg.generation)
        try:
            updates = service.set_design(msg.design, generation, key)
        except PatternError as e:
            self.reject(msg, e.element, str(e))
            return
        except Exception as e:  # meshing failed: still an answer, never silence
            log.exception("pattern generation %d (design %s): meshing failed", msg.generation, key)
            self.reject(msg, "", f"the remesher could not mesh this design: {type(e).__name__}: {e}")
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
            self.publish(up)
            log.info(
                "gen %d %s: %d vertices (%s, %.0f ms)",
                generation,
                up.level,
                up.mesh.n_vertices,
                up.how,
                1e3 * up.seconds,
            )
        node.count("meshes", len(updates))
        self.worker.submit("warm", service.warm_coordinates)

    def press(self, msg: EditMsg, element: str) -> None:
        service = self.service
        if self.off_design(msg):  # a pattern queued before it has been numbered since
            return
        try:
            psis = service.psi_for(element)
        except (PatternError, RuntimeError, KeyError) as e:
            self.node.error(f"edit {msg.edit_id}: no Ψ for {element!r}: {e}")
            return
        # Ψ alone: the receivers hold the meshes it lives on (the fine one first, the
        # sensitivity node's first prediction waits on it)
        for level in sorted(psis, key=lambda lv: lv != "fine"):
            self.psi_pubs[level].put(
                PsiMsg(
                    generation=service.generation,
                    level="fine" if level == "fine" else "coarse",
                    mesh_generation=service.levels[level].mesh_generation,
                    design_id=service.design_id,
                    edit_id=msg.edit_id,
                    psi=Array.from_numpy(psis[level], "float64"),
                )
            )
        self.node.count("psi")

    # -- judging numbers
    def off_design(self, msg: EditMsg) -> bool:
        """A press made on another design than the current one: logged, counted, no Ψ."""
        verdict = self.service.judge_edit(msg.generation)
        if verdict == "current":
            return False
        self.node.count(f"{verdict}_edits")
        log.warning(
            "edit %s: press on generation %d, the current design is %d (%s): no Ψ",
            msg.edit_id,
            msg.generation,
            self.service.generation,
            verdict,
        )
        return True

    def observe(self, what: str, generation: int, mesh_generation: int = 0) -> bool:
        if self.service.observe(generation, mesh_generation):
            return True
        self.node.count("foreign_generations")
        log.warning(
            "%s of generation %d ignored: above every design this remesher numbered (newest %d)",
            what,
            generation,
            self.service.generation,
        )
        return False


def main(config: Config) -> None:
    with Node(config.name, config.bus, kind="remesher") as node:
        adapter = RemesherAdapter(node, config)
        try:
            node.run()
        finally:
            adapter.close()

"""Which design each mesh was drafted from, for the nodes downstream of the remesher.

The remesher meshes a ``pattern`` and publishes ``mesh/{coarse,fine}`` with the
pattern's generation; a solver or the sensitivity node needs that pattern's
fabric and scene to build a cloth model. The two topics are independent, so a
mesh can arrive before its pattern (history delivered to a late joiner, or a
slow subscriber). :class:`MeshMatcher` holds such a mesh until its design
arrives, drops meshes older than the one already taken, and hands each mesh
out with its design exactly once. It is bus-free: the node adapters feed it
messages' contents and act on what it returns.
"""

from __future__ import annotations

import logging
import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Generic, Literal, TypeVar

from schemas.design import Design

log = logging.getLogger(__name__)

T = TypeVar("T")


class DesignLog:
    """Recent designs by pattern generation and by design_id (the newest ``keep`` of each)."""

    def __init__(self, keep: int = 16) -> None:
        self.keep = keep
        self._by_gen: dict[int, Design] = {}
        self._by_id: OrderedDict[str, Design] = OrderedDict()
        self._lock = threading.Lock()

    def add(self, generation: int, design: Design, design_id: str = "") -> None:
        with self._lock:
            self._by_gen[generation] = design
            for g in sorted(self._by_gen)[: -self.keep]:
                del self._by_gen[g]
            if design_id:
                self._by_id[design_id] = design
                self._by_id.move_to_end(design_id)
                while len(self._by_id) > self.keep:
                    self._by_id.popitem(last=False)

    def by_id(self, design_id: str) -> Design | None:
        """The design its publisher named ``design_id``, if seen."""
        with self._lock:
            return self._by_id.get(design_id)

    def exact(self, generation: int) -> Design | None:
        """The design of exactly this generation, if seen."""
        with self._lock:
            return self._by_gen.get(generation)

    def at(self, generation: int) -> Design | None:
        """The design of this generation, or else of the newest older one."""
        with self._lock:
            older = [g for g in self._by_gen if g <= generation]
            return self._by_gen[max(older)] if older else None

    @property
    def latest_generation(self) -> int:
        """The newest generation seen, 0 before any."""
        with self._lock:
            return max(self._by_gen, default=0)


@dataclass
class MeshArrival(Generic[T]):
    """A mesh as it came off the bus (``payload`` is whatever the node keeps of it)."""

    level: str
    """'coarse' or 'fine'"""
    generation: int
    """pattern generation the mesh was drafted from"""
    mesh_generation: int
    """the remesher's number for this level's mesh (bumps on every new rest shape)"""
    payload: T
    design_id: str = ""
    """design_id of the pattern the mesh was drafted from ('' when it had none)"""


@dataclass
class Matched(Generic[T]):
    """A mesh together with the design it was drafted from."""

    mesh: MeshArrival[T]
    design: Design


@dataclass
class MeshOutcome(Generic[T]):
    """What :meth:`MeshMatcher.add_mesh` did with a mesh."""

    status: Literal["matched", "parked", "stale", "repeat"]
    matched: Matched[T] | None = None
    """the mesh with its design when status is 'matched'"""


class MeshMatcher(Generic[T]):
    """Pairs meshes with their designs (see the module docstring).

    Per level it remembers the newest ``mesh_generation`` handed out; a mesh
    with the same number is a repeat (the remesher re-sends the mesh it holds
    to carry Ψ) and one with a smaller number is stale: both are dropped. A
    mesh whose design has not arrived is parked, one per level (a newer mesh
    of the level replaces it), until :meth:`add_design` brings its design, or
    a newer design shows that its own will not come (then the newest older
    design stands in, as the remesher had no other to draft from). A mesh
    that names its design's ``design_id`` gets exactly that design.
    Thread-safe.
    """

    def __init__(self, keep: int = 16) -> None:
        self.designs = DesignLog(keep)
        self._taken: dict[str, int] = {}
        self._parked: dict[str, MeshArrival[T]] = {}
        self._lock = threading.Lock()
        self.stale = 0
        """meshes dropped because a newer mesh of their level was already taken"""
        self.repeats = 0
        """meshes dropped because that very mesh was already taken"""

    def add_design(self, generation: int, design: Design, design_id: str = "") -> list[Matched[T]]:
        """Record a design (its publisher's generation and id); returns the parked meshes it releases."""
        self.designs.add(generation, design, design_id)
        out: list[Matched[T]] = []
        with self._lock:
            for level, m in list(self._parked.items()):
                d = self._design_for(m)
                if d is not None:
                    del self._parked[level]
                    self._taken[level] = m.mesh_generation
                    out.append(Matched(m, d))
        return out

    def add_mesh(self, mesh: MeshArrival[T]) -> MeshOutcome[T]:
        """Match, park or drop a mesh (see the class docstring)."""
        with self._lock:
            taken = self._taken.get(mesh.level)
            if taken is not None and mesh.mesh_generation <= taken:
                if mesh.mesh_generation == taken:
                    self.repeats += 1
                    return MeshOutcome("repeat")
                self.stale += 1
                log.info("mesh/%s %d dropped: mesh %d already taken", mesh.level, mesh.mesh_generation, taken)
                return MeshOutcome("stale")
            parked = self._parked.get(mesh.level)
            if parked is not None and mesh.mesh_generation < parked.mesh_generation:
                self.stale += 1
                return MeshOutcome("stale")
            d = self._design_for(mesh)
            if d is None:
                log.info("mesh/%s of generation %d arrived before its pattern; parked", mesh.level, mesh.generation)
                self._parked[mesh.level] = mesh
                return MeshOutcome("parked")
            self._parked.pop(mesh.level, None)
            self._taken[mesh.level] = mesh.mesh_generation
            return MeshOutcome("matched", Matched(mesh, d))

    def parked(self) -> list[MeshArrival[T]]:
        """Meshes waiting for their design, oldest level first."""
        with self._lock:
            return list(self._parked.values())

    def _design_for(self, mesh: MeshArrival[T]) -> Design | None:
        if mesh.design_id:  # the remesher may have numbered it apart from what its publisher asked
            return self.designs.by_id(mesh.design_id)
        generation = mesh.generation
        exact = self.designs.exact(generation)
        if exact is not None:
            return exact
        if self.designs.latest_generation > generation:
            return self.designs.at(generation)
        return None


class OwnDesigns:
    """A publisher's own designs and the generations the remesher gave them.

    A publisher asks for a generation (``PatternMsg.generation``) and names
    its design with a unique ``design_id``; the remesher's meshes carry the
    generation it actually gave, with that id. Waiting for the drape of
    exactly one's own design means waiting for that generation.
    """

    def __init__(self, keep: int = 256) -> None:
        self.keep = keep
        self._design_of: OrderedDict[int, str] = OrderedDict()
        """generation asked for -> design_id of the newest own design that asked for it"""
        self._given: dict[str, int] = {}
        """design_id -> generation given"""
        self._lock = threading.Lock()

    def add(self, design_id: str, requested: int) -> None:
        with self._lock:
            old = self._design_of.pop(requested, None)
            if old is not None:
                self._given.pop(old, None)
            self._design_of[requested] = design_id
            while len(self._design_of) > self.keep:
                _, d = self._design_of.popitem(last=False)
                self._given.pop(d, None)

    def meshed(self, design_id: str, generation: int) -> bool:
        """A mesh of ``design_id`` with the remesher's ``generation``; True if the design is ours."""
        with self._lock:
            if design_id not in self._design_of.values():
                return False
            self._given[design_id] = generation
            return True

    def is_own(self, requested: int) -> bool:
        with self._lock:
            return requested in self._design_of

    def given(self, requested: int) -> int | None:
        """The generation the remesher gave our newest design that asked for
        ``requested`` (None until one of its meshes has been seen)."""
        with self._lock:
            d = self._design_of.get(requested)
            return None if d is None else self._given.get(d)

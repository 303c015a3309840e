"""Design identity, and which design each mesh was drafted from.

Identity. Every design passes through the remesher, which numbers the
session's designs (:meth:`couture.remesh.service.RemeshService.next_generation`):
its number, the *generation*, is what meshes, drapes and edits carry, unique
and increasing in the session. A publisher names its design with a
``design_id`` (a uuid; :meth:`schemas.messages.PatternMsg.identity` for one
without) and only asks for a number; the remesher's meshes echo the id with
the number it gave, which is how a publisher learns it (:class:`OwnDesigns`,
:class:`ShownDesign`). A message whose generation is not the current design's
is judged with :func:`judge` (stale: an older design's; foreign: a number the
remesher has not given) and rejected by its receiver with a log line naming
both numbers and a status count.

Matching. The remesher meshes a ``pattern`` and publishes ``mesh/{coarse,fine}``
with the generation it gave and the pattern's identity; a solver or the
sensitivity node needs that pattern's fabric and scene to build a cloth model.
The two topics are independent, so a mesh can arrive before its pattern
(history delivered to a late joiner, or a slow subscriber). :class:`MeshMatcher`
holds such a mesh until its design arrives, drops meshes older than the one
already taken, and hands each mesh out with its design exactly once. All of
it is bus-free: the node adapters feed it messages' contents and act on what
it returns.
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

GENERATION_LIMIT = 2**53
"""No design is numbered at or above this (JSON and JavaScript integers are
exact below it, and msgpack's int64 never overflows); a generation seen at or
above it is foreign wherever it comes from."""

MAX_AHEAD = 64
"""How far above the session's newest generation the remesher grants the
number a publisher asks for: a UI commits several designs while the remesher
is busy (all but the newest are superseded) and a replay re-sends a session
whose rejected designs left gaps. A request further ahead (a hostile 1000 or
2**62 early in a session) gets the next number instead, so numbers stay dense
and no request can push the count towards the limit."""

Verdict = Literal["current", "stale", "foreign"]


def judge(generation: int, current: int) -> Verdict:
    """Where a message's ``generation`` stands against the ``current`` design's
    (both the remesher's numbers): 'stale' is an older design's, 'foreign' one
    the receiver has not seen numbered (from another session, a rogue
    publisher, or not yet here)."""
    if generation == current:
        return "current"
    return "stale" if generation < current else "foreign"


class DesignLog:
    """Recent designs by identity and, for meshes that name none, by generation (the newest ``keep`` of each)."""

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
        """The design published with exactly this generation, if seen."""
        with self._lock:
            return self._by_gen.get(generation)


@dataclass
class MeshArrival(Generic[T]):
    """A mesh as it came off the bus (``payload`` is whatever the node keeps of it)."""

    level: str
    """'coarse' or 'fine'"""
    generation: int
    """the remesher's number for the design the mesh was drafted from"""
    mesh_generation: int
    """the remesher's number for this level's mesh (bumps on every new rest shape)"""
    payload: T
    design_id: str = ""
    """identity of the pattern the mesh was drafted from ('' from a remesher that named none)"""


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
    of the level replaces it), until :meth:`add_design` brings its design. A
    mesh gets exactly the design its ``design_id`` names (one that names none,
    from an older remesher, the design published with its generation): never
    a stand-in, whose fabric would give a wrong drape. A matched mesh its
    receiver cannot use (a fabric outside its physical range) is handed back
    with :meth:`refuse`, so that it does not count as taken. Thread-safe.
    """

    def __init__(self, keep: int = 16) -> None:
        self.designs = DesignLog(keep)
        self._taken: dict[str, int] = {}
        self._taken_gen: dict[str, int] = {}
        """level -> the generation of the mesh taken"""
        self._before: dict[str, tuple[int, int] | None] = {}
        """level -> (mesh_generation, generation) taken before its last take, for :meth:`refuse`"""
        self._parked: dict[str, MeshArrival[T]] = {}
        self._lock = threading.Lock()
        self.stale = 0
        """meshes dropped because a newer mesh of their level was already taken"""
        self.repeats = 0
        """meshes dropped because that very mesh was already taken"""
        self.newest = -1
        """the newest generation (the remesher's number) among the meshes handed out, -1 before any"""

    def add_design(self, generation: int, design: Design, design_id: str = "") -> list[Matched[T]]:
        """Record a design (the generation its publisher asked for, its identity);
        returns the parked meshes it releases."""
        self.designs.add(generation, design, design_id)
        out: list[Matched[T]] = []
        with self._lock:
            for level, m in list(self._parked.items()):
                d = self._design_for(m)
                if d is not None:
                    del self._parked[level]
                    out.append(self._take(m, d))
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
                log.info(
                    "mesh/%s %d dropped: mesh %d already waits for its design",
                    mesh.level,
                    mesh.mesh_generation,
                    parked.mesh_generation,
                )
                return MeshOutcome("stale")
            d = self._design_for(mesh)
            if d is None:
                log.info(
                    "mesh/%s of generation %d (design %s) arrived before its pattern; parked",
                    mesh.level,
                    mesh.generation,
                    mesh.design_id or "unnamed",
                )
                self._parked[mesh.level] = mesh
                return MeshOutcome("parked")
            self._parked.pop(mesh.level, None)
            return MeshOutcome("matched", self._take(mesh, d))

    def refuse(self, mesh: MeshArrival[T]) -> None:
        """A mesh handed out that its receiver refused (nothing adopted): as if
        it had never been taken, so that a refused mesh numbered above the
        remesher's (one sent past it) cannot make the next good meshes stale."""
        with self._lock:
            if self._taken.get(mesh.level) != mesh.mesh_generation or mesh.level not in self._before:
                return
            before = self._before.pop(mesh.level)
            if before is None:
                del self._taken[mesh.level], self._taken_gen[mesh.level]
            else:
                self._taken[mesh.level], self._taken_gen[mesh.level] = before
            self.newest = max(self._taken_gen.values(), default=-1)

    def parked(self) -> list[MeshArrival[T]]:
        """Meshes waiting for their design, oldest level first."""
        with self._lock:
            return list(self._parked.values())

    def _take(self, mesh: MeshArrival[T], design: Design) -> Matched[T]:
        level = mesh.level
        self._before[level] = (self._taken[level], self._taken_gen[level]) if level in self._taken else None
        self._taken[level], self._taken_gen[level] = mesh.mesh_generation, mesh.generation
        self.newest = max(self.newest, mesh.generation)
        return Matched(mesh, design)

    def _design_for(self, mesh: MeshArrival[T]) -> Design | None:
        if mesh.design_id:  # the remesher may have numbered it apart from what its publisher asked
            return self.designs.by_id(mesh.design_id)
        return self.designs.exact(mesh.generation)


class OwnDesigns:
    """A publisher's own designs and the generations the remesher gave them.

    A publisher asks for a generation (``PatternMsg.generation``) and names
    its design with a unique ``design_id``; the remesher's meshes carry the
    generation it actually gave, with that id. Waiting for the drape of
    exactly one's own design means waiting for that generation. The first
    mesh that names a design decides its number: a later one naming the same
    id (a re-sent or forged pattern, numbered again) is someone else's design.
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
        """A mesh of ``design_id`` with the remesher's ``generation``; True if it
        numbers one of our designs (the first number given to it stays)."""
        with self._lock:
            if design_id not in self._design_of.values():
                return False
            given = self._given.setdefault(design_id, generation)
            if given != generation:
                log.warning(
                    "design %s numbered %d again as %d (re-sent or forged): %d stays ours",
                    design_id,
                    given,
                    generation,
                    given,
                )
                return False
            return True

    def is_own(self, requested: int) -> bool:
        with self._lock:
            return requested in self._design_of

    def design_of(self, requested: int) -> str | None:
        """design_id of our newest design that asked for ``requested``."""
        with self._lock:
            return self._design_of.get(requested)

    def given(self, requested: int) -> int | None:
        """The generation the remesher gave our newest design that asked for
        ``requested`` (None until one of its meshes has been seen)."""
        with self._lock:
            d = self._design_of.get(requested)
            return None if d is None else self._given.get(d)


class ShownDesign:
    """Which design a participant that shows the session's design (the UI)
    should show, and the numbers it knows, learnt from the remesher's meshes.

    The participant commits designs of its own (shown at once, optimistically)
    and sees other publishers' patterns (a script, a replay, the sensitivity
    node's 3D tug). Another publisher's design is adopted only once the
    remesher has numbered it (a design it rejects never shows) and only when
    it is newer than what is shown: numbered above it, and arrived after this
    participant's own newest commit. Its edits then carry the number the
    remesher gave the design on screen (:meth:`edit_generation`). Not
    thread-safe: the adapter calls it under its own lock.
    """

    def __init__(self, keep: int = 64) -> None:
        self.keep = keep
        self.top = 0
        """the newest generation the remesher gave (seen on a mesh), 0 before any"""
        self.asked = 0
        """the newest generation this participant asked for"""
        self.shown_id = ""
        """identity of the design shown ('' before any)"""
        self._given: OrderedDict[str, int] = OrderedDict()
        """design identity -> generation the remesher gave it (first mesh wins)"""
        self._own: OrderedDict[str, None] = OrderedDict()
        self._foreign: OrderedDict[str, tuple[int, Design]] = OrderedDict()
        """another publisher's design identity -> (arrival tick, design), until adopted"""
        self._tick = 0
        self._commit_tick = 0

    def request(self) -> int:
        """The generation to ask for with the next own design (one above every number known)."""
        self.asked = max(self.asked, self.top) + 1
        return self.asked

    def committed(self, design_id: str) -> None:
        """An own design, published under ``design_id``, is now shown."""
        self._tick += 1
        self._commit_tick = self._tick
        self._own[design_id] = None
        _trim(self._own, self.keep)
        self.shown_id = design_id

    @property
    def shown_generation(self) -> int | None:
        """The remesher's number for the design shown (None until its mesh arrived)."""
        return self._given.get(self.shown_id)

    def edit_generation(self) -> int:
        """The generation an edit of the design shown carries: its number, or
        before the remesher gave one the newest number known (the remesher's
        design, on which its Ψ would be computed: a receiver that holds a newer
        one rejects the edit as stale)."""
        g = self.shown_generation
        return self.top if g is None else g

    def pattern(self, design_id: str, design: Design) -> Design | None:
        """Another publisher's pattern arrived; returns the design to show now, if any."""
        if design_id in self._own:
            return None
        self._tick += 1
        self._foreign[design_id] = (self._tick, design)
        _trim(self._foreign, self.keep)
        return self._adopt(design_id)

    def meshed(self, design_id: str, generation: int) -> tuple[bool, Design | None]:
        """A mesh of ``design_id`` numbered ``generation``: (whether the number
        was accepted, the design to show now if any). A number at or above
        :data:`GENERATION_LIMIT` is foreign and not accepted."""
        if generation >= GENERATION_LIMIT:
            return False, None
        self.top = max(self.top, generation)
        if design_id:
            self._given.setdefault(design_id, generation)
            self._given.move_to_end(design_id)
            _trim(self._given, self.keep)
        return True, self._adopt(design_id)

    def _adopt(self, design_id: str) -> Design | None:
        entry = self._foreign.get(design_id)
        given = self._given.get(design_id)
        if entry is None or given is None:
            return None
        tick, design = entry
        shown = self.shown_generation
        if tick < self._commit_tick or (shown is not None and given <= shown):
            return None
        del self._foreign[design_id]
        self.shown_id = design_id
        return design


def _trim(d: OrderedDict, keep: int) -> None:
    while len(d) > keep:
        d.popitem(last=False)

"""The remesher's state machine, free of bus code (nodes/remesher adapts it).

Given successive designs it keeps one mesh per level and decides, per SC §6,
how to carry it forward:

- same drafted structure (same panels and polyline vertex counts): the *same*
  mesh follows the pattern (boundary on the new polylines, interior by PMVC),
  so vertices, per-vertex state and warm starts survive; then Delaunay flips
  if quality dropped; a full remesh only if quality stays below the threshold,
  with the 3D state carried over by barycentric interpolation in 2D;
- otherwise a new mesh.

It also answers a press with Ψ for the edited element on both levels, and
owns the coarse -> fine prolongation map.

It numbers the designs of its session (:meth:`RemeshService.next_generation`):
every design passes through the remesher, so its numbers are the generations
that meshes, drapes and edits carry, unique and increasing whatever publishers
ask for (:mod:`couture.designs`).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from couture.designs import GENERATION_LIMIT, MAX_AHEAD, Verdict, judge
from couture.mesh import GarmentMesh
from couture.pattern.drafted import DraftedPattern
from couture.pattern.edit import edit_jacobian
from couture.pattern.validate import validate
from couture.remesh.meshing import RemeshResult, _place, mesh_pattern
from couture.remesh.psi import PsiCoordinates, build_coordinates, follow_pattern, psi
from couture.remesh.quality import improve
from couture.remesh.transfer import prolongation, transfer_state
from schemas.design import Design

log = logging.getLogger(__name__)

LEVELS = ("coarse", "fine")


def structure_key(drafted: DraftedPattern) -> tuple:
    """What must stay equal for a mesh to follow a pattern edit."""
    return tuple((p.name, len(p.outline), tuple(len(h) for h in p.holes)) for p in drafted.panels) + tuple(
        (s.a_panel, s.a_segment, s.b_panel, s.b_segment) for s in drafted.seams
    )


@dataclass
class LevelState:
    result: RemeshResult
    mesh: GarmentMesh
    mesh_generation: int
    target: int
    coords: PsiCoordinates | None = None
    last_x: np.ndarray | None = None
    """latest drape on this mesh (for state transfer), shape (n, 3)"""


@dataclass
class MeshUpdate:
    level: str
    mesh: GarmentMesh
    mesh_generation: int
    how: str
    """'new', 'followed', 'flipped', 'remeshed'"""
    fine_parent_tri: np.ndarray | None = None
    fine_bary: np.ndarray | None = None
    seconds: float = 0.0


@dataclass
class RemeshService:
    levels: dict[str, LevelState] = field(default_factory=dict)
    fine_prolongation: tuple[np.ndarray, np.ndarray] | None = None
    """the current fine mesh located in the coarse one (parent triangle, barycentrics):
    re-sent with Ψ, so a solver that joins late (a restarted one) prolongs as the others did"""
    design: Design | None = None
    drafted: DraftedPattern | None = None
    key: tuple | None = None
    generation: int = -1
    """generation of the current design (-1 before the first)"""
    design_id: str = ""
    """the current design's identity (``PatternMsg.identity()``)"""
    seen_generation: int = 0
    """highest generation seen on the bus before this remesher numbered its
    first design (a restarted remesher numbers above its predecessor's)"""
    _mesh_gen: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def _next_mesh_gen(self) -> int:
        self._mesh_gen += 1
        return self._mesh_gen

    def next_generation(self, requested: int) -> int:
        """The generation a newly received design gets: the one its publisher
        asks for when it is above every number of the session and at most
        :data:`~couture.designs.MAX_AHEAD` above, else one more than the
        highest (a client that starts late or restarts, or two clients at
        once, cannot reuse a number, and a huge one cannot move the count).
        Call :meth:`set_design` with it; a design that fails validation
        leaves its number unused."""
        with self._lock:
            top = max(self.generation, self.seen_generation, 0)
        if top < requested <= top + MAX_AHEAD and requested < GENERATION_LIMIT:
            return requested
        return top + 1

    @staticmethod
    def request_verdict(requested: int, given: int) -> Literal["granted", "stale", "foreign"]:
        """What a publisher's request was, against the number given: granted,
        stale (a number already used: the publisher is behind), or foreign (a
        number too far ahead: another session's, or hostile)."""
        if requested == given:
            return "granted"
        return "stale" if requested < given else "foreign"

    def observe(self, generation: int, mesh_generation: int = 0) -> bool:
        """Numbers seen on the bus (meshes and drapes of this session): before
        this remesher has numbered a design they are its predecessor's (after
        a restart), and later designs and meshes are numbered above them, so
        downstream nodes never take a new mesh for a stale one. Once it
        numbers designs itself a generation above its own is foreign (a rogue
        publisher, another session's): not taken, returns False."""
        with self._lock:
            if generation >= GENERATION_LIMIT or (self.generation >= 0 and generation > self.generation):
                return False
            if self.generation < 0:
                self.seen_generation = max(self.seen_generation, generation)
                self._mesh_gen = max(self._mesh_gen, mesh_generation)
            return True

    def judge_edit(self, generation: int) -> Verdict:
        """Whether an edit made on the design of ``generation`` is on the current design."""
        with self._lock:
            return judge(generation, self.generation)

    def set_design(self, design: Design, generation: int, design_id: str = "") -> list[MeshUpdate]:
        """Draft, validate and mesh a design; raises PatternError naming the bad element."""
        drafted = validate(design)
        key = structure_key(drafted)
        targets = {"coarse": design.resolution.coarse_vertices, "fine": design.resolution.fine_vertices}
        updates: list[MeshUpdate] = []
        with self._lock:
            for level in LEVELS:
                t0 = time.perf_counter()
                st = self.levels.get(level)
                if st is not None and key == self.key and st.target == targets[level]:
                    up = self._follow(level, st, drafted, generation)
                else:
                    up = self._new(level, drafted, targets[level], generation)
                up.seconds = time.perf_counter() - t0
                updates.append(up)
            coarse, fine = self.levels["coarse"], self.levels["fine"]
            parent, bary = prolongation(coarse.mesh, fine.mesh)
            updates[1].fine_parent_tri, updates[1].fine_bary = parent, bary
            self.fine_prolongation = (parent, bary)
            self.design, self.drafted, self.key, self.generation = design, drafted, key, generation
            self.design_id = design_id
        return updates

    def _new(self, level: str, drafted: DraftedPattern, target: int, generation: int) -> MeshUpdate:
        res = mesh_pattern(drafted, target, level=level, generation=generation)
        st = LevelState(result=res, mesh=res.mesh, mesh_generation=self._next_mesh_gen(), target=target)
        self.levels[level] = st
        return MeshUpdate(level, st.mesh, st.mesh_generation, "new")

    def _coords(self, st: LevelState) -> PsiCoordinates:
        if st.coords is None:
            st.coords = build_coordinates(st.result, "pmvc")
        return st.coords

    def _follow(self, level: str, st: LevelState, drafted: DraftedPattern, generation: int) -> MeshUpdate:
        X = follow_pattern(self._coords(st), drafted)
        tris, report = improve(X, st.mesh.tris)
        old = st.mesh
        if report.needs_remesh:
            log.info("%s: quality %.3f after flips, remeshing", level, report.min_quality)
            up = self._new(level, drafted, st.target, generation)
            if st.last_x is not None:
                new = up.mesh
                new.x0 = transfer_state(
                    old.X,
                    old.tris,
                    st.last_x,
                    new.X,
                    old_tri_panel=old.tri_panel,
                    new_vertex_panel=self.levels[level].result.vertex_panel,
                )
            up.how = "remeshed"
            return up
        x0 = st.last_x if st.last_x is not None else _place(drafted, X, st.result.vertex_panel)
        mesh = GarmentMesh(
            X=X,
            tris=tris,
            x0=x0,
            tri_panel=old.tri_panel,
            panel_names=old.panel_names,
            # a followed edit may turn a panel's grain (the names and order stay)
            panel_grain=np.array([p.grain for p in drafted.panels], dtype=np.float64),
            seam_emitters=old.seam_emitters,
            seam_edges=old.seam_edges,
            seam_weights=old.seam_weights,
            pinned=old.pinned,
            level=level,
            generation=generation,
        )
        changed_topology = not np.array_equal(tris, old.tris)
        st.mesh = mesh
        st.result.mesh = mesh
        # rest shape changed either way: a new mesh generation (vertex identity is kept)
        st.mesh_generation = self._next_mesh_gen()
        return MeshUpdate(level, mesh, st.mesh_generation, "flipped" if changed_topology else "followed")

    def note_drape(self, level: str, mesh_generation: int, x: np.ndarray) -> None:
        """Remember the latest 3D state of a level's current mesh (for transfer)."""
        with self._lock:
            st = self.levels.get(level)
            if st is not None and st.mesh_generation == mesh_generation and x.shape == st.mesh.x0.shape:
                st.last_x = np.array(x, dtype=np.float64)

    def psi_for(self, element: str) -> dict[str, np.ndarray]:
        """Ψ (n, 2, 2) per level for a press on ``element`` of the current design."""
        with self._lock:
            if self.design is None:
                raise RuntimeError("no design yet: publish a pattern before editing")
            jac = edit_jacobian(self.design, element)
            return {level: psi(self._coords(st), jac) for level, st in self.levels.items()}

    def warm_coordinates(self) -> None:
        """Precompute PMVC coordinates (idle time), so the next press is fast."""
        for st in list(self.levels.values()):
            with self._lock:
                self._coords(st)

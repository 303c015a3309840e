"""The UI's two background threads, each draining a latest-value slot, so
that bus callbacks only store and return:

- :class:`DrapeRenderer`: the newest drape to the 3D view, at most
  ``max_fps`` times a second (a burst of predictions costs one render), and
  the status text twice a second or when it changed;
- :class:`Drafter`: the newest design drafted with couture.pattern for the
  pattern view, then its handles planned (skipped when a newer design waits).
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Callable, Iterable

from couture.mesh import GarmentMesh
from couture.pattern import draft
from couture.pattern.drafted import DraftedPattern
from couture.ui.controls import Controls
from couture.ui.drape_view import DrapeView
from couture.ui.handles import HandleSet, plan_handles
from couture.ui.state import DrapeFrame, LatestSlot
from couture.ui.status import StatusPanel
from schemas.design import Design

log = logging.getLogger("couture.ui")


class DrapeRenderer:
    def __init__(
        self,
        view3d: DrapeView,
        status: StatusPanel,
        controls: Controls,
        *,
        meshes: Callable[[], Iterable[GarmentMesh]],
        selected_solver: Callable[[], str],
        max_fps: float,
    ):
        self.view3d, self.status, self.controls = view3d, status, controls
        self.meshes, self.selected_solver = meshes, selected_solver
        self.min_dt = 1.0 / max(max_fps, 1.0)
        self.slot: LatestSlot[DrapeFrame] = LatestSlot()
        self.on_screen: DrapeFrame | None = None
        self.frames_pushed = 0
        self.on_pushed: Callable[[DrapeFrame], None] | None = None
        """called (on this thread) after each drape reached the view"""
        self.waiting: DrapeFrame | None = None
        """the newest drape whose mesh had not arrived when it was taken: shown
        once that mesh is here, unless a drape that supersedes it was shown
        first (any but a coarse drape of its own design under a held fine one; a late joiner
        gets the session's meshes and drapes on separate subscriptions, in any
        order, and a finished solve sends no other drape)"""

    def run(self, stop: threading.Event) -> None:
        last_push = 0.0
        last_status = 0.0
        while not stop.is_set():
            frame = self.slot.take(timeout=0.05)
            if frame is None and self.waiting is not None and self._mesh_for(self.waiting) is not None:
                frame, self.waiting = self.waiting, None
            if frame is not None:
                wait = last_push + self.min_dt - time.perf_counter()
                if wait > 0:
                    time.sleep(wait)
                    frame = self.slot.take() or frame
                try:
                    self.push(frame)
                except Exception:
                    log.exception("drawing a drape failed")
                last_push = time.perf_counter()
            now = time.perf_counter()
            if self.status.dirty.is_set() or now - last_status > 0.5:
                self.status.dirty.clear()
                last_status = now
                try:
                    self.controls.show_solvers(self.status.live_solvers(), self.selected_solver())
                    self.status.refresh(self.on_screen)
                except Exception:
                    log.exception("status refresh failed")

    def _mesh_for(self, frame: DrapeFrame) -> GarmentMesh | None:
        n = len(frame.x)
        if self.view3d.mesh is not None and self.view3d.mesh.n_vertices == n:
            return self.view3d.mesh
        return next((m for m in self.meshes() if m.n_vertices == n), None)

    def push(self, frame: DrapeFrame) -> None:
        mesh = self._mesh_for(frame)
        if mesh is None:
            self.waiting = frame  # a drape for a mesh we do not have yet: shown when it comes
            return
        if mesh is not self.view3d.mesh:
            self.view3d.set_mesh(mesh)
        self.view3d.set_x(frame.x)
        w = self.waiting
        if w is not None and not (w.level == "fine" and frame.level == "coarse" and w.generation >= frame.generation):
            self.waiting = None  # superseded; a held fine drape outlives its own design's coarse one
        self.on_screen = frame
        self.frames_pushed += 1
        self.status.show_frame(frame, self.frames_pushed)
        self.controls.show_legend(self.view3d.scale)
        if self.on_pushed is not None:
            self.on_pushed(frame)


class Drafter:
    def __init__(
        self,
        *,
        show_pattern: Callable[[DraftedPattern], None],
        pattern: Callable[[], DraftedPattern | None],
        show_handles: Callable[[Design, HandleSet], None],
    ):
        self.show_pattern, self.pattern, self.show_handles = show_pattern, pattern, show_handles
        self.slot: LatestSlot[Design] = LatestSlot()

    def run(self, stop: threading.Event) -> None:
        while not stop.is_set():
            design = self.slot.take(timeout=0.1)
            if design is None:
                continue
            try:
                pattern = draft(design)
            except Exception as e:
                log.warning("drafting the design failed: %s", e)
                continue
            self.show_pattern(pattern)
            if self.slot.peek() is not design:
                continue  # a newer design is waiting: plan its handles instead
            try:
                handle_set = plan_handles(design, pattern)
            except Exception:
                log.exception("planning the pattern handles failed")
                continue
            if self.slot.peek() is design and self.pattern() is pattern:
                self.show_handles(design, handle_set)

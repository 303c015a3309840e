"""Drag-to-edit: a handle dragged in the pattern view, or the drape tugged in
the 3D view, becomes a typed :class:`Edit` per phase (press, drag, release).

A handle's release commits ``couture.pattern.apply_edit(design, element, d)``
as one new design. A 3D tug commits nothing here: the sensitivity node maps
the screen drag to a sloper option and publishes the design it gives.
"""

from __future__ import annotations

import logging
import uuid
from dataclasses import dataclass
from typing import Callable

import numpy as np

from couture import pattern as pattern_model
from couture.ui.geometry import CameraState, MaterialPoint
from couture.ui.handles import Handle
from couture.ui.state import Phase
from schemas.design import Design

log = logging.getLogger("couture.ui")


@dataclass(frozen=True)
class ScreenPick:
    """Where a 3D tug grabbed the cloth, and the camera it was seen through."""

    vertex: int
    """fine-mesh vertex nearest the pick"""
    tri: int
    bary: np.ndarray
    """barycentric coordinates in ``tri``, shape (3,), float64"""
    view_proj: np.ndarray | None = None
    """OpenGL view-projection (world [m] -> clip), shape (4, 4); None if the camera was unknown"""
    viewport_px: tuple[int, int] | None = None
    """viewport (width, height) [px]"""


@dataclass(frozen=True)
class Edit:
    """One phase of a drag (the ``edit`` message's content, less the bus fields)."""

    edit_id: str
    """shared by the press, drags and release of one gesture"""
    phase: Phase
    element: str
    """couture.pattern element id ('param:length', 'cv:gore0:hem:0', ...); '' for a tug driving nothing"""
    dofs: tuple[str, ...]
    """the element's degrees of freedom the drag moves"""
    d: np.ndarray
    """since press: the element's d (handle drag: [m] or the option change), or [px] on screen (tug); shape (2,)"""
    param: str = ""
    """sloper option driven ('' for a stroke element)"""
    pick: ScreenPick | None = None
    """set for a 3D tug"""


class Gestures:
    """Turns drags into edits; hands them to ``on_edit``."""

    def __init__(
        self,
        design: Callable[[], Design],
        commit: Callable[[Design], None],
        *,
        restore_pattern: Callable[[], None],
        say: Callable[[str], None],
        tug_option: Callable[[], str],
        on_edit: Callable[[Edit], object],
    ):
        self.design, self.commit = design, commit
        self.restore_pattern, self.say, self.tug_option = restore_pattern, say, tug_option
        self.on_edit = on_edit
        self._edit_id = ""

    def _begin(self, phase: Phase) -> str:
        if phase == "press" or not self._edit_id:
            self._edit_id = uuid.uuid4().hex[:12]
        return self._edit_id

    def _emit(self, edit: Edit) -> None:
        try:
            self.on_edit(edit)
        except Exception:
            log.exception("handing an edit on failed")

    def handle_drag(self, phase: Phase, handle: Handle, d: np.ndarray) -> None:
        """A handle drag; ``d`` is already in the element's convention (Handle.element_delta)."""
        edit_id = self._begin(phase)
        d = np.asarray(d, np.float64).reshape(2)
        param = handle.element.split(":", 1)[1] if handle.kind == "param" else ""
        self._emit(Edit(edit_id, phase, handle.element, (param,) if param else ("x", "y"), d.copy(), param))
        if phase != "release":
            return
        if not np.any(d):
            self.restore_pattern()  # nothing moved: the outline goes back
            return
        try:
            new = pattern_model.apply_edit(self.design(), handle.element, d)
        except Exception as e:  # e.g. a value outside the option's range
            log.warning("edit %s by %s rejected: %s", handle.element, d, e)
            self.say(f"**Edit rejected**: {e}")
            self.restore_pattern()
            return
        self.commit(new)

    def tug(
        self,
        phase: Phase,
        mp: MaterialPoint,
        vertex: int,
        p0: tuple[float, float],
        p: tuple[float, float],
        cam: CameraState | None,
    ) -> None:
        """A drag on the drape: screen pixels since press, with the pick and the camera."""
        edit_id = self._begin(phase)
        param = self.tug_option()
        pick = ScreenPick(
            int(vertex),
            int(mp.tri),
            np.asarray(mp.bary, np.float64).copy(),
            cam.view_proj_gl() if cam is not None else None,
            (cam.width, cam.height) if cam is not None else None,
        )
        self._emit(
            Edit(
                edit_id,
                phase,
                f"param:{param}" if param else "",
                (param,) if param else (),
                np.array([p[0] - p0[0], p[1] - p0[1]], np.float64),
                param,
                pick,
            )
        )

"""The "Session" folder of the 3D server's panel: the record toggle and the
exports, the pattern (DXF, SVG, PDF at true scale) and the drape (OBJ, glTF
binary), written to a folder and offered to the browser as a download.

Pattern files come from couture.pattern.io (AAMA-style DXF, SVG and PDF at
true scale); an exporter's error is shown on the panel, the UI keeps running.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Callable

import numpy as np
import viser

from couture.mesh import GarmentMesh
from couture.pattern.drafted import DraftedPattern
from couture.ui.widgets import on_user_change

log = logging.getLogger("couture.ui")

PATTERN_FORMATS = ("dxf", "svg", "pdf")
DRAPE_FORMATS = ("obj", "glb")


def export_pattern(pattern: DraftedPattern, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in PATTERN_FORMATS:
        raise ValueError(f"pattern export: unknown format {fmt!r}; choose from {PATTERN_FORMATS}")
    from couture.pattern import io as pattern_io

    getattr(pattern_io, f"export_{fmt}")(pattern, path)
    return path


def export_drape(mesh: GarmentMesh, x: np.ndarray, path: Path) -> Path:
    """The drape as a triangle mesh [m], y up, with the pattern coordinates
    [m] as texture coordinates (so strain or a print can be mapped back)."""
    import trimesh

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    visual = trimesh.visual.TextureVisuals(uv=np.asarray(mesh.X))
    m = trimesh.Trimesh(vertices=np.asarray(x), faces=mesh.tris, visual=visual, process=False)
    m.export(path)
    return path


class SessionPanel:
    """Record toggle and export buttons. ``pattern`` and ``drape`` return what
    is on screen now (None while there is nothing)."""

    def __init__(
        self,
        gui: viser.GuiApi,
        export_dir: Path,
        *,
        pattern: Callable[[], DraftedPattern | None],
        drape: Callable[[], tuple[GarmentMesh | None, np.ndarray | None]],
        on_record: Callable[[bool], object],
    ):
        self.export_dir = Path(export_dir)
        self.pattern, self.drape, self.on_record = pattern, drape, on_record
        with gui.add_folder("Session", expand_by_default=False):
            self.record = gui.add_checkbox("record", False)
            on_user_change(self.record, lambda: self._record(bool(self.record.value)))
            self.record_note = gui.add_markdown("")
            self.pattern_buttons = gui.add_button_group("export pattern", PATTERN_FORMATS)
            self.pattern_buttons.on_click(self._pattern_clicked)
            self.drape_buttons = gui.add_button_group("export drape", DRAPE_FORMATS)
            self.drape_buttons.on_click(self._drape_clicked)
            self.note = gui.add_markdown("")

    def _pattern_clicked(self, event: viser.GuiEvent) -> None:
        self.export_pattern(str(event.target.value), event.client)

    def _drape_clicked(self, event: viser.GuiEvent) -> None:
        self.export_drape(str(event.target.value), event.client)

    def _record(self, on: bool) -> None:
        try:
            self.on_record(on)
        except Exception:
            log.exception("the record toggle failed")

    def show_record(self, text: str, on: bool | None = None) -> None:
        """What the record toggle did (file path, or why not); ``on`` moves the toggle."""
        self.record_note.content = text
        if on is not None:
            self.record.value = on  # type: ignore[misc]  # viser has the setter; mypy misses it

    def export_pattern(self, fmt: str, client: viser.ClientHandle | None = None) -> Path | None:
        pattern = self.pattern()
        if pattern is None:
            self.note.content = "no pattern to export yet"
            return None
        try:
            path = export_pattern(pattern, self.export_dir / f"pattern.{fmt}")
        except Exception as e:
            self.note.content = f"pattern export to {fmt} failed: {type(e).__name__}: {e}"
            return None
        self._offer(path, client)
        return path

    def export_drape(self, fmt: str, client: viser.ClientHandle | None = None) -> Path | None:
        mesh, x = self.drape()
        if mesh is None or x is None:
            self.note.content = "no drape to export yet"
            return None
        path = export_drape(mesh, x, self.export_dir / f"drape.{fmt}")
        self._offer(path, client)
        return path

    def _offer(self, path: Path, client: viser.ClientHandle | None) -> None:
        self.note.content = f"wrote `{path}`"
        if client is not None:
            client.send_file_download(path.name, path.read_bytes())

"""Exports offered by the UI: the pattern (DXF, SVG, PDF at true scale) and
the drape (OBJ, glTF binary).

Pattern files come from couture.pattern.io (AAMA-style DXF, SVG and PDF at
true scale); an exporter's error reaches the caller, which shows it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from couture.mesh import GarmentMesh
from couture.pattern.drafted import DraftedPattern

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

"""Exports offered by the UI: the pattern (DXF, SVG, PDF at true scale) and
the drape (OBJ, glTF binary).

Pattern files come from couture.pattern's exporters when it has them
(``export_dxf/export_svg/export_pdf(drafted, path)``); until then, and for
any format it lacks, the small writers below keep the buttons working: DXF as
one closed polyline per panel on layer '1' (AAMA/ASTM cut line) with seam
segments on layer '14' (sew line) and the panel name as text, SVG and PDF at
1 unit = 1 mm.
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
    try:
        import couture.pattern as cp

        fn = getattr(cp, f"export_{fmt}", None)
        if fn is None:
            from couture.pattern import io as cp_io  # type: ignore[attr-defined]

            fn = getattr(cp_io, f"export_{fmt}", None)
        if callable(fn):
            fn(pattern, path)
            return path
    except Exception:
        pass
    {"dxf": _dxf, "svg": _svg, "pdf": _pdf}[fmt](pattern, path)
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


def _panel_polys(pattern: DraftedPattern):
    from couture.ui.pattern_view import segment_indices

    for p in pattern.panels:
        segs = []
        for s in p.segments:
            try:
                segs.append((s.name, p.outline[segment_indices(p, s.name)]))
            except StopIteration:
                pass
        yield p, segs


def _dxf(pattern: DraftedPattern, path: Path) -> None:
    import ezdxf

    doc = ezdxf.new("R12")
    msp = doc.modelspace()
    for p, segs in _panel_polys(pattern):
        pts = [tuple(v) for v in (p.outline * 1000.0)]
        msp.add_polyline2d(pts, close=True, dxfattribs={"layer": "1"})
        for h in p.holes:
            msp.add_polyline2d([tuple(v) for v in (h * 1000.0)], close=True, dxfattribs={"layer": "1"})
        for _name, P in segs:
            msp.add_polyline2d([tuple(v) for v in (P * 1000.0)], dxfattribs={"layer": "14"})
        c = p.outline.mean(axis=0) * 1000.0
        msp.add_text(p.name, dxfattribs={"layer": "1", "height": 20.0, "insert": (float(c[0]), float(c[1]))})
    doc.saveas(path)


def _bbox_mm(pattern: DraftedPattern) -> tuple[np.ndarray, np.ndarray]:
    pts = np.concatenate([p.outline for p in pattern.panels]) * 1000.0
    return pts.min(axis=0) - 10.0, pts.max(axis=0) + 10.0


def _svg(pattern: DraftedPattern, path: Path) -> None:
    lo, hi = _bbox_mm(pattern)
    w, h = hi - lo
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w:.1f}mm" height="{h:.1f}mm" '
           f'viewBox="0 0 {w:.3f} {h:.3f}">']
    for p, _segs in _panel_polys(pattern):
        P = p.outline * 1000.0
        pts = " ".join(f"{x - lo[0]:.3f},{hi[1] - y:.3f}" for x, y in P)  # SVG y grows downwards
        out.append(f'<polygon id="{p.name}" points="{pts}" fill="none" stroke="black" stroke-width="0.5"/>')
    out.append("</svg>")
    path.write_text("\n".join(out))


def _pdf(pattern: DraftedPattern, path: Path) -> None:
    from reportlab.lib.units import mm
    from reportlab.pdfgen import canvas

    lo, hi = _bbox_mm(pattern)
    w, h = hi - lo
    c = canvas.Canvas(str(path), pagesize=(w * mm, h * mm))
    for p, _segs in _panel_polys(pattern):
        P = (p.outline * 1000.0 - lo) * mm
        pth = c.beginPath()
        pth.moveTo(*P[0])
        for q in P[1:]:
            pth.lineTo(*q)
        pth.close()
        c.drawPath(pth, stroke=1, fill=0)
    c.showPage()
    c.save()

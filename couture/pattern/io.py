"""Pattern files: our JSON design (``couture/design/v1``), and exports of the
drafted pattern: DXF (AAMA/ASTM style), SVG and PDF at true scale."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from couture.pattern.drafted import DraftedPattern, Panel
from couture.pattern.errors import PatternError
from schemas.design import DESIGN_SCHEMA, Design


class DesignFile(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """Our JSON pattern file: the design in a versioned envelope."""

    schema: str = DESIGN_SCHEMA
    design: Design = msgspec.field(default_factory=Design)


# ------------------------------------------------------------------ JSON


_AT_BYTE = re.compile(r"\s*\(byte (\d+)\)")
_EXPONENT_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?[eE][+-]?\d+")


def _line_col(data: bytes, offset: int) -> tuple[int, int]:
    """1-based line and column (in characters) of byte ``offset``."""
    before = data[: max(0, min(offset, len(data)))]
    line_start = before.rfind(b"\n") + 1
    return before.count(b"\n") + 1, len(before[line_start:].decode("utf-8", errors="replace")) + 1


def parse_json(data: bytes | str, source: str = "<json>") -> Any:
    """Standard JSON (RFC 8259: no NaN, no Infinity, no trailing commas) to
    Python objects. A syntax error raises PatternError whose element is
    ``<source>:<line>:<column>`` and whose message says what is wrong there."""
    raw = data.encode() if isinstance(data, str) else bytes(data)
    try:
        return msgspec.json.decode(raw)
    except msgspec.ValidationError:  # (a DecodeError too) a number beyond the float range, such as 1e400
        big = [mm for mm in _EXPONENT_NUMBER.finditer(raw) if abs(float(mm.group())) == float("inf")]
        offset = big[0].start() if big else 0
        number = f" {big[0].group().decode()}" if big else ""
        what = f"number{number} is beyond the float range (about 1.8e308)"
    except msgspec.DecodeError as e:
        text = str(e)
        m = _AT_BYTE.search(text)
        offset = int(m.group(1)) if m else len(raw)
        what = _AT_BYTE.sub("", text).removeprefix("JSON is malformed: ")
        if raw[offset : offset + 3] == b"NaN" or raw[offset : offset + 8] == b"Infinity":
            offset -= raw[offset - 1 : offset] == b"-"
            what = "NaN and Infinity are not JSON numbers (write a finite number)"
        elif not raw.strip():
            what = "the file is empty"
        elif "truncated" in what:
            what = "the file ends inside a value (truncated)"
    line, col = _line_col(raw, offset)
    raise PatternError(f"{source}:{line}:{col}", f"invalid JSON: {what}")


def design_to_json(design: Design) -> bytes:
    """Our pattern file; standard JSON (msgspec writes no NaN or Infinity)."""
    return msgspec.json.format(msgspec.json.encode(DesignFile(design=design)), indent=2)


def design_from_json(data: bytes | str, source: str = "<json>") -> Design:
    """A ``couture/design/v1`` file's design; PatternError naming ``source``
    and the line and column of a syntax error, or the field of a wrong value."""
    try:
        f = msgspec.convert(parse_json(data, source), DesignFile)
    except msgspec.ValidationError as e:
        raise PatternError(source, f"not a {DESIGN_SCHEMA} design: {e}") from None
    if f.schema != DESIGN_SCHEMA:
        raise PatternError(source, f"schema {f.schema!r} is not {DESIGN_SCHEMA!r}")
    return f.design


def save_design(design: Design, path: str | Path) -> None:
    Path(path).write_bytes(design_to_json(design))


def load_design(path: str | Path) -> Design:
    return design_from_json(Path(path).read_bytes(), str(path))


def design_json_schema() -> dict:
    """JSON Schema (draft 2020-12) of our pattern file."""
    return msgspec.json.schema(DesignFile)


# ------------------------------------------------------------------ layout helpers

GAP = 0.03  # [m] between panels laid out flat


def offset_outline(P: np.ndarray, d: float) -> np.ndarray:
    """Outline offset outward by d [m] (miter joins, limited to 3 d)."""
    if d == 0:
        return P.copy()
    e_in = P - np.roll(P, 1, axis=0)
    e_out = np.roll(P, -1, axis=0) - P

    def nrm(e):
        n = np.stack([e[:, 1], -e[:, 0]], axis=1)
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)

    n1, n2 = nrm(e_in), nrm(e_out)
    m = n1 + n2
    m /= np.maximum(np.linalg.norm(m, axis=1, keepdims=True), 1e-300)
    c = np.maximum((m * n2).sum(1), 1 / 3)
    return P + (d / c)[:, None] * m


def layout(pattern: DraftedPattern, seam_allowance: float = 0.0) -> list[tuple[Panel, np.ndarray]]:
    """Each panel with the shift [m] that lays it out flat, side by side, from (0, 0)."""
    out = []
    x = 0.0
    for p in pattern.panels:
        o = offset_outline(p.outline, seam_allowance)
        lo, hi = o.min(0), o.max(0)
        out.append((p, np.array([x - lo[0], -lo[1]])))
        x += hi[0] - lo[0] + GAP
    return out


# ------------------------------------------------------------------ DXF (AAMA/ASTM)

AAMA_BOUNDARY, AAMA_GRAIN, AAMA_MIRROR, AAMA_CUTOUT, AAMA_SEW = "1", "7", "8", "11", "14"


def export_dxf(pattern: DraftedPattern, path: str | Path, seam_allowance: float = 0.0, units: str = "mm") -> None:
    """AAMA-style DXF: one BLOCK per piece, inserted once. In each block: layer 1
    the boundary (cut line: the outline plus seam allowance) as a closed
    POLYLINE, layer 14 the sew line (the drafted outline), layer 11 internal
    cut-outs (holes, interior darts), layer 7 the grain line, layer 8 a mirror
    line for symmetric pieces, TEXT 'Piece Name: <name>'. Units: mm
    ($INSUNITS 4) or inches ($INSUNITS 1)."""
    import ezdxf

    scale = {"mm": 1000.0, "in": 1000.0 / 25.4}[units]
    doc = ezdxf.new("R2000")
    doc.header["$INSUNITS"] = 4 if units == "mm" else 1
    doc.header["$MEASUREMENT"] = 1 if units == "mm" else 0
    for layer in (AAMA_BOUNDARY, AAMA_GRAIN, AAMA_MIRROR, AAMA_CUTOUT, AAMA_SEW):
        if layer not in doc.layers:
            doc.layers.add(layer)
    msp = doc.modelspace()
    for p, shift in layout(pattern, seam_allowance):
        blk = doc.blocks.new(name=_block_name(p.name))
        cut = offset_outline(p.outline, seam_allowance) * scale
        blk.add_polyline2d([tuple(v) for v in cut], close=True, dxfattribs={"layer": AAMA_BOUNDARY})
        blk.add_polyline2d([tuple(v) for v in p.outline * scale], close=True, dxfattribs={"layer": AAMA_SEW})
        for h in p.holes:
            blk.add_polyline2d([tuple(v) for v in h * scale], close=True, dxfattribs={"layer": AAMA_CUTOUT})
        lo, hi = p.outline.min(0), p.outline.max(0)
        cx = 0.5 * (lo[0] + hi[0])
        blk.add_line(
            (cx * scale, (lo[1] + 0.25 * (hi[1] - lo[1])) * scale),
            (cx * scale, (lo[1] + 0.75 * (hi[1] - lo[1])) * scale),
            dxfattribs={"layer": AAMA_GRAIN},
        )
        if any(s.name.endswith("_mirror") for s in p.segments):
            blk.add_line((cx * scale, lo[1] * scale), (cx * scale, hi[1] * scale), dxfattribs={"layer": AAMA_MIRROR})
        blk.add_text(
            f"Piece Name: {p.name}",
            dxfattribs={
                "layer": AAMA_GRAIN,
                "height": 10.0 if units == "mm" else 0.4,
                "insert": (cx * scale, 0.5 * (lo[1] + hi[1]) * scale),
            },
        )
        msp.add_blockref(blk.name, (shift[0] * scale, shift[1] * scale))
    doc.saveas(str(path))


def _block_name(name: str) -> str:
    return "".join(c if c.isalnum() or c in "_-" else "_" for c in name)


def import_dxf(path: str | Path) -> dict[str, dict]:
    """Pieces of an AAMA DXF: name -> {'outline': sew line (k, 2) [m], 'cut': (k, 2) [m],
    'holes': [...]} read from the blocks' layers 14, 1 and 11."""
    import ezdxf
    from ezdxf.entities import Polyline

    doc = ezdxf.readfile(str(path))
    unit = {4: 1e-3, 1: 0.0254, 6: 1.0, 5: 1e-2}.get(doc.header.get("$INSUNITS", 4), 1e-3)
    out = {}
    for ref in doc.modelspace().query("INSERT"):
        blk = doc.blocks[ref.dxf.name]
        piece: dict[str, Any] = {"outline": None, "cut": None, "holes": []}
        name = ref.dxf.name
        for e in blk:
            if e.dxftype() == "TEXT" and e.dxf.text.startswith("Piece Name:"):
                name = e.dxf.text.split(":", 1)[1].strip()
            elif isinstance(e, Polyline):
                P = np.array([(v.dxf.location.x, v.dxf.location.y) for v in e.vertices], np.float64) * unit
                if e.dxf.layer == AAMA_SEW:
                    piece["outline"] = P
                elif e.dxf.layer == AAMA_BOUNDARY:
                    piece["cut"] = P
                elif e.dxf.layer == AAMA_CUTOUT:
                    piece["holes"].append(P)
        out[name] = piece
    return out


# ------------------------------------------------------------------ SVG

SCALE_SQUARE = 0.10  # [m] the scale check square


def export_svg(pattern: DraftedPattern, path: str | Path, seam_allowance: float = 0.0) -> None:
    """True-scale SVG (width/height in mm, viewBox in mm), with a 10 cm check square."""
    pieces = layout(pattern, seam_allowance)
    W, H = _extent(pieces, seam_allowance)
    mm = 1000.0
    lines = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{W * mm:.3f}mm" height="{H * mm:.3f}mm" '
        f'viewBox="0 0 {W * mm:.3f} {H * mm:.3f}">'
    ]

    def path_d(P, shift):
        Q = (P + shift) * mm
        return "M " + " L ".join(f"{x:.3f},{H * mm - y:.3f}" for x, y in Q) + " Z"

    for p, shift in pieces:
        shift = shift + np.array([0.0, SCALE_SQUARE + 2 * GAP])
        lines.append(f'<g id="{_block_name(p.name)}">')
        if seam_allowance > 0:
            lines.append(
                f'<path d="{path_d(offset_outline(p.outline, seam_allowance), shift)}" fill="none" '
                f'stroke="black" stroke-width="0.3"/>'
            )
        lines.append(
            f'<path class="sew" d="{path_d(p.outline, shift)}" fill="none" stroke="black" '
            f'stroke-width="0.5" stroke-dasharray="{"3,2" if seam_allowance > 0 else "none"}"/>'
        )
        for h in p.holes:
            lines.append(f'<path class="hole" d="{path_d(h, shift)}" fill="none" stroke="red" stroke-width="0.3"/>')
        c = (p.outline.min(0) + p.outline.max(0)) / 2 + shift
        lines.append(
            f'<text x="{c[0] * mm:.1f}" y="{H * mm - c[1] * mm:.1f}" font-size="12" '
            f'text-anchor="middle">{p.name}</text></g>'
        )
    s = SCALE_SQUARE * mm
    lines.append(
        f'<rect id="scale_check" x="{GAP * mm:.3f}" y="{H * mm - (GAP * mm + s):.3f}" width="{s:.3f}" '
        f'height="{s:.3f}" fill="none" stroke="blue" stroke-width="0.5"/>'
    )
    lines.append(f'<text x="{GAP * mm:.1f}" y="{H * mm - GAP * mm * 0.3:.1f}" font-size="8">10 cm x 10 cm</text>')
    lines.append("</svg>")
    Path(path).write_text("\n".join(lines))


def _extent(pieces, seam_allowance):
    W = max(float((offset_outline(p.outline, seam_allowance) + s).max(0)[0]) for p, s in pieces)
    H = max(float((offset_outline(p.outline, seam_allowance) + s).max(0)[1]) for p, s in pieces)
    return max(W, SCALE_SQUARE + 2 * GAP), H + SCALE_SQUARE + 3 * GAP


# ------------------------------------------------------------------ PDF


def export_pdf(pattern: DraftedPattern, path: str | Path, seam_allowance: float = 0.0) -> tuple[float, float]:
    """True-scale PDF on one page large enough for every piece (print tiled
    with any poster tool, or on a plotter); 10 cm check square. Returns the
    page size in points."""
    from reportlab.pdfgen import canvas

    pieces = layout(pattern, seam_allowance)
    W, H = _extent(pieces, seam_allowance)
    pt = 72.0 / 0.0254  # points per metre
    size = (W * pt, H * pt)
    c = canvas.Canvas(str(path), pagesize=size)
    c.setTitle("couture pattern")

    def poly(P, shift, dash=False):
        Q = (P + shift) * pt
        pth = c.beginPath()
        pth.moveTo(*Q[0])
        for q in Q[1:]:
            pth.lineTo(*q)
        pth.close()
        c.setDash(3, 2) if dash else c.setDash()
        c.drawPath(pth, stroke=1, fill=0)

    for p, shift in pieces:
        shift = shift + np.array([0.0, SCALE_SQUARE + 2 * GAP])
        if seam_allowance > 0:
            poly(offset_outline(p.outline, seam_allowance), shift)
        poly(p.outline, shift, dash=seam_allowance > 0)
        for h in p.holes:
            poly(h, shift)
        ctr = (p.outline.min(0) + p.outline.max(0)) / 2 + shift
        c.setDash()
        c.drawCentredString(ctr[0] * pt, ctr[1] * pt, p.name)
    c.setDash()
    c.rect(GAP * pt, GAP * pt, SCALE_SQUARE * pt, SCALE_SQUARE * pt, stroke=1, fill=0)
    c.drawString(GAP * pt, GAP * pt * 0.4, "10 cm x 10 cm scale check")
    c.showPage()
    c.save()
    return size

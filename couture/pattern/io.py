"""Pattern files: our JSON design (``couture/design/v1``), and exports of the
drafted pattern as pieces to cut (``couture.pattern.cutting``: cut line with
seam allowances, sew line, notches, drill holes, grain line, labels): DXF
(AAMA/ASTM layers), SVG and PDF at true scale, and a PDF tiled on A4 or US
letter pages for a home printer."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from couture.pattern.cutting import DRILL_RADIUS, CutPiece, CutSpec, cut_pieces
from couture.pattern.drafted import DraftedPattern, Panel
from couture.pattern.errors import PatternError
from couture.pattern.geometry import signed_area
from schemas.design import DESIGN_SCHEMA, Design

EXAMPLES = Path(__file__).resolve().parent / "examples"
"""the example designs shipped with couture (``couture/pattern/examples/<name>.json``): the one
place the golden cases, the benchmarks and the tests find them"""


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
    """Outline offset outward by d [m] (miter joins, limited to 3 d), vertex by
    vertex (it may cross itself where the outline turns inward sharply; the
    exports use ``couture.pattern.cutting.offset_polygon``, which never does)."""
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


SCALE_SQUARE = 0.10  # [m] the scale check square
HEADER = SCALE_SQUARE + 2 * GAP  # [m] the band above the pieces holding the square and the legend


def _spec(seam_allowance: float, spec: CutSpec | None) -> CutSpec:
    """The spec an export uses: ``spec``, or (the older call with a width only)
    that width everywhere, hems included, every panel its own piece."""
    if spec is not None:
        return spec
    return CutSpec(seam_allowance=seam_allowance, hem_allowance=seam_allowance, group=False, sheet_width=0.0)


@dataclass
class Sheet:
    """Pieces laid out on one sheet [m], y up, origin at the bottom left; the
    scale square and legend in a band along the top."""

    pieces: list[CutPiece]
    shifts: list[np.ndarray]
    """per piece, added to its material coordinates"""
    width: float
    height: float
    spec: CutSpec

    @property
    def square(self) -> np.ndarray:
        """bottom-left corner of the 10 cm scale square"""
        return np.array([GAP, self.height - GAP - SCALE_SQUARE])


def sheet_layout(pieces: list[CutPiece], spec: CutSpec) -> Sheet:
    """Shelf packing: pieces left to right, a new row below when the next would
    pass ``spec.sheet_width`` (0: one row)."""
    limit = spec.sheet_width if spec.sheet_width > 0 else math.inf
    rows: list[list[tuple[CutPiece, np.ndarray, np.ndarray]]] = [[]]
    x = 0.0
    for p in pieces:
        lo, hi = p.cut.min(0), p.cut.max(0)
        if rows[-1] and x + (hi[0] - lo[0]) > limit:
            rows.append([])
            x = 0.0
        rows[-1].append((p, lo, hi))
        x += hi[0] - lo[0] + GAP
    heights = [max(hi[1] - lo[1] for _, lo, hi in r) for r in rows]
    H = HEADER + sum(heights) + GAP * len(rows)
    shifts, W = [], SCALE_SQUARE + 2 * GAP
    top = H - HEADER
    for r, h in zip(rows, heights, strict=True):
        x = GAP
        for _, lo, hi in r:
            shifts.append(np.array([x - lo[0], top - hi[1]]))  # top-aligned in the row
            x += hi[0] - lo[0] + GAP
        W = max(W, x)
        top -= h + GAP
    return Sheet([p for r in rows for p, _, _ in r], shifts, W, H, spec)


# ------------------------------------------------------------------ what is drawn


@dataclass
class Mark:
    """One drawn thing of a piece, in sheet coordinates [m].

    kind: 'cut' (closed), 'sew' (closed), 'cutout' (closed), 'notch' (line),
    'grain' (line), 'arrow' (open polyline), 'axis' (line), 'drill' (point),
    'text' (point + text, height [m]; ``system``: an AAMA piece system text)."""

    kind: str
    pts: np.ndarray
    text: str = ""
    height: float = 0.0
    system: bool = False


def piece_marks(p: CutPiece, shift: np.ndarray) -> list[Mark]:
    out = [Mark("cut", p.cut + shift), Mark("sew", p.sew + shift)]
    for H, C in zip(p.panel.holes, p.hole_cut, strict=True):
        out.append(Mark("sew", H + shift))
        if C is not None:
            out.append(Mark("cutout", C + shift))
    for n in p.notches:
        out.append(Mark("notch", np.array([n.outer, n.inner]) + shift))
    for d in p.drills:
        out.append(Mark("drill", d[None] + shift))
    g = p.grain + shift
    out.append(Mark("grain", g))
    u = (g[1] - g[0]) / max(float(np.linalg.norm(g[1] - g[0])), 1e-12)
    v = np.array([-u[1], u[0]])
    head = 0.015
    for tip, d in ((g[1], u), (g[0], -u)):  # arrowheads at both ends: the grain runs either way
        out.append(Mark("arrow", np.array([tip - head * d + 0.4 * head * v, tip, tip - head * d - 0.4 * head * v])))
    if p.symmetry_axis is not None:
        out.append(Mark("axis", p.symmetry_axis + shift))
    # labels beside the grain line's middle, reading down
    at = 0.5 * (g[0] + g[1]) + np.array([0.012, 0.0])
    for i, line in enumerate(p.labels):
        h = 0.008 if i == 0 else 0.005
        out.append(Mark("text", at[None].copy(), line, h, system=line.split(":")[0] in _SYSTEM_TEXT))
        at = at - np.array([0.0, 1.6 * h])
    return out


_SYSTEM_TEXT = ("Piece Name", "Quantity", "Size", "Style Name")


def _legend(sheet: Sheet) -> list[str]:
    """Lines written inside the scale square (so they print on the first page)."""
    s = sheet.spec
    return [
        s.design_name or "couture pattern",
        f"size {s.size}" if s.size else "",
        f"seams {s.seam_allowance * 100:g} cm, hems {s.hem_allowance * 100:g} cm",
        "allowances included",
        "",
        "this square: 10 cm x 10 cm",
    ]


# ------------------------------------------------------------------ DXF (AAMA/ASTM)

AAMA_BOUNDARY, AAMA_TURN, AAMA_NOTCH, AAMA_GRAIN, AAMA_INTERNAL = "1", "2", "4", "7", "8"
TURN_ANGLE = math.radians(25)
"""a line's vertex that turns more than this is a turn point (corner), layer 2"""
AAMA_CUTOUT, AAMA_DRILL, AAMA_SEW, AAMA_ANNOTATION = "11", "13", "14", "15"
AAMA_MIRROR = AAMA_INTERNAL  # an older name: the symmetry axis is drawn as an internal line
_DXF_LAYER = {
    "cut": AAMA_BOUNDARY,
    "sew": AAMA_SEW,
    "cutout": AAMA_CUTOUT,
    "notch": AAMA_NOTCH,
    "grain": AAMA_GRAIN,
    "arrow": AAMA_INTERNAL,
    "axis": AAMA_INTERNAL,
    "drill": AAMA_DRILL,
}


def export_dxf(
    pattern: DraftedPattern,
    path: str | Path,
    seam_allowance: float = 0.0,
    units: str = "mm",
    *,
    spec: CutSpec | None = None,
) -> list[CutPiece]:
    """AAMA/ASTM-style DXF: one BLOCK per piece, inserted once, in the piece's
    material coordinates. Layers: 1 the cut line (closed POLYLINE) and the
    piece system texts ('Piece Name: ', 'Quantity: ', 'Size: ', 'Style Name: ')
    as TEXT, 14 the sew lines (the outline first, then each hole's), 11 the cut
    lines of openings, 4 notches (LINEs from the cut line inward), 7 the grain
    line (one LINE, tail to head), 2 turn points (POINTs at the corners of the
    cut and sew lines), 8 internal lines (grain arrowheads, the
    symmetry axis), 13 drill holes (POINTs), 15 annotation text ('Cut 2 ...').
    Without ``spec``: ``seam_allowance`` [m] on every edge, hems included, one
    piece per panel. Units: mm ($INSUNITS 4) or inches ($INSUNITS 1)."""
    import ezdxf

    if units not in ("mm", "in"):
        raise PatternError("units", f"DXF units {units!r} are not 'mm' or 'in'")
    spec = _spec(seam_allowance, spec)
    pieces = cut_pieces(pattern, spec)
    scale = {"mm": 1000.0, "in": 1000.0 / 25.4}[units]
    doc = ezdxf.new("R2000")
    doc.header["$INSUNITS"] = 4 if units == "mm" else 1
    doc.header["$MEASUREMENT"] = 1 if units == "mm" else 0
    for layer in (AAMA_BOUNDARY, AAMA_TURN, AAMA_NOTCH, AAMA_GRAIN, AAMA_INTERNAL, AAMA_CUTOUT, AAMA_DRILL, AAMA_SEW):
        if layer not in doc.layers:
            doc.layers.add(layer)
    doc.layers.add(AAMA_ANNOTATION)
    msp = doc.modelspace()
    sheet = sheet_layout(pieces, spec)
    for p, shift in zip(sheet.pieces, sheet.shifts, strict=True):
        blk = doc.blocks.new(name=_block_name(p.name))
        for m in piece_marks(p, np.zeros(2)):
            P = m.pts * scale
            if m.kind in ("cut", "sew", "cutout"):
                blk.add_polyline2d([tuple(v) for v in P], close=True, dxfattribs={"layer": _DXF_LAYER[m.kind]})
                for v in P[turn_points(m.pts)]:
                    blk.add_point(tuple(v), dxfattribs={"layer": AAMA_TURN})
            elif m.kind == "arrow":
                blk.add_polyline2d([tuple(v) for v in P], close=False, dxfattribs={"layer": AAMA_INTERNAL})
            elif m.kind == "drill":
                blk.add_point(tuple(P[0]), dxfattribs={"layer": AAMA_DRILL})
            elif m.kind == "text":
                blk.add_text(
                    m.text,
                    dxfattribs={
                        "layer": AAMA_BOUNDARY if m.system else AAMA_ANNOTATION,
                        "height": m.height * scale,
                        "insert": tuple(P[0]),
                    },
                )
            else:
                blk.add_line(tuple(P[0]), tuple(P[1]), dxfattribs={"layer": _DXF_LAYER[m.kind]})
        msp.add_blockref(blk.name, (shift[0] * scale, shift[1] * scale))
    doc.saveas(str(path))
    return pieces


def turn_points(P: np.ndarray) -> np.ndarray:
    """Indices of the closed polyline's corners: where it turns more than ``TURN_ANGLE``."""
    a = P - np.roll(P, 1, axis=0)
    b = np.roll(P, -1, axis=0) - P
    cos = (a * b).sum(1) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-300)
    return np.nonzero(cos < math.cos(TURN_ANGLE))[0]


def _block_name(name: str) -> str:
    return "".join(c if c.isalnum() or c in "_-" else "_" for c in name)


def import_dxf(path: str | Path) -> dict[str, dict]:
    """Pieces of an AAMA DXF: name -> {'outline': sew line (k, 2) [m], 'cut': (k, 2) [m],
    'holes': sew lines of holes, 'cutouts': cut lines of openings, 'notches': [(2, 2)],
    'grain': (2, 2) or None, 'drills': (d, 2), 'texts': [str], 'insert': (2,) [m]},
    read from the blocks' layers 14, 1, 11, 4, 7, 13 and their TEXT."""
    import ezdxf
    from ezdxf.entities import Polyline

    doc = ezdxf.readfile(str(path))
    unit = {4: 1e-3, 1: 0.0254, 6: 1.0, 5: 1e-2}.get(doc.header.get("$INSUNITS", 4), 1e-3)
    out = {}
    for ref in doc.modelspace().query("INSERT"):
        blk = doc.blocks[ref.dxf.name]
        piece: dict[str, Any] = {
            "outline": None,
            "cut": None,
            "holes": [],
            "cutouts": [],
            "notches": [],
            "grain": None,
            "drills": [],
            "texts": [],
            "insert": np.array([ref.dxf.insert.x, ref.dxf.insert.y]) * unit,
        }
        name = ref.dxf.name
        sew = []
        for e in blk:
            layer = e.dxf.layer
            if e.dxftype() == "TEXT":
                piece["texts"].append(e.dxf.text)
                if e.dxf.text.startswith("Piece Name:"):
                    name = e.dxf.text.split(":", 1)[1].strip()
            elif isinstance(e, Polyline):
                P = np.array([(v.dxf.location.x, v.dxf.location.y) for v in e.vertices], np.float64) * unit
                if layer == AAMA_SEW:
                    sew.append(P)
                elif layer == AAMA_BOUNDARY:
                    piece["cut"] = P
                elif layer == AAMA_CUTOUT:
                    piece["cutouts"].append(P)
            elif e.dxftype() == "LINE":
                seg = np.array([[e.dxf.start.x, e.dxf.start.y], [e.dxf.end.x, e.dxf.end.y]]) * unit
                if layer == AAMA_NOTCH:
                    piece["notches"].append(seg)
                elif layer == AAMA_GRAIN:
                    piece["grain"] = seg
            elif e.dxftype() == "POINT" and layer == AAMA_DRILL:
                piece["drills"].append([e.dxf.location.x * unit, e.dxf.location.y * unit])
        if sew:  # the outline is the sew line enclosing the others
            k = max(range(len(sew)), key=lambda i: abs(signed_area(sew[i])))
            piece["outline"] = sew[k]
            piece["holes"] = sew[:k] + sew[k + 1 :]
        piece["drills"] = np.array(piece["drills"]).reshape(-1, 2)
        out[name] = piece
    return out


# ------------------------------------------------------------------ SVG


def _svg_marks(lines: list[str], marks: list[Mark], H: float) -> None:
    mm = 1000.0

    def pts(P):
        return " ".join(f"{x * mm:.3f},{(H - y) * mm:.3f}" for x, y in P)

    for m in marks:
        if m.kind == "cut":
            lines.append(f'<polygon class="cut" points="{pts(m.pts)}" fill="none" stroke="black" stroke-width="0.5"/>')
        elif m.kind == "sew":
            lines.append(
                f'<polygon class="sew" points="{pts(m.pts)}" fill="none" stroke="black" stroke-width="0.3" '
                f'stroke-dasharray="3,2"/>'
            )
        elif m.kind == "cutout":
            lines.append(f'<polygon class="cutout" points="{pts(m.pts)}" fill="none" stroke="red" stroke-width="0.4"/>')
        elif m.kind in ("notch", "grain", "arrow", "axis"):
            dash = ' stroke-dasharray="8,2,1,2"' if m.kind == "axis" else ""
            width = 0.5 if m.kind == "notch" else 0.35
            lines.append(
                f'<polyline class="{m.kind}" points="{pts(m.pts)}" fill="none" stroke="black" '
                f'stroke-width="{width}"{dash}/>'
            )
        elif m.kind == "drill":
            x, y = m.pts[0]
            r = DRILL_RADIUS * mm
            lines.append(
                f'<circle class="drill" cx="{x * mm:.3f}" cy="{(H - y) * mm:.3f}" r="{r:.2f}" fill="none" '
                f'stroke="black" stroke-width="0.3"/>'
            )
        elif m.kind == "text":
            x, y = m.pts[0]
            lines.append(
                f'<text class="label" x="{x * mm:.2f}" y="{(H - y) * mm:.2f}" font-size="{m.height * mm:.1f}" '
                f'font-family="sans-serif">{_xml(m.text)}</text>'
            )


def _xml(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def export_svg(
    pattern: DraftedPattern, path: str | Path, seam_allowance: float = 0.0, *, spec: CutSpec | None = None
) -> Sheet:
    """True-scale SVG (width/height in mm, viewBox in mm): per piece a group with
    its cut line (solid), sew lines (dashed), notches, drill holes, grain line
    with arrowheads and labels; a 10 cm check square at the top left."""
    spec = _spec(seam_allowance, spec)
    sheet = sheet_layout(cut_pieces(pattern, spec), spec)
    W, H = sheet.width, sheet.height
    mm = 1000.0
    lines = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{W * mm:.3f}mm" height="{H * mm:.3f}mm" '
        f'viewBox="0 0 {W * mm:.3f} {H * mm:.3f}">'
    ]
    for p, shift in zip(sheet.pieces, sheet.shifts, strict=True):
        lines.append(f'<g id="{_block_name(p.name)}">')
        _svg_marks(lines, piece_marks(p, shift), H)
        lines.append("</g>")
    s = SCALE_SQUARE * mm
    x0, y0 = sheet.square * mm
    lines.append(
        f'<rect id="scale_check" x="{x0:.3f}" y="{H * mm - (y0 + s):.3f}" width="{s:.3f}" '
        f'height="{s:.3f}" fill="none" stroke="blue" stroke-width="0.5"/>'
    )
    for i, t in enumerate(_legend(sheet)):
        lines.append(
            f'<text x="{x0 + 4:.1f}" y="{H * mm - (y0 + s) + 9 + 6 * i:.1f}" font-size="4" '
            f'font-family="sans-serif">{_xml(t)}</text>'
        )
    lines.append("</svg>")
    Path(path).write_text("\n".join(lines))
    return sheet


# ------------------------------------------------------------------ PDF

PT_PER_M = 72.0 / 0.0254
PAPERS = {"a4": (0.210, 0.297), "letter": (0.2159, 0.2794)}
"""[m] portrait paper sizes"""
PRINT_MARGIN = 0.01  # [m] blank border of a tiled page (printers do not print to the edge)
TILE_OVERLAP = 0.01  # [m] shared strip between neighbouring tiles, with the registration marks in it


def _pdf_marks(c, marks: list[Mark]) -> None:
    pt = PT_PER_M

    def path(P, close):
        pth = c.beginPath()
        pth.moveTo(*(P[0] * pt))
        for q in P[1:]:
            pth.lineTo(*(q * pt))
        if close:
            pth.close()
        c.drawPath(pth, stroke=1, fill=0)

    for m in marks:
        c.setDash()
        c.setLineWidth(0.5)
        c.setStrokeColorRGB(0, 0, 0)
        if m.kind == "cut":
            c.setLineWidth(0.9)
            path(m.pts, True)
        elif m.kind == "sew":
            c.setDash(3, 2)
            path(m.pts, True)
        elif m.kind == "cutout":
            c.setStrokeColorRGB(0.8, 0, 0)
            path(m.pts, True)
        elif m.kind in ("notch", "grain", "arrow", "axis"):
            if m.kind == "axis":
                c.setDash([8, 2, 1, 2])
            c.setLineWidth(0.9 if m.kind == "notch" else 0.6)
            path(m.pts, False)
        elif m.kind == "drill":
            x, y = m.pts[0] * pt
            r = DRILL_RADIUS * pt
            c.circle(x, y, r, stroke=1, fill=0)
            c.line(x - 2 * r, y, x + 2 * r, y)
            c.line(x, y - 2 * r, x, y + 2 * r)
        elif m.kind == "text":
            c.setFont("Helvetica-Bold" if m.height > 0.006 else "Helvetica", m.height * pt)
            c.drawString(*(m.pts[0] * pt), m.text)


def _pdf_sheet(c, sheet: Sheet, window: tuple[float, float, float, float] | None = None) -> None:
    """Every piece, the scale square and the legend, in sheet coordinates (points);
    with a ``window`` (x0, y0, x1, y1) [m], only the pieces that reach into it."""
    pt = PT_PER_M
    for p, shift in zip(sheet.pieces, sheet.shifts, strict=True):
        lo, hi = p.cut.min(0) + shift, p.cut.max(0) + shift
        if window and (hi[0] < window[0] or lo[0] > window[2] or hi[1] < window[1] or lo[1] > window[3]):
            continue
        _pdf_marks(c, piece_marks(p, shift))
    c.setDash()
    c.setStrokeColorRGB(0, 0, 0.8)
    c.setLineWidth(0.8)
    x0, y0 = sheet.square * pt
    c.rect(x0, y0, SCALE_SQUARE * pt, SCALE_SQUARE * pt, stroke=1, fill=0)
    c.setStrokeColorRGB(0, 0, 0)
    c.setFont("Helvetica", 10)
    for i, t in enumerate(_legend(sheet)):
        c.drawString(x0 + 10, y0 + SCALE_SQUARE * pt - 20 - 14 * i, t)


def export_pdf(
    pattern: DraftedPattern, path: str | Path, seam_allowance: float = 0.0, *, spec: CutSpec | None = None
) -> tuple[float, float]:
    """True-scale PDF on one page large enough for every piece (a plotter, a
    copy shop; ``export_pdf_tiled`` for a home printer); 10 cm check square.
    Returns the page size in points."""
    from reportlab.pdfgen import canvas

    spec = _spec(seam_allowance, spec)
    sheet = sheet_layout(cut_pieces(pattern, spec), spec)
    size = (sheet.width * PT_PER_M, sheet.height * PT_PER_M)
    c = canvas.Canvas(str(path), pagesize=size)
    c.setTitle(spec.design_name or "couture pattern")
    _pdf_sheet(c, sheet)
    c.showPage()
    c.save()
    return size


def tile_grid(width: float, height: float, paper: str = "a4") -> tuple[int, int]:
    """(columns, rows) of portrait ``paper`` pages that cover a width x height [m]
    sheet, with ``PRINT_MARGIN`` around each page's printed area and neighbouring
    areas overlapping by ``TILE_OVERLAP``."""
    if paper not in PAPERS:
        raise PatternError("paper", f"paper {paper!r} is not one of {sorted(PAPERS)}")
    pw, ph = (d - 2 * PRINT_MARGIN for d in PAPERS[paper])
    cols = max(1, math.ceil((width - TILE_OVERLAP) / (pw - TILE_OVERLAP) - 1e-9))
    rows = max(1, math.ceil((height - TILE_OVERLAP) / (ph - TILE_OVERLAP) - 1e-9))
    return cols, rows


def _col_name(i: int) -> str:
    s = ""
    i += 1
    while i:
        i, r = divmod(i - 1, 26)
        s = chr(65 + r) + s
    return s


def export_pdf_tiled(
    pattern: DraftedPattern, path: str | Path, paper: str = "a4", *, spec: CutSpec | None = None
) -> tuple[int, int]:
    """The sheet at true scale on portrait A4 or US letter pages for a home
    printer: columns A, B, ... left to right, rows 1, 2, ... top to bottom,
    page A1 (the first) with the 10 cm check square. Neighbouring pages share
    a ``TILE_OVERLAP`` strip; its middle line carries registration marks (a
    circled cross) that land on each other when the pages are laid over one
    another. Returns (columns, rows); pages are A1, B1, ..., A2, ..."""
    from reportlab.pdfgen import canvas

    spec = spec or CutSpec()
    tile_grid(1.0, 1.0, paper)  # a wrong paper name fails before the work
    sheet = sheet_layout(cut_pieces(pattern, spec), spec)
    cols, rows = tile_grid(sheet.width, sheet.height, paper)
    PW, PH = PAPERS[paper]
    pw, ph = PW - 2 * PRINT_MARGIN, PH - 2 * PRINT_MARGIN
    sx, sy = pw - TILE_OVERLAP, ph - TILE_OVERLAP
    top = sheet.height
    pt = PT_PER_M
    # registration marks in sheet coordinates: on the middle lines of the overlaps
    vx = [k * sx + TILE_OVERLAP / 2 for k in range(1, cols)]
    hy = [top - k * sy - TILE_OVERLAP / 2 for k in range(1, rows)]
    marks = [(x, top - r * sy - ph / 2) for x in vx for r in range(rows)]
    marks += [(c0 * sx + pw / 2, y) for y in hy for c0 in range(cols)]
    marks += [(x, y) for x in vx for y in hy]
    c = canvas.Canvas(str(path), pagesize=(PW * pt, PH * pt))
    c.setTitle(f"{spec.design_name or 'couture pattern'} ({cols} x {rows} {paper} pages)")
    for r in range(rows):
        for k in range(cols):
            x0, y1 = k * sx, top - r * sy  # the page's printed window: [x0, x0 + pw] x [y1 - ph, y1]
            label = f"{_col_name(k)}{r + 1}"
            c.saveState()
            c.translate(PRINT_MARGIN * pt, PRINT_MARGIN * pt)
            c.setFillColorRGB(0.88, 0.88, 0.88)
            c.setFont("Helvetica-Bold", 96)
            c.drawCentredString(pw * pt / 2, ph * pt / 2 - 34, label)
            c.setFillColorRGB(0, 0, 0)
            pth = c.beginPath()
            pth.rect(0, 0, pw * pt, ph * pt)
            c.clipPath(pth, stroke=0, fill=0)
            c.translate(-x0 * pt, -(y1 - ph) * pt)
            _pdf_sheet(c, sheet, (x0, y1 - ph, x0 + pw, y1))
            c.setDash([2, 2])
            c.setLineWidth(0.3)
            c.setStrokeColorRGB(0.4, 0.4, 0.4)
            for x in vx:
                c.line(x * pt, (y1 - ph) * pt, x * pt, y1 * pt)
            for y in hy:
                c.line(x0 * pt, y * pt, (x0 + pw) * pt, y * pt)
            c.setDash()
            c.setLineWidth(0.5)
            c.setStrokeColorRGB(0, 0, 0)
            for x, y in marks:
                if not (x0 - 0.01 <= x <= x0 + pw + 0.01 and y1 - ph - 0.01 <= y <= y1 + 0.01):
                    continue  # on another page
                c.circle(x * pt, y * pt, 0.003 * pt, stroke=1, fill=0)
                c.line((x - 0.005) * pt, y * pt, (x + 0.005) * pt, y * pt)
                c.line(x * pt, (y - 0.005) * pt, x * pt, (y + 0.005) * pt)
            c.restoreState()
            c.setFont("Helvetica", 7)
            c.drawString(
                PRINT_MARGIN * pt,
                PRINT_MARGIN * pt / 3,
                f"{label}  (page {r * cols + k + 1} of {cols * rows}: {cols} columns A-{_col_name(cols - 1)}, "
                f"{rows} rows 1-{rows}; overlap {TILE_OVERLAP * 1000:g} mm, align the circled crosses; "
                f"print at 100 %)",
            )
            c.showPage()
    c.save()
    return cols, rows

"""Pattern pieces drawn by other tools: AAMA/ASTM DXF (Gerber, Lectra, Optitex,
CLO, Seamly2D/Valentina, this project's own export) and FreeSewing SVG, read
into :class:`ImportedPiece` (sew line, holes, notches, grain, name, cut count)
in metres, y up. Bus-free; ``couture.pattern.sewing`` turns the pieces into a
design (segments, suggested seams, placement).

DXF layers (AAMA/ASTM): 1 cut line and piece system text, 14 sew line, 11 cut
line of an opening, 4 notches, 7 grain line, 13 drill holes, 8 internal lines,
2 turn points (ignored: corners are found again from the sew line). Pieces
come as blocks (one INSERT each, or, as Valentina writes them, every piece in
one block inserted once per piece) or as loose polylines in model space: a
piece is a closed cut line not inside another, its sew line the largest layer
14 outline inside it (without one, the cut line less ``seam_allowance``).
Arcs, bulges and splines are flattened to polylines.

FreeSewing SVG (``pattern.render()``): one ``<g id="fs-stack-DESIGN.PART-part-...">``
per part; the seam line is the closed ``class="fabric"`` path, the seam
allowance the ``class="fabric sa"`` path (ignored), the cut count and
mirroring from the part's ``cut,N,...mirrored`` / ``onFold`` annotation
text. Units come from the SVG's width/height and viewBox (svgelements
resolves them, with every group transform).

SVG path library: svgelements (pure Python, no dependencies), because it
parses the whole document (groups, their transforms, ``<use>``, the
width/height units against the viewBox) into absolute coordinates; the other
candidate, svgpathtools, parses path ``d`` strings but leaves transforms and
document units to the caller.

Every problem raises :class:`ImportError_` (a PatternError) naming the file,
the piece and the problem; nothing is written here.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from couture.pattern.errors import PatternError
from couture.pattern.geometry import point_in_polygon, polyline_length, self_intersections, signed_area

UNITS = {"mm": 1e-3, "cm": 1e-2, "in": 0.0254, "m": 1.0}
"""[m] per file unit, for ``--units``"""
_INSUNITS = {1: "in", 4: "mm", 5: "cm", 6: "m"}
MIN_PIECE = 0.01
"""[m] a piece smaller than this (its bounding box's longer side) is an error (wrong units?)"""
MAX_PIECE = 3.0
"""[m] a piece larger than this is an error (wrong units?)"""
CLOSE_TOL = 1e-3
"""[m] an outline whose ends are this close is closed"""
FLATTEN = 0.2
"""[file units] chord tolerance when flattening arcs, bulges and splines (0.2 mm for mm files)"""


class ImportError_(PatternError):  # noqa: N801  # not the builtin ImportError
    """A file that cannot be imported: ``element`` is ``FILE`` or ``FILE:PIECE``."""

    def __init__(self, source: str, piece: str, message: str):
        self.source = source
        self.piece = piece
        super().__init__(f"{source}:{piece}" if piece else source, message)


@dataclass
class ImportedPiece:
    """One pattern piece as the file gives it, in metres, y up."""

    name: str
    sew: np.ndarray
    """sew line [m], shape (k, 2), counter-clockwise, not closed"""
    cut: np.ndarray | None = None
    """cut line [m], shape (c, 2), counter-clockwise; None where the file has none"""
    holes: list[np.ndarray] = field(default_factory=list)
    """sew lines of holes and cut-outs [m], each (h, 2), clockwise"""
    notches: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    """[m] notch positions, (n, 2): each notch's point nearest the sew line"""
    grain: np.ndarray | None = None
    """[m] grain line, tail to head, (2, 2)"""
    drills: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    """[m] drill holes, (d, 2)"""
    internal: list[np.ndarray] = field(default_factory=list)
    """[m] internal lines (darts, placement lines), each (m, 2) open"""
    cut_count: int = 1
    mirrored: bool = False
    """'cut 2' as a left and a right: the second copy is the mirror image"""
    on_fold: bool = False
    """the piece is a half, cut on the fold (FreeSewing 'onFold'): mirror about its fold edge"""
    texts: list[str] = field(default_factory=list)
    role: str = ""
    """what the piece is ('front', 'sleeve', ... as ``couture.pattern.sewing.role_of``
    reads names); '' from its name"""
    center_at_min_x: bool | None = True
    """the piece's centre (front/back) edge is its left one as drawn (FreeSewing parts are
    drafted with the centre at x = 0, to the left); None: unknown (a DXF), the side with
    the longer straight vertical edge"""


# ------------------------------------------------------------------ shared checks


def _close(P: np.ndarray, source: str, name: str, what: str = "outline") -> np.ndarray:
    """P without its closing vertex; ImportError_ when its ends do not meet."""
    if len(P) >= 2 and np.linalg.norm(P[0] - P[-1]) <= CLOSE_TOL:
        P = P[:-1]
    elif len(P) >= 2 and np.linalg.norm(P[0] - P[-1]) > CLOSE_TOL:
        gap = float(np.linalg.norm(P[0] - P[-1]))
        raise ImportError_(source, name, f"open {what}: its ends are {gap * 1000:.1f} mm apart (not a closed piece)")
    keep = np.ones(len(P), bool)
    keep[1:] = np.linalg.norm(np.diff(P, axis=0), axis=1) > 1e-9
    return P[keep]


def check_piece(P: np.ndarray, source: str, name: str, units_hint: str = "") -> np.ndarray:
    """The outline counter-clockwise, after checking it is a piece: at least 3
    vertices, finite, not self-intersecting, between ``MIN_PIECE`` and ``MAX_PIECE``."""
    P = _decimate(np.asarray(P, float))
    if len(P) < 3 or not np.all(np.isfinite(P)):
        raise ImportError_(source, name, f"outline has {len(P)} usable vertices (a piece needs at least 3)")
    size = float((P.max(0) - P.min(0)).max())
    if size < MIN_PIECE or size > MAX_PIECE:
        raise ImportError_(
            source,
            name,
            f"piece is {size * 1000:.4g} mm across, outside {MIN_PIECE * 1000:g} mm .. {MAX_PIECE:g} m: "
            f"wrong units? {units_hint or 'give --units mm|cm|in'}",
        )
    hits = self_intersections(P)
    if hits:
        i, j = hits[0]
        raise ImportError_(
            source, name, f"outline self-intersects (edges {i} and {j}, near ({P[i][0]:.3f}, {P[i][1]:.3f}) m)"
        )
    if abs(signed_area(P)) < 1e-8:
        raise ImportError_(source, name, "outline has no area")
    return P if signed_area(P) > 0 else P[::-1].copy()


def _decimate(P: np.ndarray, d: float = 3e-4) -> np.ndarray:
    """P without the vertices closer than d [m] to the previous kept one (a
    densely flattened curve; corners survive: they are kept vertices)."""
    if len(P) < 4 or not np.all(np.isfinite(P)):
        return P
    keep = [0]
    for i in range(1, len(P)):
        if np.linalg.norm(P[i] - P[keep[-1]]) >= d:
            keep.append(i)
    return P[keep]


def _parse_cut(texts: list[str]) -> tuple[int, bool, bool]:
    """(cut count, mirrored pair, on fold) from a piece's texts."""
    count, mirrored, fold = 1, False, False
    for t in texts:
        low = t.lower()
        m = re.search(r"(?:quantity|cut)\s*[:,]?\s*(\d+)", low)
        if m:
            count = max(1, int(m.group(1)))
            mirrored = mirrored or count == 2 and ("mirror" in low or "pair" in low or "quantity" in low)
        if "onfold" in low or "on fold" in low or "cutonfold" in low:
            fold = True
    if count == 2 and not fold:
        mirrored = True  # 'cut 2' of one piece: a left and a right
    return count, mirrored, fold


# ------------------------------------------------------------------ DXF


@dataclass
class _Poly:
    layer: str
    pts: np.ndarray  # file units
    closed: bool


def _looks_like_dxf(data: bytes) -> bool:
    head = data[:4096].decode("latin-1", errors="replace")
    return bool(re.search(r"^\s*0\s*\r?\n\s*SECTION", head, re.M)) or head.startswith("AutoCAD Binary DXF")


def _dxf_entities(doc) -> tuple[list[_Poly], list[tuple[str, np.ndarray]], list[tuple[str, str, np.ndarray]]]:
    """Every polyline (flattened), point and text of the drawing in world
    coordinates: block contents through their INSERTs, plus loose entities.
    Duplicates (the same block inserted once per piece, the same line on two
    layers) are dropped."""
    from ezdxf import path as dxfpath

    polys: list[_Poly] = []
    points: list[tuple[str, np.ndarray]] = []
    texts: list[tuple[str, str, np.ndarray]] = []
    seen: set = set()

    def visit(e, depth=0):
        t = e.dxftype()
        layer = str(e.dxf.get("layer", "0"))
        if t == "INSERT":
            if depth > 8:
                return
            try:
                for v in e.virtual_entities():
                    visit(v, depth + 1)
            except Exception:  # noqa: BLE001  # a broken block reference: its entities are skipped
                return
        elif t in ("LINE", "LWPOLYLINE", "POLYLINE", "SPLINE", "ARC", "CIRCLE", "ELLIPSE"):
            try:
                p = dxfpath.make_path(e)
                P = np.array([(v.x, v.y) for v in p.flattening(FLATTEN)], float)
            except Exception:  # noqa: BLE001  # an entity ezdxf cannot turn into a path (e.g. a 3D mesh)
                return
            if len(P) < 2:
                return
            closed = bool(t in ("CIRCLE",) or getattr(e, "is_closed", False) or np.allclose(P[0], P[-1]))
            if closed and not np.allclose(P[0], P[-1]):
                P = np.vstack([P, P[:1]])
            key = (layer, closed, np.round(P, 4).tobytes())
            if key not in seen:
                seen.add(key)
                polys.append(_Poly(layer, P, closed))
        elif t == "POINT":
            q = np.array([e.dxf.location.x, e.dxf.location.y])
            key = (layer, "pt", np.round(q, 4).tobytes())
            if key not in seen:
                seen.add(key)
                points.append((layer, q))
        elif t in ("TEXT", "MTEXT", "ATTRIB"):
            s = e.plain_text() if t == "MTEXT" else str(e.dxf.get("text", ""))
            ins = e.dxf.get("insert", (0.0, 0.0))
            q = np.array([ins[0], ins[1]], float)
            key = (layer, s, np.round(q, 4).tobytes())
            if key not in seen and s.strip():
                seen.add(key)
                texts.append((layer, s.strip(), q))

    for e in doc.modelspace():
        visit(e)
    return polys, points, texts


def _dxf_units(doc, units: str | None, sizes: list[float]) -> tuple[float, str]:
    """[m] per drawing unit and how it was decided: ``units`` if given, else
    $INSUNITS, else the first of mm, cm, in that makes the largest piece a
    garment piece (5 cm .. 2.5 m)."""
    if units is not None:
        if units not in UNITS:
            raise PatternError("units", f"units {units!r} are not one of {sorted(UNITS)}")
        return UNITS[units], f"--units {units}"
    code = doc.header.get("$INSUNITS", 0)
    if code in _INSUNITS:
        return UNITS[_INSUNITS[code]], f"$INSUNITS {code} ({_INSUNITS[code]})"
    big = max(sizes) if sizes else 0.0
    for name in ("mm", "cm", "in"):
        if 0.05 <= big * UNITS[name] <= 2.5:
            return UNITS[name], f"no $INSUNITS: {name} detected from the piece sizes"
    return UNITS["mm"], "no $INSUNITS: mm assumed"


def read_dxf(
    path: str | Path, units: str | None = None, seam_allowance: float = 0.0, source: str | None = None
) -> list[ImportedPiece]:
    """Pieces of an AAMA/ASTM DXF (module docstring). ``units``: 'mm', 'cm',
    'in' or 'm' when the file has no (or a wrong) $INSUNITS; ``seam_allowance``
    [m]: what a piece with a cut line but no sew line has beyond its sew line."""
    import ezdxf

    src = source or str(path)
    data = Path(path).read_bytes()
    if not _looks_like_dxf(data):
        raise ImportError_(src, "", "not a DXF file (no SECTION header)")
    try:
        doc = ezdxf.readfile(str(path))
    except Exception as e:  # noqa: BLE001  # ezdxf raises several types for a broken file
        raise ImportError_(src, "", f"not a readable DXF file: {type(e).__name__}: {e}") from None
    polys, points, texts = _dxf_entities(doc)
    closed = [p for p in polys if p.closed and len(p.pts) >= 4]
    cuts = [p for p in closed if p.layer == "1"]
    sews = [p for p in closed if p.layer == "14"]
    if not cuts and not sews:
        # no AAMA layers: every closed polyline not inside another is a piece's sew line
        sews = [p for p in closed]
    outers_from = cuts if cuts else sews

    def inside(a: _Poly, b: _Poly) -> bool:
        """a lies inside b (its vertices, up to a few on b's boundary)"""
        return bool(point_in_polygon(a.pts[:-1], b.pts[:-1]).mean() > 0.9) and abs(signed_area(a.pts)) < abs(
            signed_area(b.pts)
        )

    outers = [p for p in outers_from if not any(q is not p and inside(p, q) for q in outers_from)]
    if not outers:
        open_on = [p for p in polys if p.layer in ("1", "14") and not p.closed]
        if open_on:
            gap = float(np.linalg.norm(open_on[0].pts[0] - open_on[0].pts[-1]))
            raise ImportError_(
                src, "piece 1", f"open outline on layer {open_on[0].layer}: its ends are {gap:.4g} units apart"
            )
        raise ImportError_(src, "", "no pieces found: no closed outline on layer 1 (cut) or 14 (sew), or anywhere")
    sizes = [float((p.pts.max(0) - p.pts.min(0)).max()) for p in outers]
    unit, how = _dxf_units(doc, units, sizes)
    hint = f"units: {how}; give --units mm|cm|in"

    pieces: list[ImportedPiece] = []
    names: dict[str, int] = {}
    taken_text: set[int] = set()
    for i, outer in enumerate(sorted(outers, key=lambda p: (p.pts[:, 0].min(), p.pts[:, 1].min()))):
        poly_o = outer.pts[:-1]
        mine_texts = [
            (j, t) for j, (_, t, q) in enumerate(texts) if j not in taken_text and point_in_polygon(q[None], poly_o)[0]
        ]
        taken_text.update(j for j, _ in mine_texts)
        tx = [t for _, t in mine_texts]
        name = _dxf_name(tx) or f"piece{i + 1}"
        names[name] = names.get(name, 0) + 1
        if names[name] > 1:
            name = f"{name}_{names[name]}"
        el = name
        inner_sews = [p for p in sews if p is not outer and inside(p, outer)]
        if outer.layer != "1":  # a sew line (layer 14, or any closed line in a file without AAMA layers)
            sew_lines = [outer] + inner_sews
        else:
            sew_lines = inner_sews
        cut = _close(outer.pts * unit, src, el, "cut line") if outer.layer == "1" else None
        if sew_lines:
            sew_lines.sort(key=lambda p: -abs(signed_area(p.pts)))
            sew = _close(sew_lines[0].pts * unit, src, el)
            hole_lines = [p for p in sew_lines[1:] if inside(p, sew_lines[0])]
        else:
            assert cut is not None
            sew = _inset(check_piece(cut, src, el, hint), seam_allowance, src, el)
            hole_lines = []
        sew = check_piece(sew, src, el, hint)
        holes = []
        for h in hole_lines:
            H = _close(h.pts * unit, src, el, "hole")
            holes.append(H if signed_area(H) < 0 else H[::-1].copy())
        if not hole_lines:  # openings drawn only as cut lines (layer 11, or layer 1 inside the piece)
            for p in closed:
                if p.layer in ("11",) or (p.layer == "1" and p is not outer and inside(p, outer)):
                    if inside(p, outer):
                        H = _close(p.pts * unit, src, el, "cut-out")
                        holes.append(H if signed_area(H) < 0 else H[::-1].copy())
        notches, grain, internal = [], None, []
        for p in polys:
            if p.closed or p.layer not in ("4", "7", "8"):
                continue
            if not point_in_polygon(p.pts[:1], poly_o)[0] and not point_in_polygon(p.pts[-1:], poly_o)[0]:
                if not _near(p.pts, poly_o):
                    continue
            P = p.pts * unit
            if p.layer == "4":
                d0 = _dist_to(P[0], sew)
                d1 = _dist_to(P[-1], sew)
                notches.append(P[0] if d0 <= d1 else P[-1])
            elif p.layer == "7" and grain is None:
                grain = np.array([P[0], P[-1]])
            elif p.layer == "8":
                internal.append(P)
        for layer, q in points:
            if layer == "4" and point_in_polygon(q[None], poly_o)[0]:
                notches.append(q * unit)
        drills = [q * unit for layer, q in points if layer == "13" and point_in_polygon(q[None], poly_o)[0]]
        count, mirrored, fold = _parse_cut(tx)
        pieces.append(
            ImportedPiece(
                name=name,
                sew=sew,
                cut=check_piece(cut, src, el, hint) if cut is not None else None,
                holes=holes,
                notches=np.array(notches, float).reshape(-1, 2),
                grain=grain,
                drills=np.array(drills, float).reshape(-1, 2),
                internal=internal,
                cut_count=count,
                mirrored=mirrored,
                on_fold=fold,
                texts=tx,
                center_at_min_x=None,
            )
        )
    return pieces


def _dxf_name(texts: list[str]) -> str:
    for t in texts:
        if t.lower().startswith("piece name:"):
            return t.split(":", 1)[1].strip()
    for t in texts:
        low = t.lower()
        if ":" in t or re.match(r"^(cut|quantity|size|style)\b", low):
            continue
        return t
    return ""


def _near(P: np.ndarray, poly: np.ndarray, tol: float = 1.0) -> bool:
    return bool(min(_dist_to(q, poly) for q in (P[0], P[-1])) < tol)


def _dist_to(q: np.ndarray, P: np.ndarray) -> float:
    """Distance from point q to the closed polyline P."""
    A = P
    B = np.roll(P, -1, axis=0)
    AB = B - A
    t = np.clip(((q - A) * AB).sum(1) / np.maximum((AB * AB).sum(1), 1e-300), 0, 1)
    return float(np.linalg.norm(A + t[:, None] * AB - q, axis=1).min())


def _inset(cut: np.ndarray, d: float, source: str, name: str) -> np.ndarray:
    """The cut line moved inward by the seam allowance d [m] (the sew line)."""
    if d <= 0:
        return cut
    from shapely import Polygon

    g = Polygon(cut).buffer(-d, join_style="mitre", mitre_limit=4.0)
    if g.is_empty or g.geom_type != "Polygon":
        raise ImportError_(source, name, f"a seam allowance of {d * 1000:g} mm leaves no piece inside the cut line")
    P = np.array(g.exterior.coords)[:-1]
    return P if signed_area(P) > 0 else P[::-1].copy()


# ------------------------------------------------------------------ SVG

_FS_PART = re.compile(r"^fs-stack-(?P<design>[^.]+)\.(?P<part>.+?)-part-")


def read_svg(path: str | Path, units: str | None = None, source: str | None = None) -> list[ImportedPiece]:
    """Pieces of a FreeSewing SVG, or of any SVG whose pieces are closed paths
    (one per group, the largest a piece's outline). Units from the SVG's
    width/height; ``units`` overrides what one user unit is."""
    from svgelements import SVG, Circle, Group, Shape, Text, Use
    from svgelements import Path as SvgPath

    src = source or str(path)
    data = Path(path).read_bytes()
    if b"<svg" not in data[:65536]:
        raise ImportError_(src, "", "not an SVG file (no <svg> element)")
    try:
        svg = SVG.parse(str(path), reify=True)
    except Exception as e:  # noqa: BLE001  # the XML parser and svgelements raise many types
        raise ImportError_(src, "", f"not a readable SVG file: {type(e).__name__}: {e}") from None
    # svgelements gives px at 96 per inch after every transform and the viewBox
    scale = 0.0254 / 96.0
    if units is not None:
        if units not in UNITS:
            raise PatternError("units", f"units {units!r} are not one of {sorted(UNITS)}")
        vb = getattr(svg, "viewbox", None)
        user_px = 1.0
        if vb is not None and vb.width and svg.width:
            user_px = float(svg.width) / float(vb.width)
        scale = UNITS[units] / user_px
    parts: dict[str, dict] = {}

    def part_of(stack: list[str]) -> str:
        for gid in reversed(stack):
            m = _FS_PART.match(gid or "")
            if m:
                return m.group("part")
        return next((g for g in reversed(stack) if g), "")

    def walk(g, stack: list[str]) -> None:
        for e in g:
            if isinstance(e, Group):
                walk(e, stack + [str(e.id or "")])
                continue
            key = part_of(stack)
            d = parts.setdefault(
                key, {"seam": [], "other": [], "texts": [], "notches": [], "notch_lines": [], "grain": []}
            )
            cls = str(e.values.get("class") or "").split()
            if isinstance(e, Text):
                d["texts"].append(str(e.text or ""))
            elif isinstance(e, Use):
                href = str(e.values.get("href") or e.values.get("{http://www.w3.org/1999/xlink}href") or "")
                if "notch" in href:
                    try:
                        bb = e.bbox()
                        if bb is not None:
                            d["notches"].append([(bb[0] + bb[2]) / 2, (bb[1] + bb[3]) / 2])
                    except Exception:  # noqa: BLE001  # a use without geometry
                        pass
            elif isinstance(e, (SvgPath, Shape)) and not isinstance(e, Circle):
                try:
                    P = _flatten(SvgPath(e) if not isinstance(e, SvgPath) else e)
                except Exception as err:  # noqa: BLE001  # svgelements fails on malformed path data in many ways
                    raise ImportError_(
                        src, key or "", f"path {e.id or ''} cannot be read: {type(err).__name__}: {err}"
                    ) from None
                if len(P) < 2:
                    continue
                if "sa" in cls or "help" in cls or "hidden" in cls or "cut" in cls or "cutout" in cls:
                    continue  # seam allowance, construction lines, cut lines (couture's own export)
                closed = len(P) >= 4 and np.linalg.norm(P[0] - P[-1]) * scale <= CLOSE_TOL
                is_seam = ("fabric" in cls and "stroke-sm" not in cls) or "sew" in cls
                if "notch" in cls:
                    d["notch_lines"].append(P)
                elif "grain" in cls:
                    d["grain"].append(P)
                else:
                    (d["seam"] if is_seam or (not cls and closed) else d["other"]).append((P, closed))

    walk(svg, [])
    pieces: list[ImportedPiece] = []
    hint = "units from the SVG's width/height; give --units mm|cm|in"
    grouped = any(k and d["seam"] for k, d in parts.items())
    for key, d in parts.items():
        if not d["seam"] or (grouped and not key):
            continue  # outside every group, beside grouped pieces: a scale box, a legend
        name = key or f"piece{len(pieces) + 1}"
        outlines = sorted(d["seam"], key=lambda pc: -abs(signed_area(pc[0])))
        P, closed = outlines[0]
        Pm = P * scale * np.array([1.0, -1.0])  # SVG y down -> y up
        if not closed:
            gap = float(np.linalg.norm(Pm[0] - Pm[-1]))
            raise ImportError_(src, name, f"open outline: its ends are {gap * 1000:.1f} mm apart")
        sew = check_piece(_close(Pm, src, name), src, name, hint)
        holes = []
        for Q, qc in outlines[1:]:
            Qm = Q * scale * np.array([1.0, -1.0])
            if qc and point_in_polygon(Qm[:-1], sew).all():
                H = _close(Qm, src, name, "hole")
                holes.append(H if signed_area(H) < 0 else H[::-1].copy())
        internal = [Q * scale * np.array([1.0, -1.0]) for Q, _ in d["other"]]
        flip = scale * np.array([1.0, -1.0])
        notch_pts = [np.asarray(q, float) * flip for q in d["notches"]]
        for Q in d["notch_lines"]:  # a slit from the cut line inward: its end nearest the sew line
            a, b = Q[0] * flip, Q[-1] * flip
            notch_pts.append(a if _dist_to(a, sew) <= _dist_to(b, sew) else b)
        notches = np.array(notch_pts, float).reshape(-1, 2)
        grain = np.array([d["grain"][0][0], d["grain"][0][-1]]) * flip if d["grain"] else None
        count, mirrored, fold = _parse_cut(d["texts"])
        pieces.append(
            ImportedPiece(
                name=name,
                sew=sew,
                holes=holes,
                notches=notches,
                grain=grain,
                internal=internal,
                cut_count=count,
                mirrored=mirrored,
                on_fold=fold,
                texts=list(d["texts"]),
            )
        )
    if not pieces:
        raise ImportError_(
            src, "", "no pieces found: no closed seam-line path ('fabric' class or unclassed) in any group"
        )
    return pieces


def _flatten(p, tol: float = 2.0) -> np.ndarray:
    """Points of an svgelements Path [px], curves sampled every ``tol`` px or finer
    (the first sub-path only: a piece's outline is one)."""
    from svgelements import Close, Line, Move

    out: list[tuple[float, float]] = []
    for seg in p:
        if isinstance(seg, Move):
            if out:
                break
            out.append((seg.end.x, seg.end.y))
            continue
        if isinstance(seg, (Line, Close)):
            if seg.end is not None:
                out.append((seg.end.x, seg.end.y))
            continue
        # the control polygon is no shorter than the curve: enough samples, no arc-length integral
        ctrl = [
            q
            for q in (
                seg.start,
                getattr(seg, "control1", None),
                getattr(seg, "control2", None),
                getattr(seg, "control", None),
                seg.end,
            )
            if q is not None
        ]
        L = sum(abs(complex(b.x - a.x, b.y - a.y)) for a, b in zip(ctrl, ctrl[1:], strict=False))
        n = max(2, min(500, math.ceil(L / tol)))
        for t in np.linspace(0, 1, n + 1)[1:]:
            q = seg.point(float(t))
            out.append((q.x, q.y))
    return np.array(out, float).reshape(-1, 2)


# ------------------------------------------------------------------ any file


def read_pattern(
    path: str | Path, units: str | None = None, seam_allowance: float = 0.0, source: str | None = None
) -> list[ImportedPiece]:
    """Pieces of a DXF or SVG file, told apart by content (not the file name)."""
    p = Path(path)
    src = source or str(path)
    try:
        head = p.read_bytes()[:65536]
    except OSError as e:
        raise ImportError_(src, "", f"cannot read: {e.strerror or e}") from None
    if not head.strip():
        raise ImportError_(src, "", "the file is empty")
    if b"<svg" in head:
        return read_svg(p, units, src)
    if _looks_like_dxf(head):
        return read_dxf(p, units, seam_allowance, src)
    raise ImportError_(src, "", "neither a DXF (no SECTION header) nor an SVG (no <svg> element)")


def piece_length(P: np.ndarray) -> float:
    """Perimeter [m] of a closed outline."""
    return polyline_length(P, closed=True)

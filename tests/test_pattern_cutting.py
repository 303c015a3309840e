"""Pieces to cut: seam allowances, notches, grain lines, labels, read back from
the DXF with ezdxf; the tiled PDF's pages; ``couture export``.

Every check reads the written file and measures it against the drafted
pattern with its own geometry (point-to-polyline distances, ray casts, arc
lengths), not with the exporter's helpers."""

from __future__ import annotations

import math
import re
import zlib
from pathlib import Path

import ezdxf
import numpy as np
import pytest

from couture.pattern import PatternError, draft
from couture.pattern.cutting import CutSpec, cut_pieces, offset_polygon
from couture.pattern.draft import segment_points
from couture.pattern.geometry import point_in_polygon, self_intersections
from couture.pattern.io import export_dxf, export_pdf_tiled, export_svg, load_design

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "couture/pattern/examples").glob("*.json"))
IDS = [p.stem for p in EXAMPLES]
SEAM, HEM = 0.01, 0.03
# one per-seam width per example, on a segment that design has (a sewn one where there is one)
OVERRIDE = {
    "default_skirt": "side_right",
    "skirt_edited": "waist",
    "dress": "neck",
    "dress_waist": "waist_center",
    "shirt": "shoulder_right",
    "shirt_set_in": "shoulder_right",
}
OVERRIDE_W = 0.015


def _override(stem: str) -> dict[str, float]:
    return {OVERRIDE.get(stem, "inseam"): OVERRIDE_W}


def _blocks(path: Path) -> dict[str, dict]:
    """name -> {layer: [entities]} of an AAMA DXF, coordinates in metres, plus the texts."""
    doc = ezdxf.readfile(str(path))
    assert doc.header["$INSUNITS"] == 4
    out = {}
    for ref in doc.modelspace().query("INSERT"):
        layers: dict[str, list] = {}
        texts = []
        for e in doc.blocks[ref.dxf.name]:
            t = e.dxftype()
            if t == "POLYLINE":
                g = np.array([(v.dxf.location.x, v.dxf.location.y) for v in e.vertices]) / 1000
            elif t == "LINE":
                g = np.array([[e.dxf.start.x, e.dxf.start.y], [e.dxf.end.x, e.dxf.end.y]]) / 1000
            elif t == "POINT":
                g = np.array([e.dxf.location.x, e.dxf.location.y]) / 1000
            elif t == "TEXT":
                g = e.dxf.text
                texts.append((e.dxf.layer, e.dxf.text))
            else:
                continue
            layers.setdefault(f"{e.dxf.layer}:{t}", []).append(g)
        name = next(s.split(":", 1)[1].strip() for _, s in texts if s.startswith("Piece Name:"))
        out[name] = {"layers": layers, "texts": texts}
    return out


def _dist_to_polyline(q: np.ndarray, P: np.ndarray, closed: bool = True) -> np.ndarray:
    """Distance of each point q (m, 2) to the polyline P."""
    A = P
    B = np.roll(P, -1, axis=0) if closed else P[1:]
    if not closed:
        A = P[:-1]
    E = B - A
    t = np.clip(((q[:, None] - A[None]) * E[None]).sum(-1) / np.maximum((E * E).sum(-1), 1e-300), 0, 1)
    return np.linalg.norm(q[:, None] - (A[None] + t[..., None] * E[None]), axis=-1).min(1)


def _expected_widths(pattern, stem):
    """(panel, segment) -> width, from the rules: the named seam's width on both
    of its sides, hems deeper, the rest the default."""
    over = _override(stem)
    out = {}
    for p in pattern.panels:
        for s in p.segments:
            out[(p.name, s.name)] = over.get(s.name, HEM if s.name in ("hem", "cuff") else SEAM)
    named = {k for k in out if k[1] in over}
    for sp in pattern.seams:
        a, b = (sp.a_panel, sp.a_segment), (sp.b_panel, sp.b_segment)
        if a in named and b not in named:
            out[b] = out[a]
        elif b in named and a not in named:
            out[a] = out[b]
    return out


@pytest.mark.parametrize("path", EXAMPLES, ids=IDS)
def test_allowance_widths_read_back(tmp_path, path):
    """Away from corners the cut line lies exactly the requested width outside the
    sew line (the named seam's width on both its sides, hems 3 cm, the rest 1 cm);
    the cut line is simple and holds the whole sew line."""
    pattern = draft(load_design(path))
    spec = CutSpec(seam_allowance=SEAM, hem_allowance=HEM, widths=_override(path.stem), group=False)
    export_dxf(pattern, tmp_path / "p.dxf", spec=spec)
    blocks = _blocks(tmp_path / "p.dxf")
    assert set(blocks) == {p.name for p in pattern.panels}
    want = _expected_widths(pattern, path.stem)
    assert OVERRIDE_W in want.values()
    for panel in pattern.panels:
        L = blocks[panel.name]["layers"]
        (cut,) = L["1:POLYLINE"]
        sew = max(L["14:POLYLINE"], key=len)
        assert np.abs(sew - panel.outline).max() < 1e-4  # the drafted sew line, 0.1 mm
        assert self_intersections(cut) == []
        assert point_in_polygon(panel.outline, cut).all()
        outline_segs = [s for s in panel.segments if s.hole < 0]
        # boundary dart legs: bridged by the cut line, so not measured
        legs = [segment_points(panel, s) for s in outline_segs if s.name.startswith("dart:")]
        dart_legs = np.vstack(legs) if legs else np.zeros((0, 2))
        measured = {}
        for s in outline_segs:
            if s.name.startswith("dart:"):
                continue
            P = segment_points(panel, s)
            mid = 0.5 * (P[1:] + P[:-1])
            w = want[(panel.name, s.name)]
            # away from the segment's own ends, where its offset meets its neighbours' (a corner
            # across the panel, such as the trousers' band's waist split 3.5 cm below its hem, does not end it)
            ends = np.array([panel.outline[s.start], panel.outline[s.stop]])
            far = np.linalg.norm(mid[:, None] - ends[None], axis=-1).min(1) > 2 * w + 0.005
            far &= _dist_to_polyline(mid, dart_legs, closed=False) > 1e-9 if len(dart_legs) else True
            if not far.any():
                continue
            d = _dist_to_polyline(mid[far], cut)
            assert np.abs(d - w).max() < 1e-4, (panel.name, s.name, w, d.min(), d.max())
            measured[s.name] = float(np.median(d))
        hems = [v for k, v in measured.items() if k in ("hem", "cuff")]
        seams = [v for k, v in measured.items() if k not in ("hem", "cuff")]
        # both measured on every panel that has a hem (a waist-seamed dress's bodice has none)
        has_hem = any(s.name in ("hem", "cuff") for s in outline_segs)
        assert seams and (hems or not has_hem), (panel.name, measured)
        if hems:
            assert min(hems) > max(seams) + 0.01  # the hem is deeper than every seam


def _ray_hit(P: np.ndarray, o: np.ndarray, d: np.ndarray) -> np.ndarray:
    """First point where the ray o + t d (t >= 0) meets the closed polyline P."""
    A, B = P, np.roll(P, -1, axis=0)
    E = B - A
    den = d[0] * E[:, 1] - d[1] * E[:, 0]
    R = A - o
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (R[:, 0] * E[:, 1] - R[:, 1] * E[:, 0]) / den
        u = (R[:, 0] * d[1] - R[:, 1] * d[0]) / den
    ok = (np.abs(den) > 1e-15) & (t >= -1e-9) & (u >= -1e-9) & (u <= 1 + 1e-9)
    assert ok.any(), "a notch that points at no sew line"
    return o + t[ok].min() * d


def _arc_of(P: np.ndarray, q: np.ndarray) -> float | None:
    """Arc length along the open polyline P of the point q, None when q is not on it."""
    A, B = P[:-1], P[1:]
    E = B - A
    t = np.clip(((q - A) * E).sum(-1) / np.maximum((E * E).sum(-1), 1e-300), 0, 1)
    d = np.linalg.norm(q - (A + t[:, None] * E), axis=1)
    i = int(np.argmin(d))
    if d[i] > 1e-6:
        return None
    c = np.concatenate([[0.0], np.cumsum(np.linalg.norm(E, axis=1))])
    return float(c[i] + t[i] * np.linalg.norm(E[i]))


def _unique(v: list[float], tol: float = 1e-4) -> np.ndarray:
    out: list[float] = []
    for x in sorted(v):
        if not out or x - out[-1] > tol:
            out.append(x)
    return np.array(out)


@pytest.mark.parametrize("path", EXAMPLES, ids=IDS)
def test_notches_match_across_seams(tmp_path, path):
    """Each notch read back (layer 4, from the cut line inward) points at a sew
    point; on both sides of every seam those points sit at the same arc length
    from the seam's matching ends (b walked backwards when the seam says so),
    within 0.5 mm; eased seams (different lengths) at the same fraction. Each
    side has its two ends, its midpoint and (if longer) the point 7 cm from its start notched."""
    pattern = draft(load_design(path))
    # a notch 7 cm from each seam's start tells its ends apart: b must be walked the right way
    export_dxf(pattern, tmp_path / "p.dxf", spec=CutSpec(group=False, notch_distances=(0.07,)))
    blocks = _blocks(tmp_path / "p.dxf")
    hits = {}
    for panel in pattern.panels:
        notches = blocks[panel.name]["layers"]["4:LINE"]
        pts = []
        for n in notches:
            d = (n[1] - n[0]) / np.linalg.norm(n[1] - n[0])
            assert 0 < np.linalg.norm(n[1] - n[0]) <= 0.006 + 1e-9
            pts.append(_ray_hit(panel.outline, n[0], d))
        hits[panel.name] = np.array(pts)
    n_seams = 0
    for sp in pattern.seams:
        if sp.a_segment.startswith("dart:"):
            continue
        n_seams += 1
        pa, pb = pattern.panel(sp.a_panel), pattern.panel(sp.b_panel)
        A = segment_points(pa, next(s for s in pa.segments if s.name == sp.a_segment))
        B = segment_points(pb, next(s for s in pb.segments if s.name == sp.b_segment))
        if sp.reverse:
            B = B[::-1]
        La = float(np.linalg.norm(np.diff(A, axis=0), axis=1).sum())
        Lb = float(np.linalg.norm(np.diff(B, axis=0), axis=1).sum())
        sa = _unique([s for q in hits[pa.name] if (s := _arc_of(A, q)) is not None])
        sb = _unique([s for q in hits[pb.name] if (s := _arc_of(B, q)) is not None])
        assert len(sa) == len(sb) >= 3, (sp, sa, sb)
        assert sa[0] < 1e-4 and abs(sa[-1] - La) < 1e-4 and np.abs(sa - La / 2).min() < 5e-4
        if La > 0.07 + 1e-3:  # a seam shorter than 7 cm (a collar band's end, the waistband's sides) has no such notch
            assert np.abs(sa - 0.07).min() < 5e-4
        if abs(La - Lb) < 1e-3:
            np.testing.assert_allclose(sa, sb, atol=5e-4, err_msg=str(sp))
        else:  # eased: proportional, as the seam is sewn
            np.testing.assert_allclose(sa / La, sb / Lb, atol=5e-4 / max(La, Lb), err_msg=str(sp))
    assert n_seams > 0


@pytest.mark.parametrize("path", EXAMPLES, ids=IDS)
def test_grain_lines_and_labels(tmp_path, path):
    """Per piece: one grain line along the panel's vertical inside the sew line,
    turn points on its lines' corners, the AAMA piece system texts, and cut
    counts that add up to the panels."""
    pattern = draft(load_design(path))
    spec = CutSpec(design_name=path.stem, size="B88")
    pieces = cut_pieces(pattern, spec)
    export_dxf(pattern, tmp_path / "p.dxf", spec=spec)
    blocks = _blocks(tmp_path / "p.dxf")
    assert set(blocks) == {p.name for p in pieces}
    total = 0
    for name, b in blocks.items():
        (g,) = b["layers"]["7:LINE"]
        v = g[1] - g[0]
        assert abs(v[0]) < 1e-9 and v[1] > 0  # straight grain: material +y
        sew = max(b["layers"]["14:POLYLINE"], key=len)
        assert point_in_polygon(g, sew).all()
        assert v[1] > 0.3 * np.ptp(sew[:, 1])
        # turn points (layer 2): corners of the cut and sew lines, at least the cut line's 4
        turns = np.array(b["layers"]["2:POINT"])
        (cut,) = b["layers"]["1:POLYLINE"]
        on_cut = _dist_to_polyline(turns, cut) < 1e-7
        assert on_cut.sum() >= 4
        lines = b["layers"]["14:POLYLINE"] + b["layers"].get("11:POLYLINE", [])
        assert (on_cut | np.any([_dist_to_polyline(turns, q) < 1e-7 for q in lines], axis=0)).all()
        texts = dict(s.split(": ", 1) for layer, s in b["texts"] if layer == "1")
        assert texts["Piece Name"] == name and texts["Size"] == "B88" and texts["Style Name"] == path.stem
        q = int(texts["Quantity"])
        assert any(layer == "15" and s.startswith(f"Cut {q}") for layer, s in b["texts"])
        total += q
    assert total == len(pattern.panels)
    if path.stem == "default_skirt":  # identical gores
        assert len(blocks) == 1
    if path.stem == "trousers":  # legs mirrored; the waistband's front and back alike
        assert len(blocks) == 2


def test_grain_follows_the_panel(tmp_path):
    pattern = draft(load_design(EXAMPLES[IDS.index("shirt")]))
    pattern.panel("front").grain = math.pi / 4  # bias cut
    export_dxf(pattern, tmp_path / "p.dxf", spec=CutSpec())
    (g,) = _blocks(tmp_path / "p.dxf")["front"]["layers"]["7:LINE"]
    v = (g[1] - g[0]) / np.linalg.norm(g[1] - g[0])
    np.testing.assert_allclose(v, [-math.sqrt(0.5), math.sqrt(0.5)], atol=1e-9)


def test_offset_polygon_closed_forms():
    """A rectangle with a 3 cm hem and 1 cm elsewhere is a rectangle (mitred
    corners); an L shape's inner corner is the two offset lines' crossing."""
    R = np.array([[0, 0], [0.4, 0], [0.4, 0.6], [0, 0.6]], float)
    Q = offset_polygon(R, np.array([0.03, 0.01, 0.01, 0.01]))
    np.testing.assert_allclose(np.sort(Q, axis=0)[[0, -1]], [[-0.01, -0.03], [0.41, 0.61]], atol=1e-9)
    assert len(Q) == 4
    Lp = np.array([[0, 0], [0.3, 0], [0.3, 0.1], [0.1, 0.1], [0.1, 0.3], [0, 0.3]], float)
    Q = offset_polygon(Lp, 0.02)
    assert len(Q) == 6 and self_intersections(Q) == []
    assert np.linalg.norm(Q - [0.12, 0.12], axis=1).min() < 1e-9
    # a slit narrower than twice the width closes over (no crossing cut line)
    V = np.array([[0, 0], [0.2, 0], [0.2, 0.2], [0.105, 0.2], [0.1, 0.05], [0.095, 0.2], [0, 0.2]], float)
    Q = offset_polygon(V, 0.01)
    assert self_intersections(Q) == [] and point_in_polygon(V, Q).all()


def test_bad_cut_specs_name_the_problem():
    pattern = draft(load_design(EXAMPLES[IDS.index("shirt")]))
    with pytest.raises(PatternError, match="no segment 'nek'"):
        cut_pieces(pattern, CutSpec(widths={"nek": 0.01}))
    with pytest.raises(PatternError, match="front:hem.*outside"):
        cut_pieces(pattern, CutSpec(widths={"front:hem": -0.01}))
    with pytest.raises(PatternError, match="seam_allowance.*outside"):
        cut_pieces(pattern, CutSpec(seam_allowance=10))
    with pytest.raises(PatternError, match="paper 'a3'"):
        export_pdf_tiled(pattern, "/nonexistent/x.pdf", "a3")


PAPER_MM = {"a4": (210.0, 297.0), "letter": (215.9, 279.4)}


def _pdf_pages(data: bytes) -> list[dict]:
    """Each page object's MediaBox and its content streams' text, by a plain read of the file."""
    objs = {int(m.group(1)): m.group(2) for m in re.finditer(rb"(\d+) 0 obj(.*?)endobj", data, re.S)}

    def stream(body: bytes) -> bytes:
        m = re.search(rb"stream\r?\n(.*?)\s*endstream", body, re.S)
        raw = m.group(1) if m else b""
        if b"FlateDecode" in body:
            if b"ASCII85Decode" in body:
                import base64

                raw = base64.a85decode(raw.strip().removeprefix(b"<~").removesuffix(b"~>"))
            raw = zlib.decompress(raw)
        return raw

    pages = []
    for body in objs.values():
        if re.search(rb"/Type\s*/Page(?![s\w])", body):
            box = [float(v) for v in re.search(rb"/MediaBox\s*\[([^\]]*)\]", body).group(1).split()]
            refs = re.search(rb"/Contents\s*(\d+) 0 R", body)
            pages.append({"box": box, "content": stream(objs[int(refs.group(1))]) if refs else b""})
    return pages


@pytest.mark.parametrize("paper", ["a4", "letter"])
@pytest.mark.parametrize("path", EXAMPLES, ids=IDS)
def test_tiled_pdf_pages(tmp_path, path, paper):
    """As many pages as it takes to cover the sheet (its size read from the SVG)
    with the printable areas overlapping by 1 cm; every page the paper's size;
    the first holds the 10 cm square at true scale."""
    pattern = draft(load_design(path))
    spec = CutSpec(design_name=path.stem, sheet_width=0.8)
    export_svg(pattern, tmp_path / "p.svg", spec=spec)
    head = (tmp_path / "p.svg").read_text().split("\n", 1)[0]
    W, H = (float(v) for v in re.search(r'width="([\d.]+)mm" height="([\d.]+)mm"', head).groups())
    cols, rows = export_pdf_tiled(pattern, tmp_path / "p.pdf", paper, spec=spec)
    pw, ph = (d - 2 * 10.0 for d in PAPER_MM[paper])  # 10 mm margins
    step_w, step_h = pw - 10.0, ph - 10.0  # 10 mm overlap
    want_cols = next(n for n in range(1, 100) if (n - 1) * step_w + pw >= W - 1e-6)
    want_rows = next(n for n in range(1, 100) if (n - 1) * step_h + ph >= H - 1e-6)
    assert (cols, rows) == (want_cols, want_rows)
    pages = _pdf_pages((tmp_path / "p.pdf").read_bytes())
    assert len(pages) == want_cols * want_rows > 1
    size_pt = [d / 25.4 * 72 for d in PAPER_MM[paper]]
    for pg in pages:
        assert pg["box"][2] - pg["box"][0] == pytest.approx(size_pt[0], abs=0.01)
        assert pg["box"][3] - pg["box"][1] == pytest.approx(size_pt[1], abs=0.01)
    square = re.findall(rb"(-?[\d.]+) (-?[\d.]+) (-?[\d.]+) (-?[\d.]+) re", pages[0]["content"])
    side = 0.1 / 0.0254 * 72
    assert any(abs(float(w) - side) < 0.01 and abs(float(h) - side) < 0.01 for _, _, w, h in square)
    assert b"A1" in pages[0]["content"] and b"cm" in pages[0]["content"]
    # no scaling on the page: only translations (1 0 0 1 x y cm) move the drawing
    for m in re.finditer(rb"(-?[\d.]+) (-?[\d.]+) (-?[\d.]+) (-?[\d.]+) (-?[\d.]+) (-?[\d.]+) cm", pages[0]["content"]):
        a, b, c, d = (float(v) for v in m.groups()[:4])
        assert (a, b, c, d) == (1, 0, 0, 1), m.group()


def test_cli_export(tmp_path, capsys):
    from couture.cli import main

    rc = main(
        [
            "export",
            str(EXAMPLES[IDS.index("shirt")]),
            "--out",
            str(tmp_path),
            "--format",
            "dxf",
            "pdf-tiled",
            "--paper",
            "letter",
            "--seam-allowance",
            "0.012",
            "--hem-allowance",
            "0.04",
            "--allowance",
            "neck=0.006",
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out
    assert "sleeve_left: Cut 2 - also sleeve_right" in out
    assert (tmp_path / "shirt.dxf").exists() and (tmp_path / "shirt-letter.pdf").exists()
    assert not (tmp_path / "shirt.svg").exists()
    blocks = _blocks(tmp_path / "shirt.dxf")
    texts = dict(s.split(": ", 1) for layer, s in blocks["front"]["texts"] if layer == "1")
    assert texts["Size"].startswith("B") and texts["Style Name"] == "shirt"
    pattern = draft(load_design(EXAMPLES[IDS.index("shirt")]))
    front = pattern.panel("front")
    (cut,) = blocks["front"]["layers"]["1:POLYLINE"]
    for seg, w in (("hem", 0.04), ("neck", 0.006), ("side_right", 0.012)):
        P = segment_points(front, next(s for s in front.segments if s.name == seg))
        q = 0.5 * (P[len(P) // 2] + P[len(P) // 2 - 1])
        assert _dist_to_polyline(q[None], cut)[0] == pytest.approx(w, abs=1e-4), seg
    assert main(["export", str(EXAMPLES[0]), "--out", str(tmp_path), "--allowance", "nope"]) == 1


@pytest.mark.parametrize("which", ["min", "max"])
def test_cut_lines_are_simple_at_option_extremes(which):
    """Every sloper with every option at its minimum (maximum): each cut line is a
    simple polygon holding its whole sew line, and no allowance is narrower than asked."""
    from couture.pattern import SLOPERS
    from schemas.design import Design, Sloper

    for kind, sd in SLOPERS.items():
        pattern = draft(Design(sloper=Sloper(kind=kind, params={o.name: getattr(o, which) for o in sd.options})))
        for pc in cut_pieces(pattern, CutSpec(group=False)):
            assert self_intersections(pc.cut) == [], (kind, pc.name)
            assert point_in_polygon(pc.sew, pc.cut).all(), (kind, pc.name)
            # every sew vertex at least the smallest width (1 cm) inside the cut line
            assert _dist_to_polyline(pc.sew, pc.cut).min() > SEAM - 1e-6, (kind, pc.name)

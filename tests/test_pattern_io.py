"""Pattern files: JSON round trip and schema, DXF round trip, SVG/PDF true scale, placement."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from couture.pattern import SLOPERS, PatternError, draft, place
from couture.pattern.geometry import point_in_polygon
from couture.pattern.io import (
    design_from_json,
    design_json_schema,
    design_to_json,
    export_dxf,
    export_pdf,
    export_svg,
    import_dxf,
    load_design,
    save_design,
)
from couture.pattern.validate import validate
from schemas.design import Design, Fabric, Sloper

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "couture/pattern/examples").glob("*.json"))


def test_examples_load_and_validate():
    assert {p.stem for p in EXAMPLES} >= {"default_skirt", "dress", "shirt", "trousers"}
    for path in EXAMPLES:
        validate(load_design(path))


def test_json_round_trip_and_schema(tmp_path):
    d = load_design(EXAMPLES[[p.stem for p in EXAMPLES].index("skirt_edited")])
    save_design(d, tmp_path / "d.json")
    assert load_design(tmp_path / "d.json") == d
    assert json.loads(design_to_json(d))["schema"] == "couture/design/v1"
    schema = design_json_schema()
    assert "$defs" in schema and "DesignFile" in json.dumps(schema)
    # the schema describes what we write: every top-level key is a known property
    props = schema["$defs"]["DesignFile"]["properties"]
    assert set(json.loads(design_to_json(d))) <= set(props)
    with pytest.raises(PatternError, match="^d.json: schema 'couture/design/v0'"):
        design_from_json(b'{"schema": "couture/design/v0", "design": {}}', "d.json")
    with pytest.raises(PatternError, match=r"^d.json: not a couture/design/v1 design: .*bogus"):
        design_from_json(b'{"schema": "couture/design/v1", "design": {"bogus": 1}}', "d.json")


@pytest.mark.parametrize(
    "text, at, what",
    [
        # `at`: the text from where the error is (its first character's line and column are named)
        ('{"schema": "couture/design/v1",\n "design": {"fabric": {"area_density": 0.1,}}}', "}}}", "trailing comma"),
        ('{"schema": "couture/design/v1",\n\n  "design": {"fabric": {"stretch_stiffness": NaN}}}', "NaN", "NaN"),
        ('{"design":\n {"fabric": {"stretch_stiffness": -Infinity}}}', "-Inf", "Infinity"),
        ('{"design": {"fabric": {"stretch_stiffness": 1e400}}}', "1e400", "beyond the float range"),
        ('{"design": {"sloper": ', "", "truncated"),
        ("", "", "empty"),
    ],
)
def test_json_errors_name_file_line_and_column(tmp_path, text, at, what):
    from couture.client import load_design as client_load_design

    offset = text.index(at) if at else len(text)
    line = text[:offset].count("\n") + 1
    column = offset - (text.rfind("\n", 0, offset) + 1) + 1
    path = tmp_path / "bad.json"
    path.write_text(text)
    for load in (load_design, client_load_design):  # the pattern library's and the CLI's / client's reader
        with pytest.raises(ValueError) as e:
            load(path)
        msg = str(e.value)
        assert msg.startswith(f"{path}:{line}:{column}: invalid JSON: ") and what in msg, msg


def test_written_json_is_standard():
    from couture.jsonout import dumps

    text = dumps({"residual": float("inf"), "r": [np.float32("nan"), np.float64(2.5)], "n": np.int64(3)})
    assert json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} written")) == {
        "residual": None,
        "r": [None, 2.5],
        "n": 3,
    }
    d = Design(fabric=Fabric(stretch_stiffness=float("nan")))
    assert b"NaN" not in design_to_json(d) and b"Infinity" not in design_to_json(d)


@pytest.mark.parametrize("units", ["mm", "in"])
def test_dxf_round_trip(tmp_path, units):
    p = draft(load_design(EXAMPLES[[q.stem for q in EXAMPLES].index("skirt_edited")]))
    export_dxf(p, tmp_path / "p.dxf", seam_allowance=0.01, units=units)
    pieces = import_dxf(tmp_path / "p.dxf")
    assert set(pieces) == {pn.name for pn in p.panels}
    for pn in p.panels:
        got = pieces[pn.name]
        assert np.abs(got["outline"] - pn.outline).max() < 1e-4  # 0.1 mm
        assert len(got["holes"]) == len(pn.holes)
        for a, b in zip(got["holes"], pn.holes, strict=True):
            assert np.abs(a - b).max() < 1e-4
        assert got["cut"] is not None and np.ptp(got["cut"][:, 0]) > np.ptp(pn.outline[:, 0])  # allowance outside
    import ezdxf

    doc = ezdxf.readfile(tmp_path / "p.dxf")
    assert doc.header["$INSUNITS"] == (4 if units == "mm" else 1)
    assert len(doc.modelspace().query("INSERT")) == len(p.panels)


def test_svg_and_pdf_true_scale(tmp_path):
    p = draft(Design())
    export_svg(p, tmp_path / "p.svg", seam_allowance=0.01)
    root = ET.parse(tmp_path / "p.svg").getroot()
    w, h = root.get("width"), root.get("height")
    assert w.endswith("mm") and h.endswith("mm")
    vb = [float(v) for v in root.get("viewBox").split()]
    assert abs(vb[2] - float(w[:-2])) < 1e-6 and abs(vb[3] - float(h[:-2])) < 1e-6  # 1 user unit = 1 mm
    sq = next(e for e in root.iter() if e.get("id") == "scale_check")
    assert float(sq.get("width")) == pytest.approx(100.0) and float(sq.get("height")) == pytest.approx(100.0)
    size = export_pdf(p, tmp_path / "p.pdf", seam_allowance=0.01)
    data = (tmp_path / "p.pdf").read_bytes()
    assert data.startswith(b"%PDF-") and b"%%EOF" in data[-64:]
    import re

    box = [float(v) for v in re.search(rb"/MediaBox\s*\[\s*([^\]]+)\]", data).group(1).split()]
    assert box[2] - box[0] == pytest.approx(size[0], abs=0.01) and box[3] - box[1] == pytest.approx(size[1], abs=0.01)
    # the page holds every panel at 72 pt per inch
    width_m = sum(np.ptp(pn.outline[:, 0]) for pn in p.panels)
    assert size[0] / 72 * 0.0254 > width_m


# ------------------------------------------------------------------ placement


@pytest.fixture(scope="module")
def body():
    import trimesh
    from scipy.spatial import cKDTree

    m = trimesh.load(Path(__file__).resolve().parents[1] / "couture/assets/mannequin/body_a_pose.obj", process=False)
    V = np.asarray(m.vertices)
    return V, np.asarray(m.vertex_normals), cKDTree(V)


def _panel_points(panel, step=0.025):
    o = panel.outline
    lo, hi = o.min(0), o.max(0)
    narrow = float((hi - lo).min())  # a collar band: finer and nearer its edges
    step, margin = min(step, 0.25 * narrow), min(0.02, 0.3 * narrow)
    g = np.stack(np.meshgrid(np.arange(lo[0], hi[0], step), np.arange(lo[1], hi[1], step)), -1).reshape(-1, 2)
    g = g[point_in_polygon(g, o)]
    # interior only: panels are meant to touch along their seams
    from scipy.spatial import cKDTree

    return g[cKDTree(o).query(g)[0] > margin]


@pytest.mark.parametrize("kind", sorted(SLOPERS))
def test_placement_panels_do_not_overlap(body, kind):
    """Panels of one garment do not overlap grossly where they are placed.
    (Clearance from the body is checked with the exact SDF, per sloper, in
    tests/test_placement_seams.py.)"""
    for params in (
        {},
        {o.name: o.max for o in SLOPERS[kind].options if o.name in ("length", "sleeve_length", "flare")},
    ):
        p = draft(Design(sloper=Sloper(kind=kind, params=params)))
        clouds = {}
        for pn in p.panels:
            assert pn.placement is not None
            X = place(pn, _panel_points(pn))
            clouds[pn.name] = X
        from scipy.spatial import cKDTree

        names = list(clouds)
        for a in range(len(names)):
            ta = cKDTree(clouds[names[a]])
            for b in range(a + 1, len(names)):
                if len(clouds[names[b]]) == 0:
                    continue  # a strip narrower than 4 cm (a waistband) has no interior point
                close = ta.query(clouds[names[b]])[0] < 0.003
                assert close.mean() < 0.05, (names[a], names[b], close.mean())


def test_place_is_isometric_across_material_x():
    p = draft(Design())
    pn = p.panels[0]
    x = np.array([[0.0, -0.1], [0.01, -0.1]])
    X = place(pn, x)
    assert np.linalg.norm(X[1] - X[0]) == pytest.approx(0.01, rel=1e-3)


def test_mannequin_constants_match_the_mesh():
    from couture.pattern import mannequin as M

    got = M.measure_mannequin()
    assert got["waist_girth"] == pytest.approx(M.WAIST_GIRTH, abs=0.01)
    assert got["hip_girth"] == pytest.approx(M.HIP_GIRTH, abs=0.01)
    assert got["bust_girth"] == pytest.approx(M.BUST_GIRTH, abs=0.01)
    assert got["height"] == pytest.approx(1.666, abs=0.01)

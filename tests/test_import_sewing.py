"""Imported pieces -> a design (couture.pattern.sewing, couture.pattern.pieces):
corners, seam suggestions with a confidence, free edges, placement round the
body, the design as a first-class design (validated, meshed, JSON round trip)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from couture.pattern.geometry import polyline_length
from couture.pattern.imported import ImportedPiece, read_pattern
from couture.pattern.io import design_from_json, design_to_json
from couture.pattern.sewing import build_design, find_corners, panels_of, suggest_seams
from couture.pattern.validate import validate

FS = Path(__file__).parent / "data" / "imported" / "freesewing"
VAL = Path(__file__).parent / "data" / "imported" / "valentina"


def _rect(w, h, n=200, x0=0.0):
    """A w x h rectangle, each side finely sampled (a flattened file's density), CCW."""
    t = np.linspace(0, 1, n, endpoint=False)[:, None]
    c = np.array([[x0, -h], [x0 + w, -h], [x0 + w, 0.0], [x0, 0.0]])
    return np.vstack([c[i] + t * (c[(i + 1) % 4] - c[i]) for i in range(4)])


def test_corners_of_a_dense_rectangle_and_a_circle():
    P = _rect(0.3, 0.6)
    assert find_corners(P) == [0, 200, 400, 600]
    th = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    circle = 0.1 * np.column_stack([np.cos(th), np.sin(th)])
    assert len(find_corners(circle)) >= 3  # no corners: segments anyway, at the extremes


def test_two_panels_sewn_at_their_sides_and_free_hems():
    """A front and a back of the same size: both side seams suggested with a
    high confidence; top and bottom edges are free edges."""
    front = ImportedPiece("front", _rect(0.5, 0.6))
    back = ImportedPiece("back", _rect(0.5, 0.6))
    panels = panels_of([front, back])
    seams = suggest_seams(panels)
    assert len(seams) == 2
    for s in seams:
        assert {s.a_panel, s.b_panel} == {"front", "back"}
        assert s.confidence >= 0.9 and "front and back" in s.reason
        assert s.a_length == pytest.approx(0.6, abs=1e-9)
    design, rep = build_design([front, back])
    assert sorted((p, g) for p, g, _ in rep.free) == [("back", "e0"), ("back", "e2"), ("front", "e0"), ("front", "e2")]
    assert rep.order == ["front", "back"]
    assert rep.landmark == "waist"


def test_lengths_too_different_are_not_sewn():
    """Beyond the length tolerance (3 %) two sides are free edges, not a seam."""
    front = ImportedPiece("front", _rect(0.5, 0.6))
    back = ImportedPiece("back", _rect(0.5, 0.66))
    assert suggest_seams(panels_of([front, back])) == []


def test_penelope_seams_are_what_a_pattern_maker_sews():
    """FreeSewing's pencil skirt (front on the fold, back cut twice, two darts
    on each half): the importer suggests the 8 darts, the centre back between
    the two backs down to the vent (the vent's extensions, jutting past the
    centre line, lap: not sewn), and the two side seams front-to-back; the
    waist and hem stay free. The seams' two sides agree in length within 3 %."""
    pieces = [p for p in read_pattern(FS / "penelope_cisFemaleAdult34.svg") if p.name != "waistband"]
    design, rep = build_design(pieces)
    kinds = {"dart legs": 0, "mirrored pair": 0, "front and back": 0}
    for s in rep.seams:
        for k in kinds:
            if k in s.reason:
                kinds[k] += 1
        assert abs(s.a_length - s.b_length) <= 0.03 * max(s.a_length, s.b_length)
        if "dart" in s.reason:
            assert s.a_panel == s.b_panel
    assert kinds == {"dart legs": 8, "mirrored pair": 1, "front and back": 2}
    vent = [g for p, g, ln in rep.free if p == "back_left" and 0.2 < ln < 0.3]  # the extension, 25 cm
    assert len(vent) == 2  # and the hem, 29 cm
    sides = [s for s in rep.seams if "front and back" in s.reason]
    assert {s.a_panel for s in sides} | {s.b_panel for s in sides} == {"front", "back_left", "back_right"}
    # the torso ring follows the seams: front, the body's left back, its right back
    assert rep.order == ["front", "back_left", "back_right"]
    # the hem is free: the longest free edge of the front is its whole (unfolded) hem
    hem = max((ln for p, _, ln in rep.free if p == "front"), default=0.0)
    assert hem == pytest.approx(2 * 0.2475, rel=0.05)


def test_imported_design_is_a_design():
    """The design validates, survives its JSON file, and the remesher meshes
    it with every seam; the placement wraps the torso at the waist."""
    from couture.bodies import measured
    from couture.pattern.placement import place
    from couture.remesh.meshing import mesh_pattern

    pieces = [p for p in read_pattern(VAL / "Keiko_skirt_astm.dxf")]
    design, rep = build_design(pieces)
    assert design.sloper.kind == "none" and len(design.pieces) == 2
    again = design_from_json(design_to_json(design))
    assert again == design
    drafted = validate(again)
    assert [p.name for p in drafted.panels] == ["piece1", "piece2"]
    assert len(drafted.seams) == len(rep.seams) == 2
    res = mesh_pattern(drafted, 400, level="coarse")
    assert res.mesh.n_vertices > 300
    assert len(res.mesh.seam_emitters) > 0
    waist = measured("default")["waist_y"]
    for p in drafted.panels:
        X = place(p, p.outline)
        top = X[:, 1].max()
        assert abs(top - waist) < 0.05, (p.name, top, waist)
        r = np.hypot(X[:, 0], X[:, 2] - 0.04)
        assert r.min() > 0.05  # round the torso (its section is about 0.07 .. 0.2 m from the axis), not through it


def test_a_mirrored_pair_is_a_left_and_a_right():
    """'Cut 2': two panels, one the mirror image of the other (same area, same
    perimeter, x reflected)."""
    titan = read_pattern(FS / "titan_cisMaleAdult38.svg")
    panels = {p.name: p for p in panels_of(titan)}
    assert sorted(panels) == ["back_left", "back_right", "front_left", "front_right"]
    L, R = panels["back_left"].outline, panels["back_right"].outline
    assert polyline_length(L, closed=True) == pytest.approx(polyline_length(R, closed=True), rel=1e-9)
    Lm = L.copy()
    Lm[:, 0] = -Lm[:, 0]
    assert np.ptp(Lm[:, 0]) == pytest.approx(np.ptp(R[:, 0]), rel=1e-9)
    assert np.sort(Lm[:, 1]) == pytest.approx(np.sort(R[:, 1]), abs=1e-9)


def test_teagan_is_a_top():
    pieces = read_pattern(FS / "teagan_cisFemaleAdult34.svg")
    design, rep = build_design(pieces)
    assert rep.landmark == "shoulder"
    assert {p.name for p in design.pieces} == {"front", "back", "sleeve_left", "sleeve_right"}
    # the sleeves are not in the torso ring: each round its arm (tests/test_import_place.py)
    rings = {p.name: p.placement.ring for p in design.pieces}
    assert rings == {"front": "torso", "back": "torso", "sleeve_left": "left_arm", "sleeve_right": "right_arm"}
    # side seams front-to-back, and the shoulders
    fb = [s for s in rep.seams if "front and back" in s.reason]
    assert len(fb) == 2
    assert sum("shoulders" in s.reason for s in rep.seams) == 2
    assert all(math.isfinite(s.confidence) and 0 <= s.confidence <= 1 for s in rep.seams)


def test_halves_the_file_does_not_mark_are_unfolded():
    """Valentina's Keiko skirt: two halves (front and back, cut on the fold,
    which its DXF does not say) add up to 47 cm round, half a body: each is
    unfolded about its straight centre edge, and the two side seams are sewn."""
    pieces = read_pattern(VAL / "Keiko_skirt_aama.dxf")
    width = sum(np.ptp(p.sew[:, 0]) for p in pieces)
    design, rep = build_design(pieces)
    assert rep.notes and "halves cut on the fold" in rep.notes[0]
    for p, pc in zip(design.pieces, pieces, strict=True):
        assert np.ptp(np.array(p.outline)[:, 0]) == pytest.approx(2 * np.ptp(pc.sew[:, 0]), rel=1e-3)
    assert 2 * width > 0.9  # now round the hips
    assert len(rep.seams) == 2 and all(s.a_panel != s.b_panel for s in rep.seams)


def test_export_of_an_imported_design_reads_back(tmp_path):
    """`couture export` writes imported pieces like any panel: its DXF read
    back gives the design's sew lines to 1e-6 m."""
    from couture.pattern.cutting import CutSpec
    from couture.pattern.io import export_dxf

    design, _ = build_design([p for p in read_pattern(FS / "penelope_cisFemaleAdult42.svg") if p.name != "waistband"])
    pat = validate(design)
    f = tmp_path / "again.dxf"
    export_dxf(pat, f, spec=CutSpec(group=False))
    back = {p.name: p for p in read_pattern(f)}
    assert sorted(back) == sorted(p.name for p in pat.panels)
    for p in pat.panels:
        got = back[p.name].sew
        assert got.shape == p.outline.shape
        assert np.abs((got - got[0]) - (p.outline - p.outline[0])).max() < 1e-6


def test_a_pattern_message_carries_the_pieces():
    """The bus message of an imported design decodes to the same design."""
    from schemas.messages import PatternMsg, decode, encode

    design, _ = build_design(read_pattern(VAL / "TShirt_test_astm.dxf"))
    msg = PatternMsg(design=design, source="test", name="tshirt", design_id="x")
    again = decode(encode(msg), PatternMsg)
    assert again.design == design
    assert len(again.design.pieces) == 6  # the sleeve, given once, as a left and a right


@pytest.mark.parametrize(
    "file",
    [
        "freesewing/titan_cisMaleAdult46.svg",
        "freesewing/teagan_cisFemaleAdult42.svg",
        "freesewing/penelope_cisFemaleAdult42.svg",
        "valentina/TShirt_test_aama.dxf",
    ],
)
def test_every_fixture_gives_a_design_file(file):
    """Each fixture imports to a design that validates and encodes (plain
    numbers only: a numpy float once broke the file writer)."""
    design, rep = build_design(read_pattern(FS.parent / file))
    validate(design)
    assert design_from_json(design_to_json(design)) == design
    for s in rep.seams:
        assert type(s.confidence) is float and 0.0 <= s.confidence <= 1.0


def test_sleeves_close_into_tubes_not_onto_each_other():
    design, rep = build_design(read_pattern(FS / "teagan_cisFemaleAdult34.svg"))
    sleeve = [s for s in rep.seams if s.a_panel.startswith("sleeve") and s.b_panel.startswith("sleeve")]
    assert len(sleeve) == 2
    assert all(s.a_panel == s.b_panel and "tube" in s.reason for s in sleeve)
    # the rest of the sleeves' seams set their caps into the bodice's armholes
    caps = [s for s in rep.seams if (s.a_panel + s.b_panel).count("sleeve") == 1]
    assert len(caps) == 4 and all("sleeve cap" in s.reason for s in caps)

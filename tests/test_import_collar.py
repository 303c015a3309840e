"""Collars round the neck and pieces laid at arrangement points
(couture.pattern.sewing.sew_collar, couture.pattern.pieces, couture.pattern.landmarks).

FreeSewing's aaron (a sleeveless top with a neck binding and two arm
bindings), for both measurement sets: the neck binding is found as the
collar, split into the front's and the back's neckline and sewn to them, its
ends sewn into a loop; the armholes stay free (no sleeve), the arm bindings
are left out with a note; the binding (ring 'neck') is laid on the scoop
neckline it is sewn to, outside the body and below the jaw, and without its
seams round the neck at the body's neck base. Pieces laid at every body's
arrangement points start outside the body, their centres at the points."""

from __future__ import annotations

import json
from pathlib import Path

import msgspec
import numpy as np
import pytest

from couture.pattern.errors import PatternError
from couture.pattern.imported import read_pattern
from couture.pattern.landmarks import arrangement_points, neck, point_names
from couture.pattern.sewing import NECK_SLACK, body_for_measurements, build_design
from couture.pattern.validate import validate
from schemas.design import Design, Piece, PiecePlacement, Sloper

FS = Path(__file__).parent / "data" / "imported" / "freesewing"


def _design(stem: str):
    meas = json.loads((FS / f"{stem.split('_')[1]}.json").read_text())
    body, _ = body_for_measurements(meas)
    return build_design(read_pattern(FS / f"{stem}.svg"), body=body)


def _placed(design) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(positions of the coarse mesh as placed, the body's signed distance
    there, {panel: its vertices' positions})."""
    from couture.cloth.body import load_mannequin_sdf
    from couture.remesh.meshing import mesh_pattern

    drafted = validate(design)
    res = mesh_pattern(drafted, 1600, level="coarse")
    x = np.asarray(res.mesh.x0)
    phi = load_mannequin_sdf(verbose=False, name=design.body.name).phi_grad(x)[0]
    return x, phi, {p.name: x[res.vertex_panel == i] for i, p in enumerate(drafted.panels)}


def _pairs(rep) -> set[frozenset[tuple[str, str]]]:
    return {frozenset({(s.a_panel, s.a_segment), (s.b_panel, s.b_segment)}) for s in rep.seams}


@pytest.mark.parametrize("stem", ["aaron_cisMaleAdult38", "aaron_cisMaleAdult46"])
def test_neck_binding_sewn_round_the_neckline_and_laid_on_it(stem):
    design, rep = _design(stem)
    by = {p.name: p for p in design.pieces}
    assert set(by) == {"front", "back", "neckBinding"}  # the arm bindings are left out ...
    assert any("armBinding_left, armBinding_right" in n and "left out" in n for n in rep.notes)  # ... saying so
    assert rep.landmark == "shoulder"  # a top: its shoulders are sewn
    # what a pattern maker sews: 2 shoulders, 2 side seams, the binding to the neckline, its ends
    collar = [s for s in rep.seams if "collar to the neckline" in s.reason]
    assert [(s.b_panel, s.b_segment) for s in collar] == [("front", "e3"), ("back", "e3")]
    neckline = sum(s.b_length for s in collar)
    band = sum(s.a_length for s in collar)
    assert abs(band / neckline - 1) <= NECK_SLACK
    for s in collar:  # each part as long as its neckline piece, both eased alike
        assert s.a_panel == "neckBinding"
        assert s.a_length / s.b_length == pytest.approx(band / neckline, abs=2e-3)
    assert sum("shoulders" in s.reason for s in rep.seams) == 2
    assert sum("front and back" in s.reason for s in rep.seams) == 2
    assert sum("closes the collar into a loop" in s.reason for s in rep.seams) == 1
    assert len(rep.seams) == 7
    # the armholes (front e1/e5, back e1/e5) are not sewn to each other
    free = {(p, g) for p, g, _ in rep.free}
    assert {("front", "e1"), ("front", "e5"), ("back", "e1"), ("back", "e5")} <= free
    assert by["neckBinding"].placement.ring == "neck"
    x, phi, at = _placed(design)
    assert np.isfinite(x).all() and phi.min() > 0.0
    nk = neck(design.body.name)
    c = at["neckBinding"]
    assert c[:, 1].max() < nk.top_y  # below the jaw
    # all round: at the centre front and back, on both sides
    ang = np.arctan2(c[:, 0], c[:, 2] - 0.04)
    assert np.abs(ang).min() < 0.1 and np.abs(ang).max() > np.pi - 0.1 and (ang > 1).any() and (ang < -1).any()
    # laid on the scoop neckline it is sewn to (its centre front 10 cm below the neck), not round the neck
    drafted = validate(design)
    pl = next(p for p in drafted.panels if p.name == "neckBinding").placement
    assert pl.kind == "grid"
    from couture.pattern.draft import segment_points
    from couture.pattern.placement import place

    panels = {p.name: p for p in drafted.panels}
    for s in collar:
        a = place(panels["neckBinding"], segment_points(*_seg(panels, "neckBinding", s.a_segment)))
        b = place(panels[s.b_panel], segment_points(*_seg(panels, s.b_panel, s.b_segment)))
        # each part's neck edge on its neckline piece (the ends where the shoulder seams still gape excepted)
        d = np.linalg.norm(a[1:-1, None, :] - b[None, :, :], axis=2).min(axis=1)
        assert np.median(d) < 0.005, (s.b_panel, np.median(d))
    # the scoop's centre 9.6 cm below the straps' tops, which start at or a little below the neck's
    # base: round the neck, the binding's lowest point would be at the base
    assert c[:, 1].min() < nk.base_y - 0.05


def _seg(panels, panel: str, name: str):
    p = panels[panel]
    return p, next(g for g in p.segments if g.name == name)


def test_an_unsewn_collar_stays_round_the_neck():
    """The neck binding with its seams deleted from the design: nothing to lay
    it on, so it keeps its ring round the neck, its neck edge at the body's
    neck base, outside the body and below the jaw."""
    design, _ = _design("aaron_cisMaleAdult38")
    design.strokes = [s for s in design.strokes if "neckBinding" not in s.id]
    drafted = validate(design)
    assert next(p for p in drafted.panels if p.name == "neckBinding").placement.kind == "wrap"
    x, phi, at = _placed(design)
    assert phi.min() > 0.0
    nk = neck(design.body.name)
    c = at["neckBinding"]
    assert nk.base_y - 0.005 < c[:, 1].min() and c[:, 1].max() < nk.top_y


def test_collar_of_the_wrong_length_is_not_sewn():
    """A neck binding 20 % longer than the neckline is no collar of this top:
    left out, with its note, nothing sewn to the neckline."""
    from dataclasses import replace

    pieces = read_pattern(FS / "aaron_cisMaleAdult38.svg")
    # the band is drawn upright: its length is along y
    pieces = [replace(p, sew=p.sew * np.array([1.0, 1.2])) if p.name == "neckBinding" else p for p in pieces]
    design, rep = build_design(pieces, body="XL")
    assert not any("collar" in s.reason for s in rep.seams)
    assert "neckBinding" not in {p.name for p in design.pieces}
    assert any("neckBinding" in n and "left out" in n for n in rep.notes)


def _patch(name: str, point: str, w: float = 0.16, h: float = 0.10, clearance: float | None = None) -> Piece:
    return Piece(
        name=name,
        outline=[(0.0, -h), (w, -h), (w, 0.0), (0.0, 0.0)],
        corners=[0, 1, 2, 3],
        placement=PiecePlacement(ring="point", point=point, clearance=clearance),
    )


@pytest.mark.parametrize("body", ["default", "XS", "XL"])
def test_pieces_laid_at_arrangement_points_start_outside_the_body(body):
    """A 16 x 10 cm piece at every arrangement point (12 x 6 cm at the neck):
    every vertex outside the body (signed distance > 0), its centre at the
    point's height along the point's axis and on the point's side of it; the
    neck's pieces below the jaw."""
    pts = arrangement_points(body)
    assert set(pts) == set(point_names()) and len(pts) == 22
    pieces = [_patch(f"p_{n}", n, *((0.12, 0.06) if n.endswith("_neck") else ())) for n in pts]
    design = Design(sloper=Sloper(kind="none"), pieces=pieces)
    design.body.name = body
    x, phi, at = _placed(design)
    assert np.isfinite(x).all() and phi.min() > 0.0
    for n, pt in pts.items():
        c = at[f"p_{n}"]
        mid = 0.5 * (c.min(axis=0) + c.max(axis=0))
        assert abs((mid - pt.origin) @ pt.axis) < 0.02, n  # at the point's height along its axis
        d = (mid - pt.origin) - ((mid - pt.origin) @ pt.axis) * pt.axis
        assert d @ (pt.position - pt.origin) > 0, n  # on the point's side of the axis
        if n.endswith("_neck"):
            assert c[:, 1].max() < neck(body).top_y, n
    assert at["p_back_neck"][:, 2].mean() < at["p_front_neck"][:, 2].mean()


def test_an_unknown_arrangement_point_is_refused_naming_the_piece():
    design = Design(sloper=Sloper(kind="none"), pieces=[_patch("pocket", "left_elbow")])
    with pytest.raises(PatternError, match="pocket.*no arrangement point 'left_elbow'"):
        validate(design)
    bad = msgspec.json.encode(Design(sloper=Sloper(kind="none"), pieces=[_patch("pocket", "front_waist")]))
    bad = bad.replace(b'"clearance":null', b'"clearance":0.5')
    with pytest.raises(msgspec.ValidationError, match="clearance"):
        msgspec.json.decode(bad, type=Design)


def test_old_designs_decode_without_the_new_placement_fields():
    """A piece placement written before 'neck', 'point' and 'clearance' existed reads unchanged."""
    old = {
        "sloper": {"kind": "none"},
        "pieces": [
            {
                "name": "front",
                "outline": [[0, -0.5], [0.5, -0.5], [0.5, 0], [0, 0]],
                "placement": {"ring": "torso", "position": 0, "angle": 0.0, "height": 0.3},
            }
        ],
    }
    d = msgspec.json.decode(json.dumps(old).encode(), type=Design)
    pl = d.pieces[0].placement
    assert (pl.ring, pl.point, pl.clearance, pl.height) == ("torso", "", None, 0.3)


def test_neck_landmarks_on_every_body():
    """The neck's base lies above the underarm and below its narrowest
    section, the jaw above that, on every shipped body."""
    from couture.bodies import measured, shipped_names

    for body in shipped_names():
        nk = neck(body)
        assert measured(body)["underarm_y"] + 0.08 < nk.base_y < nk.narrow_y < nk.top_y, body
        assert 0.3 < nk.girth < 0.7, body


@pytest.mark.parametrize("flavour", ["astm"])  # AAMA's cut lines: the facing's edge is 5 cm too long to pair
def test_a_facing_is_laid_just_inside_the_piece_it_faces(flavour):
    """Valentina's TShirt_test kept whole: its small front neck facing (sewn
    to the front's neckline) is laid just inside the front (ring 'inside'):
    outside the body, within 3 cm of the front's vertices and nearer the torso axis than
    the front there, its sewn edge on the front's neckline; `couture import`
    says the two layers do not collide."""
    from scipy.spatial import cKDTree

    from couture.pattern.draft import segment_points
    from couture.pattern.placement import place

    path = FS.parent / "valentina" / f"TShirt_test_{flavour}.dxf"
    facing, front = ("Detail", "Detail_2") if flavour == "astm" else ("piece1", "piece2")
    design, rep = build_design(read_pattern(path))
    assert {p.name: p.placement.ring for p in design.pieces}[facing] == "inside"
    assert any(
        n.startswith(f"{facing}: a facing, laid just inside {front}") and "no cloth-cloth" in n for n in rep.notes
    )
    x, phi, at = _placed(design)
    assert phi.min() > 0.0
    F, R = at[facing], at[front]
    d, j = cKDTree(R).query(F)
    assert d.max() < 0.03  # the nearest front vertex (the coarse mesh: 2-3 cm apart)
    radius = np.hypot(F[:, 0], F[:, 2] - 0.04) - np.hypot(R[j, 0], R[j, 2] - 0.04)
    assert np.median(radius) < -0.001  # inside the front
    drafted = validate(design)
    panels = {p.name: p for p in drafted.panels}
    (s,) = [s for s in rep.seams if facing in (s.a_panel, s.b_panel)]
    mine, theirs = (
        (s.a_segment, (s.b_panel, s.b_segment)) if s.a_panel == facing else (s.b_segment, (s.a_panel, s.a_segment))
    )
    a = place(panels[facing], segment_points(*_seg(panels, facing, mine)))
    b = place(panels[theirs[0]], segment_points(*_seg(panels, *theirs)))
    assert np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2).min(axis=1).max() < 0.01  # on the neckline

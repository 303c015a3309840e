"""Editing imported pieces (``Design.pieces``) like slopers: the ``pt:``
element moves a piece's outline point (its Jacobian against central
differences of ``apply_edit``), a curve stroke bends a piece segment (its
``cv:`` element likewise), a move that makes the outline self-intersect is
refused naming the piece and the point, the UI's handles sit on the pieces'
corners and a drag moves the drafted panel, and ``couture export`` writes the
edited piece back (re-imported: the same sew line to 1e-6 m)."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from couture.pattern import apply_edit, draft, edit_elements, edit_jacobian
from couture.pattern.cutting import CutSpec
from couture.pattern.errors import PatternError
from couture.pattern.imported import read_pattern
from couture.pattern.io import export_dxf
from couture.pattern.sewing import build_design
from couture.ui.handles import plan_handles
from schemas.design import Design, Stroke

PENELOPE = Path(__file__).parent / "data" / "imported" / "freesewing" / "penelope_cisFemaleAdult34.svg"
H = 1e-5
"""[m] central-difference step of the pointer"""


@pytest.fixture(scope="module")
def penelope() -> Design:
    design, _ = build_design(read_pattern(PENELOPE))
    return design


def _curve_gap(A: np.ndarray, B: np.ndarray) -> float:
    """Largest distance [m] from a vertex of either closed polyline to the other
    one: the same sew line whatever its vertices (the importer merges vertices
    closer than 0.3 mm, such as a waistband's split points next to a corner)."""

    def one_way(P: np.ndarray, Q: np.ndarray) -> float:
        a, b = Q, np.roll(Q, -1, axis=0)
        ab = b - a
        t = np.einsum("pqk,qk->pq", P[:, None, :] - a[None], ab) / np.maximum(np.einsum("qk,qk->q", ab, ab), 1e-300)
        near = a[None] + np.clip(t, 0.0, 1.0)[..., None] * ab[None]
        return float(np.linalg.norm(P[:, None, :] - near, axis=2).min(axis=1).max())

    return max(one_way(A, B), one_way(B, A))


def _centroid(P: np.ndarray) -> np.ndarray:
    """The polygon's area centroid: where its vertices lie along its edges does not move it."""
    x, y = P[:, 0], P[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    c = x * yn - xn * y
    return np.array([((x + xn) * c).sum(), ((y + yn) * c).sum()]) / (3.0 * c.sum())


def _corner(design: Design, name: str, k: int = 1) -> int:
    return next(pc for pc in design.pieces if pc.name == name).corners[k]


def _fd(design: Design, element: str, dd: np.ndarray) -> dict[str, np.ndarray]:
    """Central difference of the drafted outlines along pointer direction dd."""
    plus, minus = draft(apply_edit(design, element, H * dd)), draft(apply_edit(design, element, -H * dd))
    return {p.name: (p.outline - minus.panel(p.name).outline) / (2 * H) for p in plus.panels}


def _check_jacobian(design: Design, element: str) -> None:
    J = edit_jacobian(design, element)
    for dd in (np.array([1.0, 0.0]), np.array([0.6, -0.8])):
        fd = _fd(design, element, dd)
        moved = [n for n, v in fd.items() if np.abs(v).max() > 1e-6]
        assert moved, f"{element}: the edit moved nothing"
        for name, v in fd.items():
            pred = J[name].outline @ dd if name in J else np.zeros_like(v)
            assert np.abs(pred).max() > 1e-3 or name not in moved, f"{element}: J on {name} is trivially zero"
            assert np.abs(pred - v).max() < 1e-5 * max(1.0, np.abs(v).max()), (element, name, np.abs(pred - v).max())


def test_piece_points_are_edit_elements_at_the_corners(penelope):
    pts = [e for e in edit_elements(penelope) if e.startswith("pt:")]
    want = [f"pt:{pc.name}:{c}" for pc in penelope.pieces for c in pc.corners]
    assert pts == want and len(pts) > 20


def test_point_jacobian_matches_apply_edit(penelope):
    """Exact Jacobian (no stroke on the piece): the corner moves with the
    pointer, its two segments stretch, the other corners stay."""
    c = _corner(penelope, "front")
    el = f"pt:front:{c}"
    _check_jacobian(penelope, el)
    J = edit_jacobian(penelope, el)["front"].outline
    assert np.allclose(J[c], np.eye(2))
    pc = next(p for p in penelope.pieces if p.name == "front")
    others = [k for k in pc.corners if k != c]
    assert np.abs(J[others]).max() == 0
    new = apply_edit(penelope, el, [0.02, -0.01])
    P0, P1 = np.asarray(pc.outline), np.asarray(next(p for p in new.pieces if p.name == "front").outline)
    assert np.allclose(P1[c] - P0[c], [0.02, -0.01])
    moved = np.flatnonzero(np.linalg.norm(P1 - P0, axis=1) > 1e-12)
    # the two segments' points between the neighbouring corners, no further
    assert moved.min() > pc.corners[0] and moved.max() < pc.corners[2] and len(moved) > 2
    # the other pieces are untouched
    assert [p for p in new.pieces if p.name != "front"] == [p for p in penelope.pieces if p.name != "front"]


def test_curve_on_a_piece_segment_and_its_jacobians(penelope):
    """The curve tool's stroke bends a piece segment (corners fixed, vertex
    count kept); its control point and a piece point with a stroke on the
    piece (central differences through the draft) match apply_edit."""
    pc = next(p for p in penelope.pieces if p.name == "front")
    d = copy.deepcopy(penelope)
    d.strokes = list(d.strokes) + [
        Stroke(id="curve-front-e0", kind="curve", panel="front", params={"segment": "e0", "points": [[0.4, 0.01]]})
    ]
    base, bent = draft(penelope).panel("front"), draft(d).panel("front")
    assert bent.outline.shape == base.outline.shape
    dev = np.linalg.norm(bent.outline - base.outline, axis=1)
    assert 0.008 < dev.max() < 0.012  # the 1 cm bulge
    assert dev[pc.corners[0]] == 0 and dev[pc.corners[1]] == 0 and dev[pc.corners[1] :].max() == 0
    assert "cv:front:e0:0" in edit_elements(d)
    _check_jacobian(d, "cv:front:e0:0")
    _check_jacobian(d, f"pt:front:{pc.corners[1]}")


def test_a_self_intersecting_move_is_refused(penelope):
    pc = next(p for p in penelope.pieces if p.name == "front")
    c = pc.corners[1]
    P = np.asarray(pc.outline)
    across = 2.0 * (P.mean(axis=0) - P[c])  # through the piece and out the other side
    with pytest.raises(PatternError, match=rf"point {c} of piece 'front'.*self-intersect"):
        apply_edit(penelope, f"pt:front:{c}", across)
    for bad, why in (("pt:nope:3", "no piece named 'nope'"), ("pt:front:99999", "no outline point 99999")):
        with pytest.raises(PatternError, match=why):
            apply_edit(penelope, bad, [0.01, 0.0])


def test_corner_handles_and_a_drag_changes_the_drafted_panel(penelope):
    pat = draft(penelope)
    hs = plan_handles(penelope, pat)
    pts = [h for h in hs.handles if h.kind == "pt"]
    assert len(pts) == sum(len(pc.corners) for pc in penelope.pieces)
    for h in pts:
        assert h.element == f"pt:{h.panel}:{h.vertex}"  # on its own corner
    old_p = pat.panel("back_left")
    c = old_p.outline.mean(axis=0)
    # the corner farthest out (a hem corner), dragged 2 cm further out
    h = max((h for h in pts if h.panel == "back_left"), key=lambda h: np.linalg.norm(old_p.outline[h.vertex] - c))
    out = old_p.outline[h.vertex] - c
    move = 0.02 * out / np.linalg.norm(out)
    d = h.element_delta(move)
    new = draft(apply_edit(penelope, h.element, d))
    new_p = new.panel("back_left")
    assert np.allclose(new_p.outline[h.vertex] - old_p.outline[h.vertex], move)
    assert np.allclose(hs.moved_outlines(pat, h.element, d)["back_left"], new_p.outline)


def test_export_writes_an_edited_piece_back(tmp_path, penelope):
    """export then import of an edited imported design: the same sew lines to 1e-6 m."""
    c = _corner(penelope, "front", 2)
    edited = apply_edit(penelope, f"pt:front:{c}", [0.015, 0.01])
    pat = draft(edited)
    f = tmp_path / "p.dxf"
    pieces = export_dxf(pat, f, units="mm", spec=CutSpec(seam_allowance=0.01, group=False))
    got = {g.name: g for g in read_pattern(f)}
    assert sorted(got) == sorted(p.name for p in pieces) == sorted(p.name for p in pat.panels)
    for p in pieces:
        g = got[p.name]
        assert _curve_gap(g.sew - _centroid(g.sew), p.sew - _centroid(p.sew)) < 1e-6, p.name
        # the exported sew line is the drafted (edited) outline, laid out on the sheet
        P = pat.panel(p.name).outline
        assert p.sew.shape == P.shape and np.abs((p.sew - p.sew[0]) - (P - P[0])).max() < 1e-9
    front = pat.panel("front").outline
    assert np.abs(front - draft(penelope).panel("front").outline).max() > 0.01


def test_remesher_psi_for_a_piece_point_moves_the_mesh_as_the_edit_does(penelope):
    """Ψ (the remesher's, for the sensitivity node) of a corner edit against
    the mesh the remesher follows to the edited design: X + Ψ dd."""
    from couture.remesh.service import RemeshService

    d = copy.deepcopy(penelope)
    d.resolution = type(d.resolution)(coarse_vertices=800, fine_vertices=1600)
    c = _corner(d, "front", 2)
    el = f"pt:front:{c}"
    svc = RemeshService()
    svc.set_design(d, 1)
    psi = svc.psi_for(el)["coarse"]
    X0 = svc.levels["coarse"].mesh.X.copy()
    assert np.abs(psi).max() > 0.5  # the mesh vertex at the corner moves with it
    dd = np.array([0.004, -0.003])
    up = svc.set_design(apply_edit(d, el, dd), 2)[0]
    assert up.how in ("followed", "flipped")
    assert np.abs(up.mesh.X - (X0 + psi @ dd)).max() < 1e-9


def test_ui_curve_tool_on_a_piece_segment_and_no_dart_on_a_piece(tmp_path, penelope):
    """The curve tool (headless UI) adds a control point on a piece segment;
    its handle then bends the segment. The dart tool refuses a piece (its
    darts come with it) and the draft names a dart stroke on one."""
    from couture.bus.ports import free_port
    from couture.pattern.pieces import segment_span
    from couture.ui.app import CoutureUI, UIConfig

    ui = CoutureUI(UIConfig(port=free_port(), export_dir=tmp_path, show_body=False, draft_locally=False))
    ui.start()
    try:
        ui.set_design(penelope)
        pat = draft(penelope)
        ui.show_pattern(pat)
        got: list[Design] = []
        ui.on_design_changed = got.append
        front = pat.panel("front")
        seg = next(s for s in front.segments if s.name == "e0")
        idx = segment_span(len(front.outline), seg.start, seg.stop)
        ui.tools.arm("curve")
        ui.tools.click(ui.view2d.display("front", front.outline[idx[len(idx) // 2]]), "front")
        assert len(got) == 1
        st = got[-1].strokes[-1]
        assert (st.kind, st.panel, st.params["segment"]) == ("curve", "front", "e0")
        assert 0.3 < st.params["points"][0][0] < 0.7 and st.params["points"][0][1] == 0.0
        curved = got[-1]
        hs = plan_handles(curved, draft(curved))
        cv = next(h for h in hs.handles if h.element == "cv:front:e0:0")
        assert cv.panel == "front" and cv.vertex in idx
        chord = front.outline[idx[-1]] - front.outline[idx[0]]
        across = 0.01 * np.array([chord[1], -chord[0]]) / np.linalg.norm(chord)  # outward, 1 cm
        bent = draft(apply_edit(curved, cv.element, cv.element_delta(across))).panel("front")
        assert 0.005 < np.abs(bent.outline - front.outline).max() < 0.02

        ui.tools.arm("dart")
        ui.tools.click(ui.view2d.display("front", front.outline[idx[len(idx) // 2]]), "front")
        assert len(got) == 1 and "imported piece" in ui.tools.help.content and ui.tools.armed is None
    finally:
        ui.stop()
    d = copy.deepcopy(penelope)
    d.strokes = list(d.strokes) + [
        Stroke(
            id="d9",
            kind="dart",
            panel="front",
            params={"segment": "e0", "position": 0.5, "width": 0.02, "length": 0.05},
        )
    ]
    with pytest.raises(PatternError, match="d9: a dart stroke on the imported piece 'front' is not supported"):
        draft(d)


def test_couture_export_cli_writes_an_edited_imported_design(tmp_path, penelope):
    """`couture export` (the command, defaults but the formats) of an imported
    design whose piece was edited: every piece comes back from the DXF and the
    SVG with the drafted (edited) sew line to 1e-6 m (the sheet layout moves
    pieces: compared about their centroids). The edited piece is half of a
    'Cut 2' pair: its twin moved with it, and the pair is one piece cut twice."""
    import subprocess
    import sys

    from couture.pattern.io import save_design

    c = _corner(penelope, "back_left", 2)
    edited = apply_edit(penelope, f"pt:back_left:{c}", [0.01, 0.01])
    save_design(edited, tmp_path / "edited.json")
    r = subprocess.run(
        [sys.executable, "-m", "couture.cli", "export", str(tmp_path / "edited.json")]
        + ["--format", "dxf", "svg", "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    pat = draft(edited)
    want = sorted(p.name for p in pat.panels if p.name != "back_right")
    for f in ("edited.dxf", "edited.svg"):
        got = {g.name: g for g in read_pattern(tmp_path / "out" / f)}
        assert sorted(got) == want, f
        assert (got["back_left"].cut_count, got["back_left"].mirrored) == (2, True), f
        for name in want:
            S, P = got[name].sew, pat.panel(name).outline
            assert _curve_gap(S - _centroid(S), P - _centroid(P)) < 1e-6, (f, name)
    for name in ("back_left", "back_right"):  # both halves moved
        assert np.abs(pat.panel(name).outline - draft(penelope).panel(name).outline).max() > 0.009

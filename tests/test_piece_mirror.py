"""'Cut 2' pairs edit as one piece cut twice: the importer marks a mirrored
pair (``Piece.mirror_of``, ``mirror_index``), a point edit (``pt:``) or a
curve (a curve stroke, its ``cv:`` control point) on one half moves its
twin's mirror points with it (to 1e-12 m), the Jacobian and the remesher's Ψ
cover both halves (against central differences and the followed mesh), a
design whose pair is not mirrored is refused naming the point, an old design
(no ``mirror_of``) decodes and edits each half alone, and ``couture export``
writes the edited pair as one piece 'Cut 2' that imports back as the pair."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from couture.pattern import apply_edit, draft, edit_jacobian
from couture.pattern.errors import PatternError
from couture.pattern.imported import read_pattern
from couture.pattern.pieces import twin_segment, with_mirrored_curve
from couture.pattern.sewing import build_design
from schemas.design import Design, Stroke

FS = Path(__file__).parent / "data" / "imported" / "freesewing"
PENELOPE = FS / "penelope_cisFemaleAdult34.svg"
H = 1e-5
"""[m] central-difference step of the pointer"""


@pytest.fixture(scope="module")
def penelope() -> Design:
    design, _ = build_design(read_pattern(PENELOPE))
    return design


def _piece(design: Design, name: str):
    return next(pc for pc in design.pieces if pc.name == name)


def _mirror_gap(A: np.ndarray, B: np.ndarray, r: int) -> float:
    """Largest distance [m] of B's points from the mirror image of A's
    (B[j] against (c - x, y) of A[(r - j) mod k], c fitted at j = 0),
    computed here, apart from couture.pattern.pieces."""
    k = len(A)
    M = A[(r - np.arange(k)) % k].copy()
    M[:, 0] = (B[0, 0] + A[r, 0]) - M[:, 0]
    return float(np.abs(M - B).max())


def _far_corners(design: Design, name: str, n: int = 2) -> list[tuple[int, np.ndarray]]:
    """The ``n`` corners of a piece farthest from its middle (its hem's), each
    with the unit vector out from the middle: a move along it keeps the outline simple."""
    pc = _piece(design, name)
    P = np.asarray(pc.outline)
    out = sorted(pc.corners, key=lambda c: -np.linalg.norm(P[c] - P.mean(axis=0)))[:n]
    return [(c, (P[c] - P.mean(axis=0)) / np.linalg.norm(P[c] - P.mean(axis=0))) for c in out]


def _outlines(design: Design, a: str, b: str) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(_piece(design, a).outline), np.asarray(_piece(design, b).outline)


def test_the_importer_marks_cut_2_pairs_as_mirror_images(penelope):
    a, b = _piece(penelope, "back_left"), _piece(penelope, "back_right")
    assert (a.mirror_of, b.mirror_of) == ("back_right", "back_left") and a.mirror_index == b.mirror_index
    assert _mirror_gap(*_outlines(penelope, "back_left", "back_right"), a.mirror_index) < 1e-12
    assert not _piece(penelope, "front").mirror_of  # cut once: no twin
    titan, _ = build_design(read_pattern(FS / "titan_cisMaleAdult38.svg"))
    teagan, _ = build_design(read_pattern(FS / "teagan_cisFemaleAdult34.svg"))
    assert {(pc.name, pc.mirror_of) for pc in titan.pieces} == {
        ("back_left", "back_right"),
        ("back_right", "back_left"),
        ("front_left", "front_right"),
        ("front_right", "front_left"),
    }
    assert {pc.name: pc.mirror_of for pc in teagan.pieces}["sleeve_left"] == "sleeve_right"


@pytest.mark.parametrize("name,twin", [("back_left", "back_right"), ("back_right", "back_left")])
def test_a_point_edit_moves_the_twin_mirrored(penelope, name, twin):
    pc = _piece(penelope, name)
    for c, out in _far_corners(penelope, name):
        new = apply_edit(penelope, f"pt:{name}:{c}", 0.012 * out)
        A, B = _outlines(new, name, twin)
        A0, B0 = _outlines(penelope, name, twin)
        assert np.allclose(A[c] - A0[c], 0.012 * out)
        assert np.abs(B - B0).max() > 0.01  # the twin moved ...
        assert _mirror_gap(A, B, pc.mirror_index) < 1e-12  # ... as the mirror image
        assert _piece(new, "front") == _piece(penelope, "front")
    # drafted too: the panels the solver sews are mirror images
    pat = draft(new)
    assert _mirror_gap(pat.panel(name).outline, pat.panel(twin).outline, pc.mirror_index) < 1e-12


def _check_jacobian(design: Design, element: str, both: tuple[str, str]) -> None:
    """edit_jacobian against central differences of draft(apply_edit), on every
    panel, after asserting it is not zero on either half of the pair."""
    J = edit_jacobian(design, element)
    for name in both:
        assert name in J and np.abs(J[name].outline).max() > 0.1, (element, name)
    for dd in (np.array([1.0, 0.0]), np.array([0.6, -0.8])):
        plus, minus = draft(apply_edit(design, element, H * dd)), draft(apply_edit(design, element, -H * dd))
        for p in plus.panels:
            fd = (p.outline - minus.panel(p.name).outline) / (2 * H)
            pred = J[p.name].outline @ dd if p.name in J else np.zeros_like(fd)
            if p.name in both:
                assert np.abs(fd).max() > 0.1, (element, p.name)  # the edit moves both halves
            assert np.abs(pred - fd).max() < 1e-5 * max(1.0, np.abs(fd).max()), (element, p.name)


def test_point_jacobian_covers_both_halves(penelope):
    c = _piece(penelope, "back_left").corners[2]
    el = f"pt:back_left:{c}"
    _check_jacobian(penelope, el, ("back_left", "back_right"))
    J = edit_jacobian(penelope, el)
    r = _piece(penelope, "back_left").mirror_index
    k = len(_piece(penelope, "back_left").outline)
    assert np.array_equal(J["back_right"].outline[(r - c) % k], np.diag([-1.0, 1.0]))


def _curved(design: Design, name: str, segment: str, points) -> Design:
    d = copy.deepcopy(design)
    sid = f"curve-{name}-{segment}"
    d.strokes = list(d.strokes) + [
        Stroke(id=sid, kind="curve", panel=name, params={"segment": segment, "points": points})
    ]
    return with_mirrored_curve(d, sid)


def test_a_curve_on_one_half_bends_the_twin_mirrored(penelope):
    a, b = _piece(penelope, "back_left"), _piece(penelope, "back_right")
    seg = "e1"
    tseg = twin_segment(a, b, seg)
    d = _curved(penelope, "back_left", seg, [[0.3, 0.01], [0.7, -0.004]])
    st = next(s for s in d.strokes if s.kind == "curve" and s.panel == "back_right")
    assert st.params["segment"] == tseg and st.params["points"] == [[pytest.approx(0.3), -0.004], [0.7, 0.01]]
    pat, base = draft(d), draft(penelope)
    assert np.abs(pat.panel("back_right").outline - base.panel("back_right").outline).max() > 0.005
    assert _mirror_gap(pat.panel("back_left").outline, pat.panel("back_right").outline, a.mirror_index) < 1e-12
    # the control point's handle: one edit bends both, its Jacobian covers both
    el = f"cv:back_left:{seg}:0"
    moved = draft(apply_edit(d, el, [0.01, 0.02]))
    assert np.abs(moved.panel("back_right").outline - pat.panel("back_right").outline).max() > 1e-3
    assert _mirror_gap(moved.panel("back_left").outline, moved.panel("back_right").outline, a.mirror_index) < 1e-12
    _check_jacobian(d, el, ("back_left", "back_right"))
    # a point of a curved piece: Jacobian by central differences through the draft
    _check_jacobian(d, f"pt:back_right:{b.corners[1]}", ("back_left", "back_right"))


def test_remesher_psi_of_a_corner_moves_both_halves_as_the_edit_does(penelope):
    from couture.remesh.service import RemeshService

    d = copy.deepcopy(penelope)
    d.resolution = type(d.resolution)(coarse_vertices=800, fine_vertices=1600)
    el = f"pt:back_left:{_piece(d, 'back_left').corners[2]}"
    svc = RemeshService()
    svc.set_design(d, 1)
    mesh = svc.levels["coarse"].mesh
    psi = svc.psi_for(el)["coarse"]
    X0 = mesh.X.copy()
    names = list(mesh.panel_names)
    for n in ("back_left", "back_right"):
        verts = np.unique(mesh.tris[mesh.tri_panel == names.index(n)])
        assert np.abs(psi[verts]).max() > 0.5, n  # the vertex at the corner and its mirror move with it
    dd = np.array([0.004, -0.003])
    up = svc.set_design(apply_edit(d, el, dd), 2)[0]
    assert up.how in ("followed", "flipped")
    assert np.abs(up.mesh.X - (X0 + psi @ dd)).max() < 1e-9


def test_a_pair_that_is_not_mirrored_is_refused_and_an_old_design_edits_each_half_alone(penelope):
    from couture.pattern.io import design_to_json, load_design

    bad = copy.deepcopy(penelope)
    b = _piece(bad, "back_right")
    b.outline = [(x + 0.003, y) if i == 40 else (x, y) for i, (x, y) in enumerate(b.outline)]
    with pytest.raises(PatternError, match=r"back_left.*point 40 of its mirror 'back_right' is 3 mm off"):
        draft(bad)
    lone = copy.deepcopy(penelope)
    _piece(lone, "back_right").mirror_of = "nope"
    with pytest.raises(PatternError, match="does not name it back"):
        draft(lone)
    short = copy.deepcopy(penelope)
    _piece(short, "back_right").outline = _piece(short, "back_right").outline[:-1]
    c = _piece(short, "back_left").corners[2]
    with pytest.raises(PatternError, match="back_left: has 225 outline points, its mirror 'back_right' 224"):
        apply_edit(short, f"pt:back_left:{c}", [0.001, 0.0])  # refused before any point moves
    # a design written before the field: no mirror_of, each half edits alone
    raw = json.loads(design_to_json(penelope))
    assert any(pc.get("mirror_of") for pc in raw["design"]["pieces"])
    for pc in raw["design"]["pieces"]:
        pc.pop("mirror_of", None), pc.pop("mirror_index", None)
    old_file = Path(__file__).parent / "_old_design.json"
    try:
        old_file.write_text(json.dumps(raw))
        old = load_design(old_file)
    finally:
        old_file.unlink()
    assert all(pc.mirror_of == "" and pc.mirror_index == 0 for pc in old.pieces)
    c = _piece(old, "back_left").corners[2]
    new = apply_edit(old, f"pt:back_left:{c}", [0.01, 0.01])
    assert _piece(new, "back_right") == _piece(old, "back_right")
    assert set(edit_jacobian(old, f"pt:back_left:{c}")) == {"back_left"}


def test_couture_export_writes_the_edited_pair_as_one_piece_cut_twice(tmp_path, penelope):
    """An edited half exported (`couture export`, DXF) is one piece 'Cut 2 (1
    mirrored)' whose sew line is the edited half's to 1e-6 m; imported back
    it is the pair again, under its names, marked mirror images, each half
    the drafted half of its name to 1e-5 m (the import resamples the
    outline)."""
    import subprocess
    import sys

    from couture.pattern.io import save_design

    (c, out), _ = _far_corners(penelope, "back_left")
    edited = apply_edit(penelope, f"pt:back_left:{c}", 0.015 * out)
    save_design(edited, tmp_path / "edited.json")
    r = subprocess.run(
        [sys.executable, "-m", "couture.cli", "export", str(tmp_path / "edited.json")]
        + ["--format", "dxf", "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    assert "back_left: Cut 2 (1 mirrored) - also back_right" in r.stdout
    pieces = read_pattern(tmp_path / "out" / "edited.dxf")
    back = next(g for g in pieces if g.name == "back_left")
    assert (back.cut_count, back.mirrored, len(pieces)) == (2, True, 3)
    again, _ = build_design(pieces)
    # the pair under its own names again (before: back_left_left, back_left_right)
    pair = [pc for pc in again.pieces if pc.name in ("back_left", "back_right")]
    assert len(pair) == 2 and {pc.mirror_of for pc in pair} == {"back_left", "back_right"}
    pat = draft(edited)

    def gap(S, name: str) -> float:  # about their centroids: the sheet layout moves pieces
        S, P = np.asarray(S, float), pat.panel(name).outline
        return _curve_gap(S - _centroid(S), P - _centroid(P))

    assert gap(back.sew, "back_left") < 1e-6  # the piece in the file: the edited half
    for pc in pair:
        # imported again, each half is one of the drafted halves (the importer's resampling: 1e-5)
        assert gap(pc.outline, pc.name) < 1e-5, pc.name  # each half the drafted half of its name
    assert _mirror_gap(*_outlines(again, pair[0].name, pair[1].name), pair[0].mirror_index) < 1e-12


def _curve_gap(A: np.ndarray, B: np.ndarray) -> float:
    """Largest distance [m] from a vertex of either closed polyline to the other one."""

    def one_way(P: np.ndarray, Q: np.ndarray) -> float:
        a, b = Q, np.roll(Q, -1, axis=0)
        ab = b - a
        t = np.einsum("pqk,qk->pq", P[:, None, :] - a[None], ab) / np.maximum(np.einsum("qk,qk->q", ab, ab), 1e-300)
        near = a[None] + np.clip(t, 0.0, 1.0)[..., None] * ab[None]
        return float(np.linalg.norm(P[:, None, :] - near, axis=2).min(axis=1).max())

    return max(one_way(A, B), one_way(B, A))


def _centroid(P: np.ndarray) -> np.ndarray:
    """The polygon's area centroid (where its vertices lie along its edges does not move it)."""
    x, y = P[:, 0], P[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    c = x * yn - xn * y
    return np.array([((x + xn) * c).sum(), ((y + yn) * c).sum()]) / (3.0 * c.sum())


def test_ui_curve_tool_and_corner_handle_on_one_half_edit_both(tmp_path, penelope):
    """The UI (headless viser): the curve tool's click on back_left commits a
    curve on both halves; a back_left corner handle's preview moves
    back_right's outline as the committed edit does."""
    from couture.bus.ports import free_port
    from couture.pattern.pieces import segment_span
    from couture.ui.app import CoutureUI, UIConfig
    from couture.ui.handles import plan_handles

    pat = draft(penelope)
    hs = plan_handles(penelope, pat)
    c, out = _far_corners(penelope, "back_left")[0]
    h = next(h for h in hs.handles if h.element == f"pt:back_left:{c}")
    d = h.element_delta(0.01 * out)
    preview = hs.moved_outlines(pat, h.element, d)
    committed = draft(apply_edit(penelope, h.element, d))
    for name in ("back_left", "back_right"):
        assert np.abs(preview[name] - pat.panel(name).outline).max() > 0.005
        assert np.abs(preview[name] - committed.panel(name).outline).max() < 1e-12

    ui = CoutureUI(UIConfig(port=free_port(), export_dir=tmp_path, show_body=False, draft_locally=False))
    ui.start()
    try:
        ui.set_design(penelope)
        ui.show_pattern(pat)
        got: list[Design] = []
        ui.on_design_changed = got.append
        back = pat.panel("back_left")
        seg = next(s for s in back.segments if s.name == "e1")
        idx = segment_span(len(back.outline), seg.start, seg.stop)
        ui.tools.arm("curve")
        ui.tools.click(ui.view2d.display("back_left", back.outline[idx[len(idx) // 2]]), "back_left")
        assert len(got) == 1
        curves = {(s.panel, s.params["segment"]): s.params["points"] for s in got[-1].strokes if s.kind == "curve"}
        twin = twin_segment(_piece(penelope, "back_left"), _piece(penelope, "back_right"), "e1")
        (s, dn), (s2, dn2) = curves[("back_left", "e1")][0], curves[("back_right", twin)][0]
        assert s2 == pytest.approx(1.0 - s) and dn == dn2 == 0.0 and len(curves) == 2
    finally:
        ui.stop()

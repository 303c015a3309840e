"""The waist-seamed dress (sloper ``dress_waist``): bodice and skirt joined at
the waist with darts, drafted from the body's measurements.

Geometry checks read the drafted polylines (not the sloper's formulas); the
body's girths come from ``couture.bodies.table()`` (measured from each mesh),
the reference the drafting is checked against."""

from __future__ import annotations

from pathlib import Path

import msgspec
import numpy as np
import pytest

from couture import bodies
from couture.pattern import SLOPERS, validate
from couture.pattern.draft import find_segment, segment_points
from couture.pattern.geometry import polyline_length
from couture.pattern.io import load_design
from couture.pattern.placement import _extents, place
from couture.pattern.slopers import waist_dart_widths
from schemas.design import Body, Design, Sloper

EXAMPLE = Path(__file__).resolve().parents[1] / "couture/pattern/examples/dress_waist.json"
TIERS = ("bodice", "skirt")
SIDES = ("front", "back")
PIECES = ("waist_left", "waist_center", "waist_right")
DEFAULTS = {o.name: o.default for o in SLOPERS["dress_waist"].options}


def _design(body: str = "default", params: dict | None = None) -> Design:
    return Design(sloper=Sloper(kind="dress_waist", params=params or {}), body=Body(name=body))


def _length(pattern, panel: str, seg: str) -> float:
    p, s = find_segment(pattern, panel, seg, "test")
    return polyline_length(segment_points(p, s))


def _measured(body: str) -> dict[str, float]:
    return next(r for r in bodies.table() if r["name"] == body)["measured"]


def _girths(pattern) -> dict[str, float]:
    """The pattern's girths: waist (waist pieces, darts closed, bodice and
    skirt), bust (bodice widths at the underarm height), hip (skirt widths at
    the hip line) [m], summed over front and back."""
    out = {}
    for tier in TIERS:
        out[f"{tier}_waist"] = sum(_length(pattern, f"{tier}_{s}", piece) for s in SIDES for piece in PIECES)
    return out


def _width_sum(pattern, tier: str, y: float) -> float:
    tot = 0.0
    for s in SIDES:
        lo, hi = _extents(pattern.panel(f"{tier}_{s}").outline, np.array([y]))
        tot += float(hi[0] - lo[0])
    return tot


def test_example_validates_remeshes_and_every_seam_is_sewn():
    from couture.remesh.meshing import mesh_pattern

    design = load_design(EXAMPLE)
    assert design.sloper.kind == "dress_waist"
    pattern = validate(design)
    assert sorted(p.name for p in pattern.panels) == ["bodice_back", "bodice_front", "skirt_back", "skirt_front"]
    res = mesh_pattern(pattern, 400, level="coarse")
    assert len(res.seam_names) == len(pattern.seams)
    for si in range(len(pattern.seams)):
        assert (res.seam_of_spring == si).sum() >= 1, pattern.seams[si]


def test_every_dart_is_present_and_sewn_leg_to_leg():
    pattern = validate(_design())
    dwb, dws, _ = waist_dart_widths(DEFAULTS)
    widths = {"bodice": dwb, "skirt": dws}
    expected = {f"{t}_{s}.waist_dart_{lr}": (f"{t}_{s}", widths[t]) for t in TIERS for s in SIDES for lr in "lr"}
    expected |= {
        f"bodice_front.bust_dart_{s}": ("bodice_front", DEFAULTS["bust_dart_width"]) for s in ("left", "right")
    }
    sewn = {(sp.a_panel, sp.a_segment, sp.b_panel, sp.b_segment) for sp in pattern.seams}
    for did, (panel, width) in expected.items():
        left, right = f"dart:{did}:left", f"dart:{did}:right"
        assert (panel, left, panel, right) in sewn, did
        p, sl = find_segment(pattern, panel, left, did)
        _, sr = find_segment(pattern, panel, right, did)
        L, R = segment_points(p, sl), segment_points(p, sr)
        # legs of one length meet at the point; the mouth is the dart's width
        assert np.allclose(L[-1], R[0]) and abs(polyline_length(L) - polyline_length(R)) < 1e-9, did
        mouth = np.linalg.norm(R[-1] - L[0])
        if "waist" in did:
            assert mouth == pytest.approx(width, abs=2e-4), did
        else:  # a stroke-style dart's width is along its (curved) armhole: the chord is close to it
            assert 0.8 * width < mouth < 1.25 * width, did
    n_dart_seams = sum(1 for sp in pattern.seams if sp.a_segment.startswith("dart:"))
    assert n_dart_seams == len(expected)


@pytest.mark.parametrize("body", ["default", "XL"])
def test_waist_and_side_seams_match_in_length(body):
    pattern = validate(_design(body))
    for s in SIDES:
        for piece in PIECES:  # the waist, piece by piece (darts closed: the pieces between them)
            a = _length(pattern, f"bodice_{s}", piece)
            b = _length(pattern, f"skirt_{s}", piece)
            assert a == pytest.approx(b, abs=1e-6), (s, piece)
    for t in TIERS:
        assert _length(pattern, f"{t}_front", "side_right") == pytest.approx(
            _length(pattern, f"{t}_back", "side_left"), abs=1e-6
        )
    assert _length(pattern, "bodice_front", "shoulder_right") == pytest.approx(
        _length(pattern, "bodice_back", "shoulder_left"), abs=1e-6
    )
    g = _girths(pattern)
    assert g["bodice_waist"] == pytest.approx(g["skirt_waist"], abs=1e-6)


@pytest.mark.parametrize("body", ["XS", "XL"])
def test_girths_follow_the_bodys_measurements(body):
    """Drafted on a graded body, the dress takes that body's measured girths
    (plus the ease options) and hangs at its measured waist height."""
    m = _measured(body)
    pattern = validate(_design(body))
    g = _girths(pattern)
    ease = DEFAULTS
    assert g["bodice_waist"] - m["waist_girth"] == pytest.approx(ease["waist_ease"], abs=2e-3)
    hu = m["underarm_y"] - m["waist_y"] - 0.03
    assert _width_sum(pattern, "bodice", hu) - m["bust_girth"] == pytest.approx(ease["bust_ease"], abs=3e-3)
    hip = -(m["waist_y"] - m["hip_y"])
    assert _width_sum(pattern, "skirt", hip) - m["hip_girth"] == pytest.approx(ease["hip_ease"], abs=3e-3)
    # the waist seam is placed at the body's waist
    bf = pattern.panel("bodice_front")
    assert place(bf, np.array([[0.0, 0.0]]))[0, 1] == pytest.approx(m["waist_y"], abs=0.01)


def test_two_bodies_draft_two_sizes_and_params_still_win():
    xs, xl = _measured("XS"), _measured("XL")
    gs, gl = _girths(validate(_design("XS"))), _girths(validate(_design("XL")))
    assert gl["bodice_waist"] - gs["bodice_waist"] == pytest.approx(xl["waist_girth"] - xs["waist_girth"], abs=2e-3)
    # an option the design sets is the design's, whatever the body
    g = _girths(validate(_design("XL", {"waist_girth": 0.70})))
    assert g["bodice_waist"] == pytest.approx(0.70 + DEFAULTS["waist_ease"], abs=2e-3)
    # the default body drafts from the option defaults (the mannequin's measurements)
    g0 = _girths(validate(_design("default")))
    assert g0["bodice_waist"] == pytest.approx(DEFAULTS["waist_girth"] + DEFAULTS["waist_ease"], abs=2e-3)


def test_one_piece_dress_keeps_the_mannequins_measurements_on_any_body():
    """Only body-fitted slopers follow the body: the one-piece dress (and its
    goldens) drafts the same pattern on XL as on the default body."""
    d0 = Design(sloper=Sloper(kind="dress"))
    p0, p1 = validate(d0), validate(msgspec.structs.replace(d0, body=Body(name="XL")))
    for a, b in zip(p0.panels, p1.panels, strict=True):
        np.testing.assert_array_equal(a.outline, b.outline)


def test_vertex_counts_do_not_depend_on_the_body():
    counts = [[len(p.outline) for p in validate(_design(b)).panels] for b in ("default", "XS", "XL")]
    assert counts[0] == counts[1] == counts[2]


@pytest.mark.slow
def test_coarse_drape_on_the_mannequin_dresses():
    """Coarse (about 400 vertices) drape on the default mannequin with friction
    reaches the dressed equilibrium (relative residual <= 1e-3), no vertex
    more than 2 mm inside the body, seams closed, not slid down."""
    from bench.drape_slopers import INSIDE_LIMIT, SLID_LIMIT, drape

    row, _, _ = drape("dress_waist", vertices=400, solvers=("newton", "kinetic"), max_seconds=30.0, tol=1e-3)
    assert row.residual <= 1e-3, row
    assert row.min_phi_mm >= INSIDE_LIMIT * 1e3, row
    assert row.top_drop_cm <= SLID_LIMIT * 100, row
    assert row.gap_max_cm <= 0.5, row


def test_option_jacobians_match_finite_differences_on_a_graded_body():
    """Edits of body-fitted options (the body's value is the base) move the
    outline as central differences of the draft say."""
    from test_pattern import check_edit_jacobian

    from couture.pattern import apply_edit

    d = _design("XL")
    for e in ("param:waist_girth", "param:bust_girth", "param:hip_girth", "param:skirt_dart_share"):
        check_edit_jacobian(d, e, np.array([1.0, 0.0]), nontrivial=1e-2)
    # the edit starts from the body's value, not the mannequin's
    edited = apply_edit(d, "param:waist_girth", np.array([0.01, 0.0]))
    assert edited.sloper.params["waist_girth"] == pytest.approx(_measured("XL")["waist_girth"] + 0.01, abs=1e-9)


def test_option_values_shown_are_the_bodys():
    """What an option control shows: the body's measurement for a body-fitted
    sloper (unless the design sets it), the design's params alone otherwise."""
    from couture.pattern.draft import option_values

    xl = _measured("XL")
    v = option_values(_design("XL", {"hip_girth": 1.10}))
    assert v["waist_girth"] == xl["waist_girth"] and v["hip_girth"] == 1.10
    assert option_values(_design("default")) == {}
    assert option_values(Design(sloper=Sloper(kind="dress"), body=Body(name="XL"))) == {}

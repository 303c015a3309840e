"""Pattern model: options, drafting over body sizes, errors naming elements,
sample-count invariance, edit Jacobians against central finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from fdcheck import assert_close, central

from couture.pattern import SLOPERS, PatternError, draft
from couture.pattern.edit import apply_edit, edit_elements, edit_jacobian
from couture.pattern.geometry import signed_area
from couture.pattern.validate import validate
from schemas.design import Design, Sloper, Stroke

BODY = ("waist_girth", "hip_girth", "bust_girth", "thigh_girth", "ankle_girth", "neck_girth", "upper_arm_girth")


def edited_skirt(**params) -> Design:
    return Design(
        sloper=Sloper(kind="skirt", params=params),
        strokes=[
            Stroke(
                id="c1", kind="curve", panel="gore0", params={"segment": "hem", "points": [[0.3, 0.02], [0.7, -0.01]]}
            ),
            Stroke(
                id="d1",
                kind="dart",
                panel="gore0",
                params={"segment": "waist", "position": 0.5, "width": 0.02, "length": 0.1},
            ),
            Stroke(
                id="h1",
                kind="hole",
                panel="gore1",
                params={"anchor": "hem", "position": 0.5, "depth": 0.2, "radius": 0.03},
            ),
            Stroke(
                id="d2",
                kind="dart",
                panel="gore2",
                params={"anchor": "waist", "position": 0.5, "depth": 0.12, "width": 0.02, "length": 0.14},
            ),
        ],
    )


def test_options_min_default_max():
    for kind, sd in SLOPERS.items():
        names = [o.name for o in sd.options]
        assert len(names) == len(set(names)), kind
        for o in sd.options:
            assert o.min <= o.default <= o.max, (kind, o)
            assert o.unit in ("m", "rad", "1", "count") and o.doc


@pytest.mark.parametrize("kind", sorted(SLOPERS))
def test_every_sloper_drafts_over_body_sizes(kind):
    opts = SLOPERS[kind].options
    body = [o for o in opts if o.name in BODY]
    sizes = []
    for f in (0.0, 0.25, 0.5, 0.75, 1.0):  # small to large bodies, extremes included
        sizes.append({o.name: o.min + f * (o.max - o.min) for o in body})
    for o in opts:  # each option alone at both extremes
        sizes += [{o.name: o.min}, {o.name: o.max}]
    for params in sizes:
        p = validate(Design(sloper=Sloper(kind=kind, params=params)))
        for panel in p.panels:
            assert signed_area(panel.outline) > 0
            assert all(len(h) for h in panel.holes)


def test_out_of_range_names_the_option():
    with pytest.raises(PatternError) as e:
        draft(Design(sloper=Sloper(kind="skirt", params={"length": 5.0})))
    assert e.value.element == "param:length"
    assert "5" in str(e.value) and "0.38" in str(e.value) and "1" in str(e.value)
    with pytest.raises(PatternError, match="param:nope"):
        draft(Design(sloper=Sloper(kind="skirt", params={"nope": 1.0})))
    with pytest.raises(PatternError, match="param:panels"):
        draft(Design(sloper=Sloper(kind="skirt", params={"panels": 3.5})))
    with pytest.raises(PatternError, match="sloper"):
        draft(Design(sloper=Sloper(kind="cape")))
    with pytest.raises(PatternError, match="param:waist_girth"):
        draft(Design(sloper=Sloper(kind="skirt", params={"waist_girth": float("nan")})))


def test_invalid_patterns_name_the_element():
    base = edited_skirt()
    # self-intersecting outline: a hem bulge that folds over itself
    bad = Design(
        sloper=base.sloper,
        strokes=[
            Stroke(
                id="fold", kind="curve", panel="gore0", params={"segment": "hem", "points": [[0.1, 0.9], [0.2, -0.9]]}
            )
        ],
    )
    with pytest.raises(PatternError) as e:
        validate(bad)
    assert "gore0" in e.value.element and "self-intersect" in str(e.value)
    # seams: unknown segment, sewn to itself, too unequal
    for prm, msg in (
        ({"a_panel": "gore0", "a_segment": "hemm", "b_panel": "gore1", "b_segment": "hem"}, "no segment"),
        ({"a_panel": "gore0", "a_segment": "hem", "b_panel": "gore0", "b_segment": "hem"}, "itself"),
        ({"a_panel": "gore0", "a_segment": "waist", "b_panel": "gore1", "b_segment": "side_left"}, "gather"),
    ):
        with pytest.raises(PatternError, match=msg) as e:
            validate(Design(sloper=base.sloper, strokes=[Stroke(id="s9", kind="seam", params=prm)]))
        assert e.value.element == "s9"
    # darts outside the panel
    with pytest.raises(PatternError) as e:
        validate(
            Design(
                sloper=base.sloper,
                strokes=[
                    Stroke(
                        id="dx",
                        kind="dart",
                        panel="gore0",
                        params={"anchor": "waist", "position": 0.5, "depth": 2.0, "width": 0.02, "length": 0.1},
                    )
                ],
            )
        )
    assert e.value.element == "dx"
    with pytest.raises(PatternError) as e:
        validate(
            Design(
                sloper=base.sloper,
                strokes=[
                    Stroke(
                        id="db",
                        kind="dart",
                        panel="gore0",
                        params={"segment": "waist", "position": 0.99, "width": 0.05, "length": 0.1},
                    )
                ],
            )
        )
    assert e.value.element == "db"
    # zero-length dart legs / non-finite values
    with pytest.raises(PatternError) as e:
        validate(
            Design(
                sloper=base.sloper,
                strokes=[
                    Stroke(
                        id="dz",
                        kind="dart",
                        panel="gore0",
                        params={"segment": "waist", "position": 0.5, "width": 0.0, "length": 0.1},
                    )
                ],
            )
        )
    assert e.value.element == "dz"
    with pytest.raises(PatternError) as e:
        validate(
            Design(
                sloper=base.sloper,
                strokes=[
                    Stroke(
                        id="c", kind="curve", panel="gore0", params={"segment": "hem", "points": [[0.5, float("inf")]]}
                    )
                ],
            )
        )
    assert e.value.element == "cv:gore0:hem:0"
    # zero-length segment: a degenerate outline check on a drafted pattern
    from couture.pattern.validate import check_pattern

    p = draft(base)
    pn = p.panels[1]
    s = next(s for s in pn.segments if s.name == "waist")
    pn.outline[s.start : s.stop + 1] = pn.outline[s.start]
    with pytest.raises(PatternError) as e:
        check_pattern(p)
    assert "gore1" in e.value.element


def _counts(p):
    return [
        (pn.name, len(pn.outline), [len(h) for h in pn.holes], [(s.name, s.start, s.stop) for s in pn.segments])
        for pn in p.panels
    ]


@pytest.mark.parametrize("kind", sorted(SLOPERS))
def test_sample_counts_do_not_depend_on_values(kind):
    opts = SLOPERS[kind].options
    ref = _counts(draft(Design(sloper=Sloper(kind=kind))))
    rng = np.random.default_rng(1)
    for _ in range(4):
        params = {o.name: float(rng.uniform(o.min, o.max)) for o in opts if not o.integer}
        try:
            p = draft(Design(sloper=Sloper(kind=kind, params=params)))
        except PatternError:
            continue
        assert _counts(p) == ref
    # stroke values too
    d = edited_skirt()
    ref = _counts(draft(d))
    d2 = apply_edit(apply_edit(d, "dart:d1:position", [0.03, 0.0]), "cv:gore0:hem:1", [0.02, 0.05])
    d2 = apply_edit(d2, "param:length", [0.2, 0.0])
    assert _counts(draft(d2)) == ref


def test_default_spacing():
    p = draft(Design())
    for pn in p.panels:
        e = np.linalg.norm(np.diff(np.vstack([pn.outline, pn.outline[:1]]), axis=0), axis=1)
        assert 0.002 < np.median(e) < 0.012


def check_edit_jacobian(design, element, dd, nontrivial=1e-3, h=1e-4):
    """The edit Jacobian of ``element`` along dd moves every outline and hole
    point as central differences of the drafts at ±h dd say (error relative
    to the largest motion, at least 1 m)."""
    J = edit_jacobian(design, element)

    def points(pattern):
        return np.vstack([P for pn in pattern.panels for P in (pn.outline, *pn.holes)])

    fd = central(lambda t: points(draft(apply_edit(design, element, t * dd))), 0.0, 1.0, h)
    an = np.vstack([Jp @ dd for pn in draft(design).panels for Jp in (J[pn.name].outline, *J[pn.name].holes)])
    return assert_close(an, fd, 1e-6, floor=1.0, nontrivial=nontrivial, what=element)


def test_edit_jacobians_match_finite_differences():
    d = edited_skirt()
    elements = edit_elements(d)
    assert {"cv:gore0:hem:0", "dart:d1:position", "dart:d2:width", "hole:h1:radius", "param:flare"} <= set(elements)
    dd = np.array([0.6, -0.8])
    for e in elements:
        check_edit_jacobian(d, e, dd if not e.startswith("param:") else np.array([1.0, 0.0]))
    # parameter Jacobians keep column 1 zero
    J = edit_jacobian(d, "param:hip_girth")
    assert np.all(J["gore0"].outline[:, :, 1] == 0)


@pytest.mark.parametrize("kind", ["dress", "shirt", "trousers"])
def test_param_jacobians_other_slopers(kind):
    d = Design(sloper=Sloper(kind=kind))
    for e in ["param:" + o.name for o in SLOPERS[kind].options if not o.integer][:4]:
        # nontrivial=None: the trousers' hip line is held by the crotch depth, waist_to_hip moves nothing
        check_edit_jacobian(d, e, np.array([1.0, 0.0]), nontrivial=None)
    if kind == "dress":  # a built-in dart is editable (override stroke)
        check_edit_jacobian(d, "dart:front.waist_dart_l:position", np.array([0.3, 0.5]))


def test_topology_option_has_no_jacobian():
    with pytest.raises(PatternError, match="param:panels"):
        edit_jacobian(Design(), "param:panels")
    with pytest.raises(PatternError, match="cv:gore0:waist:0"):
        edit_jacobian(edited_skirt(), "cv:gore0:waist:0")


def test_seams_and_darts_are_sewn():
    p = draft(edited_skirt())
    pairs = {(s.a_panel, s.a_segment, s.b_panel, s.b_segment) for s in p.seams}
    assert ("gore0", "dart:d1:left", "gore0", "dart:d1:right") in pairs
    assert ("gore2", "dart:d2:right", "gore2", "dart:d2:left") in pairs
    assert all(s.reverse for s in p.seams)  # CCW panels edge to edge, dart legs toward/away from apex


def test_symmetry_mirrors_live():
    half = Design(
        sloper=Sloper(kind="skirt", params={"panels": 2}),
        strokes=[
            Stroke(id="c1", kind="curve", panel="front", params={"segment": "hem", "points": [[0.3, 0.03]]}),
            Stroke(id="sym", kind="symmetry", panel="front", params={"axis": "waist"}),
        ],
    )
    p = validate(half)
    f = p.panel("front")
    names = {s.name for s in f.segments}
    assert {"hem", "hem_mirror", "side_left", "side_left_mirror"} <= names and "waist" not in names
    # mirrored hem equals the reflected hem
    assert signed_area(f.outline) > 0
    check_edit_jacobian(half, "cv:front:hem:0", np.array([0.4, 0.9]))

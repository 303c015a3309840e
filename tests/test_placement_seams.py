"""Initial placement: seams start nearly closed, the garment starts
outside the body; diamond darts (hole segments) are sewn.

Gaps are |x0[emitter] - receiving point| of the coarse mesh's seam springs.
Bounds are per sloper where the garment's own shape makes a closed start
impossible with wrap placements (measured; see each ``GAP_MAX``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.drape_slopers import coarse_mesh, seam_gaps

# median / max seam gap at x0 [m]. Skirt and trousers close to the goal
# (median <= 1 cm, max <= 3.5 cm: the waistband is tighter than body + 7 mm
# clearance; trouser back rise). Dress and shirt: the shoulder seams join the
# tops of front and back over the shoulder, which no wrap around a vertical
# axis can bring together (about 10 cm), and the shirt's sleeve caps are sewn
# to armholes on the torso ring (about 12 cm). The trousers' elastic waistband
# (cut to 75 % of the waist, ``waistband``) cannot reach round the body at the
# waist: each leg's half ring leaves the shortfall open at its centre seams
# (about 16 cm at the top, closed by the drape). The set-in shirt's collar
# starts round the neck above its neckline (about 4-5 cm: the neckline lies on
# the shoulders and chest, where the band would cross the body).
GAP_MEDIAN = {"skirt": 0.01, "dress": 0.01, "trousers": 0.01, "shirt": 0.10, "shirt_set_in": 0.08}
GAP_MAX = {"skirt": 0.035, "dress": 0.13, "shirt": 0.14, "trousers": 0.18, "shirt_set_in": 0.15}
CLEARANCE = {"skirt": 0.004, "dress": 0.001, "shirt": 0.002, "trousers": 0.0, "shirt_set_in": 0.002}


@pytest.fixture(scope="module")
def sdf():
    from couture.cloth.body import load_mannequin_sdf

    return load_mannequin_sdf(verbose=False)


def _extreme(kind: str, which: str) -> dict:
    from couture.pattern import SLOPERS

    keys = ("length", "flare", "sleeve_length", "hip_ease", "ease", "waist_ease")
    return {o.name: getattr(o, which) for o in SLOPERS[kind].options if o.name in keys}


@pytest.mark.parametrize("which", ["default"])
@pytest.mark.parametrize("kind", ["skirt", "dress", "shirt", "trousers", "shirt_set_in"])
def test_placement_closes_seams_outside_the_body(kind, which, sdf):
    params = {} if which == "default" else _extreme(kind, which)
    _, _, res = coarse_mesh(kind, 800, params)
    mesh = res.mesh
    g = seam_gaps(mesh, mesh.x0)
    assert np.median(g) <= GAP_MEDIAN[kind], (kind, which, np.median(g))
    assert g.max() <= GAP_MAX[kind], (kind, which, g.max())
    phi = sdf.phi_grad(mesh.x0)[0]
    assert phi.min() >= CLEARANCE[kind] - 0.006, (kind, which, phi.min())


def test_skirt_seams_close_to_the_goal(sdf):
    """The issue's numbers for the default skirt: median <= 1 cm, max <= 3.5 cm
    (was 8 / 10 cm on the cone), outside the body."""
    _, _, res = coarse_mesh("skirt", 1600)
    g = seam_gaps(res.mesh, res.mesh.x0)
    assert np.median(g) <= 0.01 and g.max() <= 0.035, (np.median(g), g.max())
    assert sdf.phi_grad(res.mesh.x0)[0].min() >= 0.004


def test_diamond_dart_is_sewn_across_its_hole():
    """skirt_edited.json has a diamond (interior) dart on gore3: springs join
    the two sides of the hole, at equal normalized arc length, and sewing it
    (moving every emitter onto its receiving point) closes it."""
    from couture.pattern.io import load_design
    from couture.pattern.validate import validate
    from couture.remesh.meshing import mesh_pattern
    from couture.remesh.seams import _arc, segment_chain

    design = load_design(Path(__file__).resolve().parents[1] / "couture/pattern/examples/skirt_edited.json")
    drafted = validate(design)
    res = mesh_pattern(drafted, 1600, level="coarse")
    names = [(s.a_panel, s.a_segment, s.b_panel, s.b_segment) for s in drafted.seams]
    si = names.index(("gore3", "dart:diamond:right", "gore3", "dart:diamond:left"))
    pi = res.mesh.panel_names.index("gore3")
    hole_loop = next(lp for lp in res.loops if lp.panel == pi and lp.loop == 1)
    right = segment_chain(res, pi, drafted.panels[pi], "dart:diamond:right")
    left = segment_chain(res, pi, drafted.panels[pi], "dart:diamond:left")
    assert set(right) <= set(hole_loop.chain) and set(left) <= set(hole_loop.chain)
    assert right[-1] == left[0] and left[-1] == right[0]  # the diamond's bottom and top tips

    sel = res.seam_of_spring == si
    assert sel.sum() >= 3
    mesh = res.mesh
    e, edges, w = mesh.seam_emitters[sel], mesh.seam_edges[sel], mesh.seam_weights[sel]
    emit_side, recv_side = (right, left[::-1]) if set(e) <= set(right) else (left[::-1], right)
    assert set(e) <= set(emit_side) and set(edges.ravel()) <= set(recv_side)
    # correspondence by normalized arc length (top to bottom on both sides)
    X = mesh.X
    ue = dict(zip(emit_side.tolist(), _arc(X, emit_side), strict=True))
    ur = dict(zip(recv_side.tolist(), _arc(X, recv_side), strict=True))
    u_recv = (1 - w) * np.array([ur[a] for a in edges[:, 0]]) + w * np.array([ur[b] for b in edges[:, 1]])
    np.testing.assert_allclose(u_recv, [ue[v] for v in e.tolist()], atol=1e-9)

    # at x0 the gap is at most the dart's width; sewn, the hole has zero width
    g = seam_gaps(mesh, mesh.x0)[sel]
    assert g.max() <= 0.02 + 1e-3
    Xs = X.copy()
    target = (1 - w)[:, None] * X[edges[:, 0]] + w[:, None] * X[edges[:, 1]]
    Xs[e] = target
    P = Xs[hole_loop.chain]
    area = 0.5 * abs(np.dot(P[:, 0], np.roll(P[:, 1], -1)) - np.dot(P[:, 1], np.roll(P[:, 0], -1)))
    assert area < 1e-6

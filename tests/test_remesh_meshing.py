"""mesh_pattern and seam springs on hand-built drafted patterns."""

import numpy as np
import pytest

from couture.pattern.drafted import DraftedPattern, Placement, SeamSpec
from couture.remesh import mesh_pattern, triangle_quality
from couture.remesh.fixtures import dart_panel, l_panel, rectangle_panel, sewn_pair, tube, u_panel
from couture.remesh.quality import boundary_edges
from couture.remesh.seams import segment_chain


def _signed_areas(X, T):
    e1 = X[T[:, 1]] - X[T[:, 0]]
    e2 = X[T[:, 2]] - X[T[:, 0]]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def _polygon_area(P):
    x, y = P[:, 0], P[:, 1]
    return 0.5 * (np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


@pytest.mark.parametrize("target,per_edge", [(1600, 12), (10000, 60)])
def test_vertex_count_quality_orientation(target, per_edge):
    d = tube(4, per_edge=per_edge)  # polylines sparser than the target spacing (they are all kept)
    r = mesh_pattern(d, target, level="coarse" if target < 5000 else "fine", generation=7)
    m = r.mesh
    assert abs(m.n_vertices - target) <= 0.15 * target
    assert m.level in ("coarse", "fine") and m.generation == 7
    areas = _signed_areas(m.X, m.tris)
    assert (areas > 0).all()
    total = sum(_polygon_area(p.outline) for p in d.panels)
    assert areas.sum() == pytest.approx(total, rel=1e-12)
    q = triangle_quality(m.X, m.tris)
    assert q.min() > 0.35 and q.mean() > 0.75  # 'q30': every angle >= 30 degrees
    # panels are separate pieces: no triangle mixes panels
    vp = r.vertex_panel
    assert (vp[m.tris] == m.tri_panel[:, None]).all()
    assert m.panel_names == [p.name for p in d.panels]


def test_polyline_vertices_kept_exactly_and_chains_on_edges():
    d = DraftedPattern([l_panel(per_edge=7), u_panel()])
    r = mesh_pattern(d, 3000)
    X = r.mesh.X
    for lp in r.loops:
        panel = d.panels[lp.panel]
        P = panel.outline if lp.loop == 0 else panel.holes[lp.loop - 1]
        assert np.array_equal(X[lp.poly_to_mesh], P)  # bit-exact, not moved
        k = len(P)
        recon = (1 - lp.chain_t)[:, None] * P[lp.chain_edge] + lp.chain_t[:, None] * P[lp.chain_next]
        np.testing.assert_allclose(X[lp.chain], recon, atol=1e-12)
        if lp.loop == 0:
            assert len(lp.chain) > k  # sparse polyline edges were subdivided
        # chain is in loop order: (edge, t) strictly increasing
        key = lp.chain_edge + lp.chain_t
        assert (np.diff(key) > 0).all()
    # the mesh boundary is exactly the chains (holes kept open, nothing leaks)
    be = {tuple(sorted(e)) for e in boundary_edges(r.mesh.tris).tolist()}
    ce = set()
    for lp in r.loops:
        c = lp.chain
        ce |= {tuple(sorted((int(a), int(b)))) for a, b in zip(c, np.roll(c, -1), strict=True)}
    assert be == ce


def test_hole_is_not_meshed():
    p = l_panel()
    r = mesh_pattern(DraftedPattern([p]), 2000)
    X, T = r.mesh.X, r.mesh.tris
    c = X[T].mean(axis=1)
    H = p.holes[0]
    lo, hi = H.min(axis=0), H.max(axis=0)
    inside = ((c > lo) & (c < hi)).all(axis=1)
    assert not inside.any()
    area = _polygon_area(p.outline) + _polygon_area(H)  # hole is clockwise: negative area
    assert _signed_areas(X, T).sum() == pytest.approx(area, rel=1e-12)


def test_boundary_spacing_matches_interior():
    r = mesh_pattern(DraftedPattern([rectangle_panel("r", 1.0, 1.0, per_edge=3)]), 2500)
    X, T = r.mesh.X, r.mesh.tris
    e = np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])
    mean_edge = np.linalg.norm(X[e[:, 0]] - X[e[:, 1]], axis=1).mean()
    c = r.loops[0].chain
    bl = np.linalg.norm(X[c] - X[np.roll(c, -1)], axis=1)
    assert 0.6 < bl.mean() / mean_edge < 1.4


def test_flat_layout_without_placement_keeps_panels_apart():
    # two panels drafted on top of each other in the plane
    d = DraftedPattern([rectangle_panel("a", 0.5, 0.5), rectangle_panel("b", 0.5, 0.5)])
    r = mesh_pattern(d, 800)
    x0 = r.mesh.x0
    assert np.all(x0[:, 2] == 0)
    xa = x0[r.vertex_panel == 0, 0]
    xb = x0[r.vertex_panel == 1, 0]
    assert xa.max() < xb.min()


def test_placement_uses_pattern_placement():
    placement = pytest.importorskip("couture.pattern.placement")
    p = rectangle_panel("a", 0.5, 0.5)
    p.placement = Placement("plane", origin=np.array([0.0, 1.0, 0.2]), u=np.array([1.0, 0, 0]), v=np.array([0, 1.0, 0]))
    r = mesh_pattern(DraftedPattern([p]), 500)
    np.testing.assert_allclose(r.mesh.x0, placement.place(p, r.mesh.X))


# ---------------------------------------------------------------- seams


def _arc(X, chain):
    s = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(X[chain], axis=0), axis=1))])
    return s / s[-1]


def test_unequal_seam_maps_by_normalized_arc_length():
    d = sewn_pair()
    r = mesh_pattern(d, 2000)
    m = r.mesh
    ca = segment_chain(r, 0, d.panels[0], "right")
    cb = segment_chain(r, 1, d.panels[1], "left")[::-1]  # reverse=True
    assert len(cb) > len(ca)  # b is longer and denser: b emits
    assert set(m.seam_emitters.tolist()) == set(cb.tolist())
    assert len(m.seam_emitters) == len(cb)
    # every receiving edge lies on a's segment, receiving points at equal normalized arc length
    ua = dict(zip(ca.tolist(), _arc(m.X, ca), strict=True))
    ub = dict(zip(cb.tolist(), _arc(m.X, cb), strict=True))
    for e, (a, b), w in zip(m.seam_emitters, m.seam_edges, m.seam_weights, strict=True):
        assert a in ua and b in ua and 0 <= w <= 1
        u_recv = (1 - w) * ua[int(a)] + w * ua[int(b)]
        assert u_recv == pytest.approx(ub[int(e)], abs=1e-12)
    # ends sewn to ends: the bottom corners and the top corners meet exactly
    ends = {
        int(e): (int(a), int(b), w) for e, (a, b), w in zip(m.seam_emitters, m.seam_edges, m.seam_weights, strict=True)
    }
    a0, b0, w0 = ends[int(cb[0])]
    assert (w0 == 0 and a0 == ca[0]) or (w0 == 1 and b0 == ca[0])
    a1, b1, w1 = ends[int(cb[-1])]
    assert (w1 == 1 and b1 == ca[-1]) or (w1 == 0 and a1 == ca[-1])
    assert (r.seam_of_spring == 0).all() and r.seam_names == [("a", "right", "b", "left")]


def test_seam_gap_is_zero_in_a_consistent_placement():
    """Springs are zero-length: in a 3D placement where the sewn edges
    coincide, emitter and receiving point coincide (equal lengths here)."""
    a = rectangle_panel("a", 0.5, 0.8, 10)
    b = rectangle_panel("b", 0.4, 0.8, 25, x0=0.5)  # b's left edge is a's right edge
    d = DraftedPattern([a, b], [SeamSpec("a", "right", "b", "left")])
    r = mesh_pattern(d, 1500)
    m = r.mesh
    recv = (1 - m.seam_weights)[:, None] * m.X[m.seam_edges[:, 0]] + m.seam_weights[:, None] * m.X[m.seam_edges[:, 1]]
    np.testing.assert_allclose(m.X[m.seam_emitters], recv, atol=1e-12)


def test_dart_notch_needs_no_special_case():
    d = dart_panel()
    r = mesh_pattern(d, 1500)
    m = r.mesh
    P = d.panels[0].outline
    tip_v = r.loops[0].poly_to_mesh[d.panels[0].segments[0].stop]
    assert np.allclose(m.X[tip_v], [0.3, 0.3])
    assert len(m.seam_emitters) > 0
    # no spring from the tip onto itself, no spring of a vertex to itself at all
    recv_vertex = np.where(
        m.seam_weights == 0, m.seam_edges[:, 0], np.where(m.seam_weights == 1, m.seam_edges[:, 1], -1)
    )
    assert not (recv_vertex == m.seam_emitters).any()
    assert tip_v not in m.seam_emitters[recv_vertex == tip_v]
    # the notch mouth corners are sewn to each other, mirrored legs meet by symmetry
    recv = (1 - m.seam_weights)[:, None] * m.X[m.seam_edges[:, 0]] + m.seam_weights[:, None] * m.X[m.seam_edges[:, 1]]
    em = m.X[m.seam_emitters]
    np.testing.assert_allclose(em[:, 0] - 0.3, -(recv[:, 0] - 0.3), atol=1e-12)
    np.testing.assert_allclose(em[:, 1], recv[:, 1], atol=1e-12)
    assert P.shape[0] == r.loops[0].n_poly


def test_tube_corners_get_no_double_springs():
    d = tube(4, per_edge=20)
    r = mesh_pattern(d, 3000)
    m = r.mesh
    target = np.where(m.seam_weights == 0, m.seam_edges[:, 0], np.where(m.seam_weights == 1, m.seam_edges[:, 1], -1))
    pairs = [(int(e), int(t)) for e, t in zip(m.seam_emitters, target, strict=True) if t >= 0]
    assert len(pairs) == len(set(pairs))
    # a vertex emits at most once per seam
    for s in range(len(d.seams)):
        e = m.seam_emitters[r.seam_of_spring == s]
        assert len(e) == len(np.unique(e))
    assert len(np.unique(r.seam_of_spring)) == 4


def test_rejects_bad_input():
    with pytest.raises(ValueError):
        mesh_pattern(DraftedPattern([]), 100)
    p = rectangle_panel("cw", 1, 1)
    p.outline = p.outline[::-1].copy()
    with pytest.raises(ValueError):
        mesh_pattern(DraftedPattern([p]), 100)
    d = sewn_pair()
    d.seams[0].a_segment = "nope"
    with pytest.raises(KeyError):
        mesh_pattern(d, 500)


def test_coarse_mesh_of_a_dense_polyline_keeps_segment_ends_and_corners():
    d = tube(4, per_edge=60)  # 7.5 mm polyline spacing, ~3 cm mesh spacing
    r = mesh_pattern(d, 1600, level="coarse")
    assert abs(r.mesh.n_vertices - 1600) <= 0.15 * 1600
    X = r.mesh.X
    for lp in r.loops:
        panel = d.panels[lp.panel]
        kept = lp.poly_to_mesh >= 0
        assert 0 < kept.sum() < lp.n_poly
        for s in panel.segments:  # segment ends (the corners here) always kept
            assert kept[s.start] and kept[s.stop]
        np.testing.assert_array_equal(X[lp.poly_to_mesh[kept]], panel.outline[kept])
        P = panel.outline
        recon = (1 - lp.chain_t)[:, None] * P[lp.chain_edge] + lp.chain_t[:, None] * P[lp.chain_next]
        np.testing.assert_allclose(X[lp.chain], recon, atol=1e-12)
    assert len(np.unique(r.seam_of_spring)) == 4

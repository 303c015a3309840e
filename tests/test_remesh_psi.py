"""Ψ: boundary interpolation + (positive) mean value coordinates inside."""

import numpy as np
import pytest
from fdcheck import check_jacobian

from couture.pattern.drafted import DraftedPattern, Panel, PanelJacobian
from couture.remesh import build_coordinates, follow_pattern, mesh_pattern, psi, triangle_quality
from couture.remesh.fixtures import l_panel, polyline, rect_corners, sewn_pair, u_panel


@pytest.fixture(scope="module")
def l_and_u():
    d = DraftedPattern([l_panel(), u_panel()])
    r = mesh_pattern(d, 2500)
    return d, r, build_coordinates(r, "pmvc"), build_coordinates(r, "mvc")


def _jac(d, fn):
    """PanelJacobians with J_i = fn(point) on every outline and hole vertex."""
    out = {}
    for p in d.panels:
        out[p.name] = PanelJacobian(
            np.array([fn(x) for x in p.outline]), [np.array([fn(x) for x in h]) for h in p.holes]
        )
    return out


def test_coordinates_are_a_partition_of_unity(l_and_u):
    _, r, cp, cm = l_and_u
    for c in (cp, cm):
        np.testing.assert_allclose(np.asarray(c.W.sum(axis=1)).ravel(), 1.0, atol=1e-12)
        np.testing.assert_allclose(np.asarray(c.L.sum(axis=1)).ravel(), 1.0, atol=1e-12)
    assert cp.W.data.min() >= 0.0  # positive mean value coordinates
    assert cm.W.data.min() < 0.0  # plain MVC goes negative in non-convex panels
    assert len(cp.interior) + len(cp.boundary) == r.mesh.n_vertices


@pytest.mark.parametrize("method", ["pmvc", "mvc"])
def test_linear_motions_are_reproduced_exactly(l_and_u, method):
    d, r, cp, cm = l_and_u
    c = cp if method == "pmvc" else cm
    A = np.array([[0.3, -0.2], [0.1, 0.7]])
    P = psi(c, _jac(d, lambda x: A))
    np.testing.assert_allclose(P, np.broadcast_to(A, P.shape), atol=1e-12)
    # an affine motion of the whole pattern moves the mesh by the same affine map
    G = np.array([[1.1, 0.2], [-0.05, 0.9]])
    t = np.array([0.3, -0.1])
    moved = DraftedPattern([Panel(p.name, p.outline @ G.T + t, [h @ G.T + t for h in p.holes]) for p in d.panels])
    np.testing.assert_allclose(follow_pattern(c, moved), r.mesh.X @ G.T + t, atol=1e-12)
    np.testing.assert_allclose(follow_pattern(c, d), r.mesh.X, atol=1e-13)  # reproduction


def _floater_mvc(r, v: np.ndarray, panel: int, values: np.ndarray) -> np.ndarray:
    """Floater's mean value interpolation at the point v of the boundary
    ``values`` (one row per mesh vertex) of ``panel``'s loops (outline and
    holes, signed angles), from the mesh's boundary polygons alone: a reference
    that shares nothing with build_coordinates' matrix."""
    num, den = 0.0, 0.0
    for lp in r.panel_loops(panel):
        P = r.mesh.X[lp.chain] - v
        Q = np.roll(P, -1, axis=0)
        ang = np.arctan2(P[:, 0] * Q[:, 1] - P[:, 1] * Q[:, 0], np.sum(P * Q, axis=1))
        t = np.tan(ang / 2)
        w = (np.roll(t, 1) + t) / np.linalg.norm(P, axis=1)
        num = num + np.tensordot(w, values[lp.chain], axes=1)
        den += w.sum()
    return num / den


def test_psi_interior_is_the_mean_value_interpolation_of_its_boundary(l_and_u):
    """Inside, Ψ (plain MVC coordinates) is Floater's mean value
    interpolation of its boundary rows, computed here from the boundary
    polygons without the coordinates' matrix; the boundary rows are J itself
    (test below). Both sides of the other Ψ tests go through the same matrix W,
    so a wrong W would pass them: this one would fail."""
    d, r, _, cm = l_and_u
    rng = np.random.default_rng(5)
    J = {
        p.name: PanelJacobian(
            rng.normal(size=(len(p.outline), 2, 2)), [rng.normal(size=(len(h), 2, 2)) for h in p.holes]
        )
        for p in d.panels
    }
    P = psi(cm, J)
    assert np.abs(P[cm.interior]).max() > 0.1
    for q in cm.interior[:: max(1, len(cm.interior) // 150)]:
        want = _floater_mvc(r, r.mesh.X[q], int(r.vertex_panel[q]), P)
        np.testing.assert_allclose(P[q], want, atol=1e-12)


def test_psi_is_the_mesh_motion_of_the_moved_polylines(l_and_u):
    """Ψ·Δd equals the mesh motion for polylines moved by J·Δd (the map is
    linear, so exactly): psi() and follow_pattern() agree. Both go through the
    same coordinates, so this is their consistency only; the values inside
    are checked against an independent mean value interpolation above, the
    boundary rows against J below."""
    d, r, cp, _ = l_and_u
    rng = np.random.default_rng(3)
    J = {
        p.name: PanelJacobian(
            rng.normal(size=(len(p.outline), 2, 2)), [rng.normal(size=(len(h), 2, 2)) for h in p.holes]
        )
        for p in d.panels
    }
    dd = np.array([0.013, -0.007])
    P = psi(cp, J)
    assert np.abs(P).max() > 0.1
    moved = DraftedPattern(
        [
            Panel(
                p.name,
                p.outline + J[p.name].outline @ dd,
                [h + jh @ dd for h, jh in zip(p.holes, J[p.name].holes, strict=True)],
            )
            for p in d.panels
        ]
    )
    np.testing.assert_allclose(follow_pattern(cp, moved) - r.mesh.X, P @ dd, atol=1e-13)
    # on the boundary: polyline vertices carry their J, inserted points interpolate their edge's ends
    for lp in r.loops:
        jac = J[r.mesh.panel_names[lp.panel]]
        Jl = jac.outline if lp.loop == 0 else jac.holes[lp.loop - 1]
        np.testing.assert_allclose(P[lp.poly_to_mesh], Jl, atol=1e-14)
        want = (1 - lp.chain_t)[:, None, None] * Jl[lp.chain_edge] + lp.chain_t[:, None, None] * Jl[lp.chain_next]
        np.testing.assert_allclose(P[lp.chain], want, atol=1e-14)


def test_panels_without_jacobian_stay_put():
    d = sewn_pair()
    r = mesh_pattern(d, 1200)
    c = build_coordinates(r)
    a = d.panels[0]
    P = psi(c, {"a": PanelJacobian(np.tile(np.eye(2), (len(a.outline), 1, 1)))})
    assert np.all(P[r.vertex_panel == 1] == 0)
    np.testing.assert_allclose(
        P[r.vertex_panel == 0], np.broadcast_to(np.eye(2), P[r.vertex_panel == 0].shape), atol=1e-12
    )
    with pytest.raises(ValueError):
        psi(c, {"a": PanelJacobian(np.zeros((3, 2, 2)))})


def _slot_u(gap=0.04):
    """A U whose arms are separated by a narrow slot, with a hole in its base."""
    g = gap / 2
    C = np.array(
        [[0, 0], [1, 0], [1, 1], [0.5 + g, 1], [0.5 + g, 0.3], [0.5 - g, 0.3], [0.5 - g, 1], [0, 1]], np.float64
    )
    P, _ = polyline(C, [20, 20, 10, 14, 2, 14, 10, 20])
    H, _ = polyline(rect_corners(0.2, 0.08, 0.4, 0.1), 6)
    return Panel("U", P, holes=[H[::-1].copy()])


@pytest.mark.parametrize("pull", [0.3, 0.6])
def test_pmvc_stays_inversion_free_where_mvc_inverts(pull):
    """SC Fig. 8: pull one arm of a slotted U (with a hole) upward, stretching
    it; plain MVC leaks the motion across the slot into the other arm with
    negative weights and inverts elements there, PMVC does not."""
    p = _slot_u()
    r = mesh_pattern(DraftedPattern([p]), 2000)
    x, y = p.outline[:, 0], p.outline[:, 1]
    ramp = np.clip((y - 0.3) / 0.7, 0, 1) * (x < 0.5)  # left arm, fading out at the base
    J = {
        "U": PanelJacobian(
            ramp[:, None, None] * np.array([[0.0, 0.0], [0.0, 1.0]]), [np.zeros((len(p.holes[0]), 2, 2))]
        )
    }
    dd = np.array([0.0, pull])
    inverted = {}
    for method in ("mvc", "pmvc"):
        Xn = r.mesh.X + psi(build_coordinates(r, method), J) @ dd
        inverted[method] = int((triangle_quality(Xn, r.mesh.tris) <= 0).sum())
    assert inverted["mvc"] > 0
    assert inverted["pmvc"] == 0


def test_pmvc_weights_ignore_hidden_boundary():
    """A point deep in one arm of the slotted U gives no weight to the far
    side of the other arm (hidden behind the slot walls)."""
    p = _slot_u()
    r = mesh_pattern(DraftedPattern([p]), 1500)
    c = build_coordinates(r, "pmvc")
    X = r.mesh.X
    q = c.interior[np.argmin(np.linalg.norm(X[c.interior] - [0.85, 0.9], axis=1))]
    row = c.W.getrow(int(np.flatnonzero(c.interior == q)[0]))
    bX = X[c.boundary[row.indices]]
    assert not np.any((bX[:, 0] < 0.05) & (bX[:, 1] > 0.5))  # the left arm's outer wall


@pytest.mark.parametrize(
    "element", ["param:length", "cv:gore0:hem:0", "dart:waist_dart:width", "dart:diamond:position"]
)
def test_jacobian_from_pattern_edit_matches_finite_differences(element):
    """With the pattern's own apply_edit: Ψ·Δd matches the FD motion of the mesh
    that follows the edited pattern (boundary and interior)."""
    from pathlib import Path

    from couture import pattern as pat
    from couture.pattern.io import load_design

    design = load_design(Path(pat.__file__).parent / "examples" / "skirt_edited.json")
    elements = pat.edit_elements(design)
    assert element in elements, elements
    r = mesh_pattern(pat.draft(design), 1600)
    c = build_coordinates(r)
    P = psi(c, pat.edit_jacobian(design, element))
    assert np.abs(P).max() > 0
    check_jacobian(
        lambda dd: follow_pattern(c, pat.draft(pat.apply_edit(design, element, dd))),
        lambda dd: P @ dd,
        np.zeros(2),
        h=1e-5,
        rtol=1e-4,
        dirs=np.eye(2),
        floor=1.0,
        nontrivial=None,  # a parameter moves nothing along its second column (P is not zero: above)
        what=element,
    )

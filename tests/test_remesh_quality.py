"""Quality, Delaunay flips, state transfer and coarse <-> fine maps."""

import numpy as np
import pytest

from couture.pattern.drafted import DraftedPattern, PanelJacobian
from couture.remesh import (
    build_coordinates,
    flip_to_delaunay,
    improve,
    mesh_pattern,
    prolong,
    prolongation,
    psi,
    restrict,
    restriction,
    transfer_state,
    triangle_quality,
)
from couture.remesh.fixtures import l_panel, rectangle_panel, sewn_pair
from couture.remesh.kernels import _incircle  # noqa: F401 (numba dispatcher, used below)
from couture.remesh.quality import boundary_edges, neighbours


def test_quality_measure():
    X = np.array([[0, 0], [1, 0], [0.5, np.sqrt(3) / 2], [0, 1], [0.5, 1e-9]])
    q = triangle_quality(X, np.array([[0, 1, 2], [0, 1, 3], [0, 2, 1], [0, 1, 4]]))
    assert q[0] == pytest.approx(1.0)
    # right isosceles: r_in = (2 - sqrt 2) / 2, l_max = sqrt 2
    assert q[1] == pytest.approx(2 * np.sqrt(3) * (2 - np.sqrt(2)) / 2 / np.sqrt(2))
    assert q[2] == pytest.approx(-1.0)  # inverted
    assert 0 < q[3] < 1e-8  # sliver


def _is_delaunay(X, T):
    N = neighbours(T)
    for t in range(len(T)):
        for i in range(3):
            u = N[t, i]
            if u < 0:
                continue
            b = [v for v in T[u] if v not in (T[t, (i + 1) % 3], T[t, (i + 2) % 3])][0]
            if _incircle(X, T[t, 0], T[t, 1], T[t, 2], b) > 1e-9:
                return False
    return True


def _tri_set(T):
    return {tuple(sorted(t)) for t in np.asarray(T).tolist()}


def test_flips_recover_the_constrained_delaunay_triangulation():
    """Stretch a mesh (valid but no longer Delaunay); flips give back exactly
    triangle's constrained Delaunay triangulation of the same points and boundary."""
    import triangle as tr

    d = DraftedPattern([l_panel()])
    r = mesh_pattern(d, 1200)
    c = build_coordinates(r)
    p = d.panels[0]
    J = {
        "L": PanelJacobian(
            np.array([[[x[0], 0], [0, 0]] for x in p.outline]), [np.array([[[x[0], 0], [0, 0]] for x in p.holes[0]])]
        )
    }
    X = r.mesh.X + psi(c, J) @ np.array([1.5, 0.0])  # stretch x by 2.5
    T = r.mesh.tris
    assert (triangle_quality(X, T) > 0).all()
    assert not _is_delaunay(X, T)
    T2 = flip_to_delaunay(X, T)
    assert T2.dtype == np.int32 and T2.shape == T.shape
    assert (triangle_quality(X, T2) > 0).all()
    assert _is_delaunay(X, T2)
    assert triangle_quality(X, T2).min() > triangle_quality(X, T).min()
    segs = np.concatenate([np.column_stack([lp.chain, np.roll(lp.chain, -1)]) for lp in r.loops])
    ref = tr.triangulate({"vertices": X, "segments": segs, "holes": [[0.15 * 2.5, 0.15]]}, "pQ")
    assert len(ref["vertices"]) == len(X)
    diff = _tri_set(T2) ^ _tri_set(ref["triangles"])
    # only (near-)cocircular ties may differ: the empty-circle check above is the real test
    assert len(diff) <= 0.03 * len(T)


def test_flips_keep_boundary_and_fixed_edges_and_positions():
    d = DraftedPattern([l_panel()])
    r = mesh_pattern(d, 1500)
    X = r.mesh.X.copy()
    rng = np.random.default_rng(1)
    # a shear of the interior degrades the Delaunay property but keeps triangles valid
    interior = np.setdiff1d(np.arange(len(X)), r.boundary_vertices())
    X[interior] += 0.0015 * rng.normal(size=(len(interior), 2))
    T = r.mesh.tris
    assert (triangle_quality(X, T) > 0).all()
    assert not _is_delaunay(X, T)
    fixed = np.array([[T[0, 0], T[0, 1]], [T[10, 1], T[10, 2]]])
    T2 = flip_to_delaunay(X, T, fixed)
    be = lambda T: {tuple(sorted(e)) for e in boundary_edges(T).tolist()}  # noqa: E731
    assert be(T2) == be(T)
    edges2 = {tuple(sorted(e)) for t in T2.tolist() for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
    for a, b in fixed.tolist():
        assert tuple(sorted((a, b))) in edges2
    q0, q2 = triangle_quality(X, T), triangle_quality(X, T2)
    assert (q2 > 0).all() and q2.min() >= q0.min() - 1e-12


def test_improve_flags_remesh_only_when_flips_do_not_help():
    d = DraftedPattern([rectangle_panel("r", 1.0, 1.0, 10)])
    r = mesh_pattern(d, 1000)
    c = build_coordinates(r)
    p = d.panels[0]
    # mild edit: stretch x by 20 %: flips are enough
    J = {"r": PanelJacobian(np.array([[[x[0], 0], [0, 0]] for x in p.outline]))}
    Xn = r.mesh.X + psi(c, J) @ np.array([0.2, 0])
    T, rep = improve(Xn, r.mesh.tris)
    assert not rep.needs_remesh and rep.n_inverted == 0
    # extreme edit: squash y by 97 %: every element is a sliver, flips cannot help
    J = {"r": PanelJacobian(np.array([[[0, 0], [0, x[1]]] for x in p.outline]))}
    Xn = r.mesh.X + psi(c, J) @ np.array([0.0, -0.97])
    T, rep = improve(Xn, r.mesh.tris)
    assert rep.needs_remesh


def test_transfer_state_reproduces_linear_fields_between_remeshes():
    d = DraftedPattern([l_panel()])
    a = mesh_pattern(d, 800).mesh
    b = mesh_pattern(d, 3000).mesh
    A = np.array([[0.2, -1.0, 0.5], [0.3, 0.1, 2.0]])
    x_old = a.X @ A + [0.0, 1.0, 0.1]
    v_old = a.X[:, :1] * 3.0 - 1.0
    out = transfer_state(a.X, a.tris, {"x": x_old, "v": v_old}, b.X)
    np.testing.assert_allclose(out["x"], b.X @ A + [0.0, 1.0, 0.1], atol=1e-9)
    np.testing.assert_allclose(out["v"], b.X[:, :1] * 3.0 - 1.0, atol=1e-9)
    # points outside the old domain take the nearest triangle's closest point
    far = np.array([[-0.5, 0.5], [0.6, 0.6]])  # left of the L; in the notch of the L
    y = transfer_state(a.X, a.tris, a.X.copy(), far)
    np.testing.assert_allclose(y[0], [0.0, 0.5], atol=1e-9)
    assert y[1][0] <= 0.3 + 1e-9 or y[1][1] <= 0.3 + 1e-9
    assert np.linalg.norm(y[1] - far[1]) == pytest.approx(0.3, abs=1e-9)


def test_prolongation_and_restriction_are_panel_aware():
    # two panels drafted on top of each other: a map that ignored panels would mix them
    d = sewn_pair()
    d.panels[1].outline = d.panels[1].outline - [0.7, 0.0]
    coarse = mesh_pattern(d, 600, level="coarse").mesh
    fine = mesh_pattern(d, 3000, level="fine").mesh
    parent, bary = prolongation(coarse, fine)
    assert parent.shape == (fine.n_vertices,) and bary.shape == (fine.n_vertices, 3)
    fine_panel = np.full(fine.n_vertices, -1)
    fine_panel[fine.tris.ravel()] = np.repeat(fine.tri_panel, 3)
    assert (coarse.tri_panel[parent] == fine_panel).all()
    assert (bary >= 0).all()
    np.testing.assert_allclose(bary.sum(axis=1), 1.0)
    # a per-panel field (different on each panel, same X) comes through untouched
    field_c = np.where(np.isin(np.arange(coarse.n_vertices), coarse.tris[coarse.tri_panel == 1]), 1.0, 0.0)
    field_c = np.column_stack([field_c, coarse.X])  # plus a linear field
    f = prolong(coarse, parent, bary, field_c)
    np.testing.assert_allclose(f[:, 0], (fine_panel == 1).astype(float), atol=1e-12)
    np.testing.assert_allclose(f[:, 1:], fine.X, atol=1e-9)
    parent_r, bary_r = restriction(fine, coarse)
    g = restrict(fine, parent_r, bary_r, f)
    np.testing.assert_allclose(g, field_c, atol=1e-9)

"""The ellipsoid proxy in use (Meng 2010 §4): a try-on drag slides along it
and ends outside the exact body (checked with the exact mesh distance, not
the proxy or the grid), the solver service keeps one proxy per body, and
picking the body by a ray through the proxy lands within the fit error of
where a brute-force ray-triangle cast meets the mannequin mesh."""

from __future__ import annotations

import math

import msgspec
import numpy as np
import pytest
from fdcheck import along_axes, assert_close

from bench.drape_slopers import coarse_mesh
from couture.cloth.body import TriangleMeshDistance, load_mannequin_mesh, load_mannequin_sdf
from couture.cloth.proxy import load_mannequin_proxy, mannequin_regions
from couture.tryon import TORSO_AXIS_POINT, TryOn, drag, panel_vertices
from couture.ui.geometry import pick_body, ray_hit


@pytest.fixture(scope="module")
def bodies():
    V, F = load_mannequin_mesh()
    return V, F, TriangleMeshDistance(V, F), load_mannequin_sdf(verbose=False), load_mannequin_proxy(verbose=False)


@pytest.fixture(scope="module")
def skirt():
    _, _, res = coarse_mesh("skirt", 400)
    return res.mesh


def _azimuth(p):
    r = np.asarray(p) - TORSO_AXIS_POINT
    return math.atan2(r[0], r[2])


def test_exact_mesh_phi_grad_is_the_distance_and_its_gradient(bodies):
    """TriangleMeshDistance.phi_grad (the exact body the proxy is judged on):
    phi equals the distance call, grad its central differences, |grad| = 1."""
    V, F, dist, _, _ = bodies
    rng = np.random.default_rng(3)
    idx = rng.choice(len(V), 300, replace=False)
    n = V[idx] - V.mean(axis=0)
    P = V[idx] + 0.03 * rng.uniform(-0.3, 1.0, (300, 1)) * n / np.linalg.norm(n, axis=1)[:, None]
    phi, g = dist.phi_grad(P)
    np.testing.assert_array_equal(phi, dist(P))
    fd = along_axes(dist, P, 1e-6)
    ok = np.abs(phi) > 1e-4  # off the medial creases' immediate surroundings
    assert_close(g[ok], fd[ok], 1e-4, what="exact mesh distance gradient")
    np.testing.assert_allclose(np.linalg.norm(g, axis=1), 1.0, atol=1e-12)


def test_drag_along_the_proxy_ends_outside_the_exact_body(skirt, bodies):
    """Random drags of every gore with the proxy as guide: the exact mesh
    distance of every panel vertex is >= the contact offset (so outside the
    true body, with the layer kept), the grid body's too, and the panel turned
    and rose by what was asked (its centroid's azimuth and height)."""
    _, _, dist, grid, proxy = bodies
    m = skirt
    rng = np.random.default_rng(7)
    offset = 0.01
    st = TryOn.start(m)
    for _ in range(6):
        p = int(rng.integers(4))
        v = panel_vertices(m, p)
        turn, rise = rng.uniform(-1.0, 1.0), rng.uniform(-0.15, 0.05)
        before = st.x[v].mean(axis=0)
        st.apply("drag", panel=p, angle=turn, vector=[0, rise, 0], body=grid, offset=offset, guide=proxy)
        after = st.x[v].mean(axis=0)
        assert dist.phi_grad(st.x[v])[0].min() >= offset - 1e-6
        assert grid.phi_grad(st.x[v])[0].min() >= offset - 1e-6
        dturn = (_azimuth(after) - _azimuth(before) + math.pi) % (2 * math.pi) - math.pi
        assert abs(dturn - turn) < 0.1  # the push-out moves it radially, not around
        assert abs((after[1] - before[1]) - rise) < 0.03  # nor (much) up or down
    # the proxy holds the panel off the body by about its fit error: farther than the grid alone
    v = panel_vertices(m, 0)
    x_proxy = drag(m.x0, v, grid, turn=0.4, offset=offset, guide=proxy)
    x_grid = drag(m.x0, v, grid, turn=0.4, offset=offset)
    assert np.median(dist(x_proxy[v])) > np.median(dist(x_grid[v]))
    assert dist(x_proxy[v]).max() < dist(x_grid[v]).max() + 0.025


def test_solver_service_drags_along_one_proxy_per_body(skirt, bodies):
    """SolveService.drag_guide: the design's body's proxy, loaded once and
    kept while the body stays, loaded again for another body; none for a
    scene without a body or with tryon_guide='body'; a bad guide is named."""
    from couture.solvers.service import SolveService
    from schemas.design import Design

    proxy = bodies[4]
    asked: list[str] = []

    def loader(name: str):
        asked.append(name)
        return proxy

    s = SolveService(method="newton", proxy_loader=loader)
    s.design = msgspec.convert({"sloper": {"kind": "skirt"}}, Design)
    assert s.drag_guide() is proxy
    assert s.drag_guide() is proxy
    assert asked == ["default"]
    s.design = msgspec.convert({"sloper": {"kind": "skirt"}, "body": {"name": "S"}}, Design)
    s.drag_guide()
    assert asked == ["default", "S"]
    s.design = msgspec.convert({"sloper": {"kind": "skirt"}, "scene": {"body": False}}, Design)
    assert s.drag_guide() is None
    assert SolveService(method="newton", tryon_guide="body", design=s.design).drag_guide() is None
    with pytest.raises(ValueError, match="tryon_guide 'ellipsoids'"):
        SolveService(method="newton", tryon_guide="ellipsoids")


def test_pick_body_lands_within_the_fit_error_of_the_mesh_hit(bodies):
    """Rays from cameras around the mannequin: where the brute-force
    Möller-Trumbore cast hits the mesh, pick_body hits too, no later along the
    ray, at a point whose exact distance to the body is within its leaf's
    fit error, mostly in the same region; a ray past the body misses both."""
    V, F, dist, _, proxy = bodies
    rng = np.random.default_rng(2)
    hits = 0
    same_region = 0
    for k in range(40):
        a = 2 * math.pi * k / 40
        eye = np.array([2.5 * math.sin(a), rng.uniform(-0.5, 0.8), 2.5 * math.cos(a)])
        target = V[rng.integers(len(V))] + rng.normal(0, 0.02, 3)
        d = target - eye
        mesh = ray_hit(V, F, eye, d / np.linalg.norm(d))
        pick = pick_body(eye, d, proxy)
        if mesh is None:
            continue
        hits += 1
        assert pick is not None, k
        t_mesh = mesh[1]
        assert pick.t <= t_mesh + 1e-3  # the proxy bounds the body (up to its surface sampling)
        sd = float(dist(pick.point[None])[0])
        assert -1e-3 <= sd <= pick.error + 1e-3, (k, sd, pick.error)
        assert abs(float(pick.normal @ d)) > 0 and pick.normal @ d < 0  # faces the eye
        hit_point = eye + t_mesh * d / np.linalg.norm(d)
        same_region += mannequin_regions(hit_point[None])[0] == pick.region
    assert hits >= 30
    assert same_region >= 0.85 * hits
    assert pick_body([0.0, 2.0, 3.0], [0.0, 0.0, -1.0], proxy) is None  # above the head
    assert ray_hit(V, F, np.array([0.0, 2.0, 3.0]), np.array([0.0, 0.0, -1.0])) is None
    with pytest.raises(ValueError, match="nonzero"):
        pick_body([0.0, 0.0, 3.0], [0.0, 0.0, 0.0], proxy)

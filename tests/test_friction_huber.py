"""Elasto-plastic ('huber') friction: one smooth energy, no slip events.

``Scene(friction_model="huber")`` replaces the anchor springs that slip in
events by the potential k_t/2 |d|² (sticking, k_t |d| <= c) or c |d| - c²/(2 k_t)
(sliding) of each anchored vertex's tangential displacement d from its anchor,
with the Coulomb limit c = mu_s f_n lagged (refreshed at a balance). Checked
here: the energy's gradient and Hessian against central differences in both
regimes, and the closed form of a sheet on an incline (it holds below mu_s with
friction/contact = tan(theta), and is never called converged above it), with
Newton and kinetic damping.
"""

from __future__ import annotations

import numpy as np
import pytest
from fdcheck import check_gradient, check_hessian
from solver_testmodel import fabric

from couture.cloth import ClothModel, Scene
from couture.cloth.body import PlaneBody, SphereBody
from couture.mesh import grid_sheet
from couture.solvers import get_solver
from couture.solvers.common import verdict


def incline(tan_theta: float) -> ClothModel:
    """A 0.2 m sheet on a plane tilted by theta, 1 mm inside the 1 cm contact layer, no pins."""
    sheet = grid_sheet(0.2, 0.2, 8, 8)
    n = np.array([0.0, 1.0, tan_theta]) / np.hypot(1.0, tan_theta)
    t = np.array([0.0, -tan_theta, 1.0]) / np.hypot(1.0, tan_theta)
    X = sheet.X
    sheet.x0 = X[:, :1] * np.array([1.0, 0.0, 0.0]) + X[:, 1:2] * t + 0.009 * n
    scene = Scene(body=PlaneBody(point=np.zeros(3), normal=n), friction=True, friction_model="huber")
    return ClothModel(sheet, fabric(stretch=500.0, bend=1e-6), scene)


def _sheet_on_sphere() -> ClothModel:
    m = grid_sheet(0.3, 0.3, 8, 8)
    X = m.X
    m.x0 = np.column_stack([X[:, 0] - 0.15, np.full(len(X), 0.2005), X[:, 1] - 0.15])
    m.pinned = np.zeros(0, np.int32)
    scene = Scene(body=SphereBody(center=np.zeros(3), radius=0.2), friction=True, friction_model="huber")
    return ClothModel(m, fabric(stretch=500.0, bend=1e-6), scene)


@pytest.mark.parametrize("move, sliding", [(1e-6, False), (3e-3, True)], ids=["sticking", "sliding"])
def test_friction_gradient_and_hessian_match_central_differences(move, sliding):
    m = _sheet_on_sphere()
    x0 = m.mesh.x0.copy()
    m.update_friction(x0)
    assert m.anchored.sum() >= 3 and (m.friction_limit[m.anchored] > 0).all()
    rng = np.random.default_rng(1)
    x = x0 + rng.normal(scale=move, size=x0.shape)
    f = m.forces(x, ["friction"])
    held = np.linalg.norm(f[m.anchored], axis=1)
    at_limit = held >= m.friction_limit[m.anchored] * (1 - 1e-12)
    assert at_limit.any() == sliding
    K = m.stiffness(x, ["friction"]).toarray()
    assert np.allclose(K, K.T) and np.linalg.eigvalsh(K).min() > -1e-9 * np.abs(K).max()
    h = 1e-7 * max(move, 1e-4)
    check_gradient(lambda y: m.energy(y, ["friction"]), -f, x, h=h, rtol=1e-5, what="friction gradient")
    check_hessian(lambda y: -m.forces(y, ["friction"]), K, x, h=h, rtol=1e-5)
    # the force never exceeds its lagged Coulomb limit
    assert (held <= m.friction_limit[m.anchored] * (1 + 1e-12)).all()


@pytest.mark.parametrize("method", ["newton", "kinetic"])
def test_huber_sheet_holds_on_a_slope_below_mu_s(method):
    """tan(theta) = 0.4 < mu_s = 0.5: a static equilibrium, every anchor inside its
    cone, and the body's friction balances the weight's slope component:
    |sum friction| / |sum contact| = tan(theta)."""
    m = incline(0.4)
    res = get_solver(method).solve(m, m.mesh.x0, tol=1e-6, max_seconds=60)
    assert res.converged, res.diagnosis
    print(f"{method}: {res.iterations} iterations, residual {res.residual:.2e}, slip events {res.stats.get('slipped')}")
    assert res.stats.get("slipped", 0) == 0
    friction = m.forces(res.x, ["friction"]).sum(axis=0)
    contact = m.forces(res.x, ["contact"]).sum(axis=0)
    assert np.linalg.norm(friction) / np.linalg.norm(contact) == pytest.approx(0.4, rel=1e-3)


@pytest.mark.parametrize("method", ["newton", "kinetic"])
def test_huber_no_equilibrium_above_mu_s_is_never_called_converged(method):
    m = incline(0.7)
    res = get_solver(method).solve(m, m.mesh.x0, tol=1e-6, max_seconds=10, max_iters=300)
    assert not res.converged and res.diagnosis
    ok, _, _ = verdict(m, res.x, 1e-6)
    assert not ok


def test_a_huber_design_drapes_through_the_solver_service_with_its_state_carried():
    """What ships: a design that asks for 'huber' friction, built as the solver node
    builds it (SolveService from the design), drapes coarse then fine; the fine
    level starts from the coarse level's anchors (carried, not released) and both
    levels converge without a slip event."""
    import msgspec

    from couture.pattern.io import EXAMPLES, load_design
    from couture.remesh.service import RemeshService
    from couture.solvers import cascadic
    from couture.solvers.service import SolveService
    from schemas.design import Resolution

    design = load_design(EXAMPLES / "default_skirt.json")
    design = msgspec.structs.replace(
        design,
        resolution=Resolution(coarse_vertices=200, fine_vertices=600),
        scene=msgspec.structs.replace(design.scene, friction=True, friction_model="huber"),
    )
    service = SolveService(method="newton")
    service.set_design(design)
    for up in RemeshService().set_design(design, 1):
        prolong = None
        if up.fine_parent_tri is not None and up.fine_bary is not None:
            prolong = (up.fine_parent_tri, up.fine_bary)
        service.set_mesh(up.level, up.mesh, up.mesh_generation, prolong)
    assert service.levels["fine"].model.friction_model == "huber"
    carried: list[int] = []
    real = cascadic.carry_friction

    def spy(*a, **kw):
        carried.append(real(*a, **kw))
        return carried[-1]

    import couture.solvers.service as svc

    old, svc.carry_friction = svc.carry_friction, spy
    try:
        runs = {run.level: run for run in service.run()}
    finally:
        svc.carry_friction = old
    assert runs["fine"].warm_start == "prolongated"
    assert carried and carried[0] > 0, "no anchor was carried from the coarse level"
    for level, run in runs.items():
        assert run.result.converged, f"{level}: {run.result.diagnosis}"
        assert run.result.stats.get("slipped", 0) == 0
    model = service.levels["fine"].model
    ok, _, why = verdict(model, runs["fine"].result.x, 1e-4)
    assert ok, why
    assert model.anchored.any()

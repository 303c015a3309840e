"""Sensitivity columns against finite differences of re-solved equilibria, the
bending floor, the near-singular fallback (SC §7) and exact free modes."""

from __future__ import annotations

import numpy as np
import pytest
from fdcheck import assert_close, central
from sens_testmodel import SimpleFabric, sheet_pinned_corners, strip_over_sphere

from couture.cloth.testing import newton
from couture.sensitivity import SensitivityFactor
from couture.sensitivity.bending import model_bending


def resolve(model, X, x_start, tol=1e-10):
    model.set_rest_positions(X)
    x, hist = newton(model, x_start, tol=tol, max_iters=60)
    assert hist[-1] < 10 * tol, hist[-5:]
    return x


def resolve_no_gravity(model, X, x_start, force_tol=1e-10):
    """Newton with the null modes gauged out (the factor as a linear solver:
    the forces of this scene have no component along its free modes). The
    project's Newton crawls on the singular K, so converge on an absolute force."""
    model.set_rest_positions(X)
    x = np.array(x_start, dtype=np.float64)
    for _ in range(30):
        f = model.forces(x)
        if np.linalg.norm(f) < force_tol:
            return x
        x = x + SensitivityFactor(model, x, bend_floor=False, check=False).solve(f)
    raise AssertionError(f"no convergence: |f| = {np.linalg.norm(model.forces(x)):.3g}")


def fd_columns(make_model, x_eq, psi, h, resolve=resolve):
    """Central differences of equilibria re-solved at X ± h psi_j."""
    m = make_model()
    X = m.X.copy()
    return np.stack([central(lambda Xp: resolve(m, Xp, x_eq), X, psi[:, :, j], h) for j in range(psi.shape[2])], axis=2)


def relerr(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def stretch_psi(X):
    """d1 stretches material x, d2 shears y with x (a non-uniform edit)."""
    psi = np.zeros((len(X), 2, 2))
    psi[:, 0, 0] = X[:, 0] - X[:, 0].min()
    psi[:, 1, 1] = (X[:, 1] - X[:, 1].min()) * (X[:, 0] - X[:, 0].min())
    return psi


@pytest.fixture(scope="module")
def sheet():
    m = sheet_pinned_corners()
    x, hist = newton(m, m.mesh.x0, tol=1e-12)
    assert hist[-1] < 1e-11
    return m, x


@pytest.fixture(scope="module")
def strip():
    from couture.solvers.newton import NewtonSolver

    m = strip_over_sphere()
    r = NewtonSolver().solve(m, m.mesh.x0, tol=1e-10, max_iters=800)
    assert r.converged, r.diagnosis
    assert r.x[:, 0].max() > 0.15  # draped over the sphere, not slid off
    return m, r.x


def test_bending_matrix_annihilates_affine_and_matches_model():
    m = sheet_pinned_corners()
    A = np.column_stack([np.ones(m.n), m.X])
    k_b, Qm = model_bending(m)
    assert k_b == m.bend_stiffness and abs(Qm).max() > 0
    # per unit k_b, the model's own bending matrix
    assert abs(Qm * k_b - m.Qbend).max() < 1e-9 * abs(m.Qbend).max()
    # a flat or rigidly moved sheet has no bending energy
    assert np.abs(Qm @ A).max() < 1e-9 * abs(Qm).max()


def test_sheet_columns_match_finite_differences(sheet):
    m, x = sheet
    psi = stretch_psi(m.X)
    f = SensitivityFactor(m, x, bend_floor=False)
    assert f.info.fallback == "" and f.info.exact_hessian and f.info.null_modes == 0
    S = f.columns(psi)
    assert np.abs(S).max() > 1e-3  # not trivially zero
    assert np.all(S[~m.free] == 0)
    fd = fd_columns(sheet_pinned_corners, x, psi, 1e-4)
    for j in range(2):
        assert_close(S[:, :, j], fd[:, :, j], 1e-3, ord=2, what=f"column {j}")
    # SuperLU (always available) agrees with the default backend
    lu = SensitivityFactor(m, x, bend_floor=False, backend="splu")
    assert lu.info.backend == "splu"
    assert relerr(lu.columns(psi), S) < 1e-10


def test_sphere_drape_columns_match_finite_differences(strip):
    """Contact on a curved body: the columns include the body-curvature term
    of the contact Hessian (the model's own, the sphere giving its SDF Hessian;
    counted once)."""
    m, x = strip
    psi = stretch_psi(m.X)
    f = SensitivityFactor(m, x)  # the node's configuration: no regularization needed here
    assert f.info.regularization == "none"
    S = f.columns(psi)
    fd = fd_columns(strip_over_sphere, x, psi, 1e-4)
    for j in range(2):
        assert np.abs(fd[:, :, j]).max() > 1e-2
        assert_close(S[:, :, j], fd[:, :, j], 1e-3, ord=2, what=f"column {j}")
    # SC's always-on floor, for the record: its measured effect and its error are
    # both percent-level on this 1e-6 N m fabric (~2000x its bending added)
    floored = SensitivityFactor(m, x, bend_floor=True)
    Sf = floored.columns(psi)
    assert relerr(Sf, fd) > 1e-2 and floored.info.regularization_effect > 1e-2


def test_press_rhs_is_the_models_derivative_and_matches_rebuilt_models(strip):
    """The factor's matrix-free right-hand side is the model's own ∂F/∂X·dX
    (presses use ∂F/∂X assembled at refactorization, equal to it:
    test_sensitivity_press), checked here against models rebuilt at X ± h dX,
    the bending part alone not trivially zero."""
    m, x = strip
    f = SensitivityFactor(m, x, bend_floor=False)
    rng = np.random.default_rng(5)

    def bending_forces_at(X):
        rebuilt = strip_over_sphere()
        rebuilt.set_rest_positions(X)
        return rebuilt.forces(x, ["bending"])

    for dX in (stretch_psi(m.X)[:, :, 0], rng.normal(size=(m.n, 2))):
        a = f.dforces_dX(dX)
        np.testing.assert_array_equal(a, m.dforces_dX(x, dX))
        bend = m.dforces_dX(x, dX, terms=["bending"])
        assert np.abs(bend).max() > 1e-6 * np.abs(a).max()
        assert_close(bend, central(bending_forces_at, m.X, dX, 1e-6), 1e-6, what="bending dF/dX")


def test_parameter_column_is_the_psi_column(sheet):
    m, x = sheet
    f = SensitivityFactor(m, x)
    psi = stretch_psi(m.X)
    S = f.columns(psi)
    assert np.allclose(f.param_column(psi[:, :, 0]), S[:, :, 0], atol=1e-12 * np.abs(S).max())


def test_bend_floor_is_applied_only_on_request_and_reported(sheet):
    m, x = sheet
    # the default (the node's) factors the exact linearisation: nothing added
    plain = SensitivityFactor(m, x)
    assert plain.info.bend_added == 0.0 and plain.info.shift == 0.0 and plain.info.exact_hessian
    assert plain.info.regularization == "none" and not plain.info.regularized
    f = SensitivityFactor(m, x, bend_floor=True)  # SC's always-on floor, opt-in
    L = np.linalg.norm(m.X.max(0) - m.X.min(0))
    k_floor = 1e-4 * (m.lam + m.mu) * L**2
    assert f.info.bend_floor == pytest.approx(k_floor)
    assert f.info.bend_added == pytest.approx(k_floor - m.bend_stiffness)
    assert f.info.regularized and "N m bending" in f.info.regularization
    # its effect on the prediction is measured once columns are computed
    psi = stretch_psi(m.X)
    S, S0 = f.columns(psi), plain.columns(psi)
    eff = f.info.regularization_effect
    assert eff > 1e-3 and plain.info.regularization_effect == 0.0
    assert f"effect {eff:.1e}" in f.info.regularization
    # it is the relative residual of the floored columns in the exact system
    assert relerr(S, S0) > 1e-3
    # a model already stiffer than the floor is left alone
    stiff = sheet_pinned_corners(fabric=SimpleFabric(bend_stiffness=10 * k_floor))
    x2, _ = newton(stiff, stiff.mesh.x0, tol=1e-10)
    assert SensitivityFactor(stiff, x2).info.bend_added == 0.0


def cantilever(bend):
    """A thin plate clamped along one edge, flat, without gravity: its normal
    displacements are held only by bending (SC §7 'Full-rank')."""
    from couture.cloth.model import ClothModel, Scene
    from couture.mesh import grid_sheet

    mesh = grid_sheet(0.4, 0.1, 13, 5)
    X = mesh.X
    mesh.pinned = np.nonzero(X[:, 0] < 1e-9)[0].astype(np.int32)
    mesh.x0 = np.column_stack([X[:, 0], np.zeros(len(X)), X[:, 1]])
    return ClothModel(mesh, SimpleFabric(bend_stiffness=bend), Scene(gravity=False))


def test_near_singular_cantilever_falls_back_to_thick_bending():
    m = cantilever(1e-13)
    x = m.mesh.x0.copy()
    f = SensitivityFactor(m, x)  # as the node runs it: regularized only because it must be
    assert f.info.fallback and "near-singular" in f.info.fallback
    assert f.info.bend_added == pytest.approx(f.info.bend_floor - m.bend_stiffness)
    assert f.info.lambda_min_rel >= 1e-10
    assert "near-singular" in f.info.regularization
    # the response is finite and in-plane for an in-plane edit
    psi = np.zeros((m.n, 2, 2))
    psi[:, 0, 0] = m.X[:, 0]
    S = f.columns(psi)
    assert np.all(np.isfinite(S))
    assert np.isfinite(f.info.regularization_effect)
    assert np.abs(S[:, 1, 0]).max() < 1e-6 * np.abs(S[:, 0, 0]).max()
    # a thick enough plate does not trigger it
    ok = SensitivityFactor(cantilever(1e-3), x, bend_floor=False)
    assert ok.info.fallback == ""


class CylinderBody:
    """Infinite vertical (y) cylinder of radius r about the origin, frictionless."""

    def __init__(self, r):
        self.r = r

    def phi_grad(self, p):
        p = np.asarray(p, dtype=np.float64)
        rho = np.hypot(p[:, 0], p[:, 2])
        g = np.zeros_like(p)
        g[:, 0] = p[:, 0] / rho
        g[:, 2] = p[:, 2] / rho
        return rho - self.r, g


def tube_on_cylinder(r=0.1, height=0.15, fabric=None):
    """A sleeve (sheet seamed into a tube, 5 % shorter round than the cylinder)
    on a frictionless vertical cylinder, no gravity: it can spin about and
    slide along the axis, so K has two exact null modes."""
    from couture.cloth.model import ClothModel, Scene
    from couture.mesh import grid_sheet

    W = 0.95 * 2 * np.pi * r
    mesh = grid_sheet(W, height, 17, 6)
    X = mesh.X
    left = np.nonzero(X[:, 0] < 1e-9)[0]
    right = np.nonzero(X[:, 0] > W - 1e-9)[0]
    right = right[np.argsort(X[right, 1])]
    em, edges, w = [], [], []
    for v in left:
        k = int(np.searchsorted(X[right, 1], X[v, 1] - 1e-12))
        k = min(k, len(right) - 2)
        a, b = right[k], right[k + 1]
        em.append(v)
        edges.append((a, b))
        w.append((X[v, 1] - X[a, 1]) / (X[b, 1] - X[a, 1]))
    mesh.seam_emitters = np.array(em, np.int32)
    mesh.seam_edges = np.array(edges, np.int32)
    mesh.seam_weights = np.clip(np.array(w), 0, 1)
    th = X[:, 0] / W * 2 * np.pi
    R = r + 0.005
    mesh.x0 = np.column_stack([R * np.cos(th), X[:, 1], -R * np.sin(th)])
    return ClothModel(mesh, fabric or SimpleFabric(bend_stiffness=1e-5), Scene(body=CylinderBody(r), gravity=False))


def test_free_spin_on_frictionless_cylinder_is_projected_out():
    """A garment on a frictionless body of revolution can spin about its axis
    (and here slide along it): K is singular. The modes are found, projected
    out, and do not corrupt the response."""
    from couture.solvers.newton import NewtonSolver

    model = tube_on_cylinder()
    res = NewtonSolver().solve(model, model.mesh.x0, tol=1e-10, max_iters=400)
    assert res.converged, res.diagnosis
    x = res.x
    f = SensitivityFactor(model, x, bend_floor=True)
    assert f.info.null_modes == 2
    spin = np.cross([0.0, 1.0, 0.0], x).ravel()
    slide = np.tile([0.0, 1.0, 0.0], model.n)
    modes = np.column_stack([spin / np.linalg.norm(spin), slide / np.linalg.norm(slide)])
    # the detected null space is span{spin, slide}
    assert np.linalg.norm(modes - f.N @ (f.N.T @ modes)) < 1e-6
    # an asymmetric edit (lengthen a quarter of the tube's height, stretch round):
    # its force has spin and slide components, which a plain solve would blow up
    X = model.X
    psi = np.zeros((model.n, 2, 2))
    psi[:, 1, 0] = (X[:, 1] - X[:, 1].min()) * (X[:, 0] < 0.25 * X[:, 0].max())
    psi[:, 0, 1] = X[:, 0]
    S = f.columns(psi)
    assert np.all(np.isfinite(S))
    for j in range(2):
        assert np.abs(modes.T @ S[:, :, j].ravel()).max() < 1e-9 * np.linalg.norm(S[:, :, j])
    # the floor-free response equals FD of re-solves modulo the free modes
    f0 = SensitivityFactor(model, x, bend_floor=False)
    S0 = f0.columns(psi)
    fd = fd_columns(tube_on_cylinder, x, psi, 1e-4, resolve_no_gravity)
    for j in range(2):
        d = fd[:, :, j].ravel()
        d = d - modes @ np.linalg.lstsq(modes, d, rcond=None)[0]
        assert np.linalg.norm(d) > 1e-3
        assert_close(S0[:, :, j].ravel(), d, 1e-3, ord=2, what=f"column {j} modulo the free modes")

"""A press by ∂F/∂X assembled at refactorization time (couture.sensitivity.dfdx)
equals the matrix-free path it replaced, term by term and in the columns;
the same Ψ again returns the kept columns."""

from __future__ import annotations

import numpy as np
import pytest
from fdcheck import assert_close, richardson
from sens_testmodel import strip_over_sphere
from test_sensitivity_factor import stretch_psi, tube_on_cylinder

from couture.sensitivity import Predictor, SensitivityFactor
from couture.sensitivity.dfdx import DForcesDX


def relerr(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.fixture(scope="module")
def strip():
    from couture.solvers.newton import NewtonSolver

    m = strip_over_sphere()
    r = NewtonSolver().solve(m, m.mesh.x0, tol=1e-10, max_iters=800)
    assert r.converged, r.diagnosis
    return m, r.x


def test_assembled_dforces_dX_is_the_models_derivative_term_by_term():
    """Term by term the model's matrix-free derivative (the same analytic
    formulas), and the bending part against an independent reference: a
    Richardson extrapolation of central differences of bending forces of
    models rebuilt at X ± h dX."""
    m = strip_over_sphere(nx=13, ny=5)
    rng = np.random.default_rng(3)
    x = m.mesh.x0 + 0.01 * rng.standard_normal((m.n, 3))  # off equilibrium: every term loaded
    dofs = np.arange(3 * m.n)
    dX = rng.standard_normal((m.n, 2))
    for term in ("membrane", "gravity", "bending"):
        new = DForcesDX(m, x, dofs, [term]).apply(dX)
        model = m.dforces_dX(x, dX, [term]).ravel()
        assert np.abs(model).max() > 0
        assert relerr(new, model) < 1e-13, term

    def bending_at(X):
        rebuilt = strip_over_sphere(nx=13, ny=5)
        rebuilt.set_rest_positions(X)
        return rebuilt.forces(x, ["bending"]).ravel()

    h = 1e-3 * float(np.mean(np.linalg.norm(m.X[m.tris[:, 1]] - m.X[m.tris[:, 0]], axis=1)))
    bend = DForcesDX(m, x, dofs, ["bending"]).apply(dX)
    # measured 1.4e-10; a central difference alone: 2e-8
    assert_close(bend, richardson(bending_at, m.X, dX, h), 1e-9, ord=2, what="bending dF/dX")
    # all terms, several columns at once, on a subset of rows
    free = np.arange(0, 3 * m.n, 2)
    D = DForcesDX(m, x, free)
    psi = rng.standard_normal((m.n, 2, 3))
    got = D.apply(psi)
    want = np.stack([m.dforces_dX(x, psi[:, :, j]).ravel()[free] for j in range(3)], axis=1)
    assert got.shape == (len(free), 3) and relerr(got, want) < 1e-13
    with pytest.raises(ValueError, match="psi must have shape"):
        D.apply(np.zeros((m.n + 1, 2)))


def test_press_columns_equal_the_matrix_free_path(strip):
    m, x = strip
    psi = stretch_psi(m.X)
    new = SensitivityFactor(m, x)
    old = SensitivityFactor(m, x, press_matrix=False)
    assert new.dfdx is not None and old.dfdx is None and new.info.dfdx_s > 0
    S_new, S_old = new.columns(psi), old.columns(psi)
    assert np.abs(S_old).max() > 0
    assert relerr(S_new, S_old) < 1e-10
    # a slider: one live column, and the parameter column
    one = psi.copy()
    one[:, :, 1] = 0.0
    S1 = new.columns(one)
    assert not np.any(S1[:, :, 1]) and relerr(S1[:, :, 0], S_old[:, :, 0]) < 1e-10
    assert relerr(new.param_column(psi[:, :, 0]), old.param_column(psi[:, :, 0])) < 1e-10
    # pinned vertices do not move
    assert not np.any(S_new[~np.asarray(m.free, bool)])


def test_press_with_free_modes_and_floor_equals_the_matrix_free_path():
    """Null modes projected out and the bending floor (regularization measured)
    on a sleeve with seams on a frictionless cylinder."""
    from couture.solvers.newton import NewtonSolver

    model = tube_on_cylinder()
    res = NewtonSolver().solve(model, model.mesh.x0, tol=1e-10, max_iters=400)
    assert res.converged, res.diagnosis
    X = model.X
    psi = np.zeros((model.n, 2, 2))
    psi[:, 1, 0] = (X[:, 1] - X[:, 1].min()) * (X[:, 0] < 0.25 * X[:, 0].max())
    psi[:, 0, 1] = X[:, 0]
    new = SensitivityFactor(model, res.x, bend_floor=True)
    old = SensitivityFactor(model, res.x, bend_floor=True, press_matrix=False)
    assert new.info.null_modes == 2
    assert relerr(new.columns(psi), old.columns(psi)) < 1e-10
    assert new.info.regularization_effect > 0
    assert new.info.regularization_effect == pytest.approx(old.info.regularization_effect, rel=1e-8)


def test_the_same_psi_returns_the_kept_columns(strip):
    m, x = strip
    f = SensitivityFactor(m, x, keep_columns=2)
    psi = stretch_psi(m.X)
    S = f.columns(psi)
    again = f.columns(psi.copy())
    np.testing.assert_array_equal(again, S)
    again[:] = 0.0  # the caller's copy: the kept columns do not change
    np.testing.assert_array_equal(f.columns(psi), S)
    other = 2.0 * psi
    assert relerr(f.columns(other), 2.0 * S) < 1e-12  # linear in Ψ, computed anew
    f.columns(3.0 * psi)
    assert len(f._columns) == 2  # the oldest was dropped
    f.clear_columns()
    assert relerr(f.columns(psi), S) < 1e-15


def test_predictor_press_uses_the_refactored_columns(strip):
    """The node's path: refactor (idle), press, linear prediction = x_eq + S d."""
    m, x = strip
    p = Predictor(method="linear", error_estimate=False, friction=False)
    p.set_equilibrium(m, x)
    info = p.refactor()
    assert info.dfdx_s > 0
    psi = stretch_psi(m.X)
    S = p.press(psi)
    S_old = SensitivityFactor(m, x, press_matrix=False).columns(psi)
    assert relerr(S, S_old) < 1e-10
    d = np.array([0.01, -0.02])
    pred = p.drag(d)
    assert pred.method == "linear"
    # the cache keeps float32 drapes and columns (relative precision ~1e-7)
    assert np.abs(pred.x - (x + S @ d)).max() < 1e-6 * (np.abs(x).max() + np.abs(S @ d).max())
    assert np.abs(pred.x - x).max() > 1e-3 * np.abs(S @ d).max()

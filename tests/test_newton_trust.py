"""The trust-region step of Newton's true-Hessian phase (``indefinite='trust'``):
Steihaug-Toint truncated CG against closed forms on small dense problems, and
the solver converging with it on a scene with free-hanging folds (an
indefinite true Hessian)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from solver_testmodel import fabric

from couture.cloth import ClothModel, Scene
from couture.mesh import grid_sheet
from couture.solvers import get_solver
from couture.solvers.linalg import factorize
from couture.solvers.newton import steihaug


def _problem(eigs, seed=0):
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(len(eigs), len(eigs))))
    A = sp.csr_matrix(Q @ np.diag(eigs) @ Q.T)
    g = rng.normal(size=len(eigs))
    return A, g


def _model(A, g, p):
    return float(-g @ p + 0.5 * p @ (A @ p))


def test_inside_the_region_it_is_the_newton_step():
    A, g = _problem([1.0, 2.0, 5.0, 10.0, 40.0])
    B = sp.identity(5, format="csr")
    p, hit, _ = steihaug(A, B, g, factorize(B, "splu"), np.inf, 1e-12, 50)
    assert hit == ""
    np.testing.assert_allclose(p, np.linalg.solve(A.toarray(), g), rtol=1e-9)


def test_a_short_region_stops_on_its_boundary_with_lower_model_energy():
    A, g = _problem([1.0, 2.0, 5.0, 10.0, 40.0], seed=1)
    B = sp.csr_matrix(np.diag([1.0, 2.0, 3.0, 4.0, 5.0]))  # a preconditioner that is not A
    newton = np.linalg.solve(A.toarray(), g)
    delta = 0.3 * np.sqrt(newton @ (B @ newton))
    p, hit, _ = steihaug(A, B, g, factorize(B, "splu"), delta, 1e-12, 50)
    assert hit == "boundary"
    assert np.sqrt(p @ (B @ p)) == pytest.approx(delta, rel=1e-9)
    # better than the Cauchy point (the model's minimum along the preconditioned gradient)
    z = np.linalg.solve(B.toarray(), g)
    t = min((g @ z) / (z @ (A @ z)), delta / np.sqrt(z @ (B @ z)))
    assert _model(A, g, p) <= _model(A, g, t * z) + 1e-12


def test_negative_curvature_is_followed_to_the_boundary():
    A, g = _problem([-3.0, 1.0, 2.0, 5.0, 10.0], seed=2)
    B = sp.csr_matrix(np.abs(A.toarray()) + 10 * np.eye(5))  # SPD, as the projected Hessian is
    delta = 0.5
    p, hit, _ = steihaug(A, B, g, factorize(B, "splu"), delta, 1e-12, 50)
    assert hit in ("negative", "boundary")
    assert np.sqrt(p @ (B @ p)) == pytest.approx(delta, rel=1e-9)
    assert _model(A, g, p) < 0.0


def test_newton_with_the_trust_region_settles_free_hanging_folds():
    m = grid_sheet(0.5, 0.5, 12, 12)
    X = m.X
    m.x0 = np.column_stack([X[:, 0], np.zeros(len(X)), X[:, 1]])
    corners = [int(np.argmin(np.linalg.norm(X - np.array(q), axis=1))) for q in ((0.0, 0.0), (0.5, 0.0))]
    m.pinned = np.array(corners, np.int32)
    m.x0[corners[1], 0] = 0.3
    model = ClothModel(m, fabric(stretch=500.0, bend=1e-6), Scene())
    res = get_solver("newton", indefinite="trust").solve(model, m.x0, tol=1e-8, max_seconds=60)
    print(f"trust: {res.iterations} iterations, {res.stats.get('trust_steps')} trust steps")
    assert res.converged, res.diagnosis
    assert res.stats.get("trust_steps", 0) > 0
    reference = get_solver("newton").solve(model, m.x0, tol=1e-8, max_seconds=60)
    # the same equilibrium as the mass-shift Newton (free folds of a sheet held at two corners)
    assert np.abs(res.x - reference.x).max() < 1e-3

"""The slip-aware distance estimate (couture.sensitivity.distance)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from bench import preview_error
from couture.sensitivity.distance import _line_min, _pcg


def test_line_min_finds_the_minimum_of_a_quadratic_valley():
    # E(t) along dx: a stiff wall past a flat valley, as along a soft-mode chord step;
    # a backtracking search would accept anything that lowers E, the minimum is at t*
    a = np.array([1.0, 1e-3])
    c = np.array([0.0, 2e-4])  # minimum of E(y) = sum a (y - c)^2 / 2 at y = c

    def ef(y):
        return float(0.5 * np.sum(a * (y - c) ** 2)), -(a * (y - c))

    x = np.zeros(2)
    dx = np.array([0.0, 1.0])  # a chord step 5000x too long
    e0, f0 = ef(x)
    t = _line_min(lambda y: ef(y)[0], ef, x, dx, e0, float(f0 @ dx))
    assert t == pytest.approx(2e-4, rel=0.05)

    # not a parabola: a quartic wall; the search still ends near the minimum
    def ef4(y):
        return float(np.sum((y - c) ** 4)), -4.0 * (y - c) ** 3

    e0, f0 = ef4(x)
    t = _line_min(lambda y: ef4(y)[0], ef4, x, dx, e0, float(f0 @ dx))
    assert t == pytest.approx(2e-4, rel=0.1)


def test_pcg_solves_the_system_less_the_released_springs():
    rng = np.random.default_rng(1)
    n = 30
    B = rng.standard_normal((n, n))
    A = sp.csr_matrix(B @ B.T + n * np.eye(n))
    D = sp.csr_matrix(np.diag(np.r_[0.5 * n * np.ones(4), np.zeros(n - 4)]))  # A - D stays SPD
    b = rng.standard_normal(n)

    class Red:  # the factor's coordinates without null modes: A itself
        def __init__(self):
            self.A = A
            self._inv = np.linalg.inv(A.toarray())

        def precondition(self, r):
            return self._inv @ r

    z, its = _pcg(Red(), D, b, iters=50, rtol=1e-10)
    ref = np.linalg.solve((A - D).toarray(), b)
    assert np.allclose(z, ref, rtol=1e-6, atol=1e-9)
    assert its <= 10  # identity plus a rank-4 update: a handful of iterations


@pytest.fixture(scope="module")
def waist_rows():
    # the default skirt, coarse: the waist's ease changed by 5 mm both ways makes
    # friction anchors slip in the true re-solve (Newton as the solver node runs it)
    return preview_error.run("skirt", 250, ["waist_ease"], [0.005], 1e-8)


def test_slip_aware_estimate_is_within_2x_where_the_held_one_is_not(waist_rows):
    assert len(waist_rows) == 2
    for r in waist_rows:
        assert r["truth_converged"] and r["truth_slipped"] > 0 and r["estimate_slipped"] > 0
        true = r["true_error_mm"]
        # with the anchors held the chord step sees a fraction of the motion
        assert r["chord_estimate_mm"] < 0.5 * true
        assert 0.5 <= r["estimate_mm"] / true <= 2.0
        assert r["estimate_cg_iterations"] <= 50 * r["estimate_rounds"]


def test_estimate_leaves_the_friction_state_and_keeps_the_chord_without_slips():
    from couture.pattern.edit import edit_jacobian
    from couture.remesh import build_coordinates
    from couture.remesh import psi as remesh_psi
    from couture.sensitivity import Predictor
    from couture.sensitivity.predictor import default_model_at

    design, res, model, x = preview_error.drape("skirt", 150, 1e-8)
    psi = remesh_psi(build_coordinates(res, "pmvc"), edit_jacobian(design, "param:waist_ease"))
    p = Predictor(method="linear")
    p.set_equilibrium(default_model_at(model, model.X.copy()), x)
    p.refactor()
    p.press(psi)
    d = np.array([0.005, 0.0])
    xp = p.drag(d, error_estimate=False).x
    m = p.model_for(d)
    before = m.friction_state()
    dist = p.distance_of(xp, d)
    est = p.last_distance
    assert est.rounds > 0 and est.slipped > 0
    assert dist == pytest.approx(float(np.max(np.linalg.norm(est.x - xp, axis=1))))
    for a, b in zip(before, m.friction_state(), strict=True):
        assert np.array_equal(a, b)
    p.slip_rounds = 0  # the held-friction chord step alone
    assert p.distance_of(xp, d) == pytest.approx(est.chord)
    # no edit: the prediction is the equilibrium, nothing moves, nothing slips
    assert p.distance_of(p.drag(np.zeros(2), error_estimate=False).x, np.zeros(2)) < 1e-6

"""The finite-difference helper itself (tests/fdcheck.py): it passes a right
derivative and fails a wrong one (sign, scale, one entry), a trivially zero
one, and a shape mismatch; its degenerate configurations are what they say."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from fdcheck import (
    along_axes,
    assert_close,
    central,
    check_gradient,
    check_hessian,
    check_jacobian,
    contact_penetrations,
    degenerate_triangles,
    rel_error,
    richardson,
)


def energy(x):
    return float(np.sum(np.sin(x) * x**2))


def gradient(x):
    return np.cos(x) * x**2 + 2 * x * np.sin(x)


def hessian(x):
    return sp.diags((-np.sin(x) * x**2 + 4 * x * np.cos(x) + 2 * np.sin(x)).ravel())


X = np.random.default_rng(0).normal(size=(7, 3))


def test_a_right_derivative_passes():
    assert check_gradient(energy, gradient(X), X, h=1e-6, rtol=1e-8) < 1e-8
    assert check_hessian(gradient, hessian(X), X, h=1e-6, rtol=1e-8) < 1e-8
    assert check_jacobian(gradient, lambda d: (hessian(X) @ d.ravel()).reshape(d.shape), X, h=1e-6, rtol=1e-8) < 1e-8


@pytest.mark.parametrize("wrong", ["sign", "scale", "one entry"])
def test_a_wrong_derivative_fails(wrong):
    g = gradient(X)
    H = hessian(X).toarray()
    if wrong == "sign":
        g, H = -g, -H
    elif wrong == "scale":
        g, H = 1.01 * g, 1.01 * H
    else:
        g = g.copy()
        g[3, 1] += 1e-3 * np.abs(g).max()
        H[5, 5] *= 1.001
    with pytest.raises(AssertionError, match="relative error"):
        check_gradient(energy, g, X, h=1e-6, rtol=1e-6, dirs=np.eye(X.size).reshape(-1, *X.shape))
    with pytest.raises(AssertionError, match="relative error"):
        check_hessian(gradient, H, X, h=1e-6, rtol=1e-6, dirs=np.eye(X.size).reshape(-1, *X.shape))


def test_trivial_and_misshapen_derivatives_fail():
    with pytest.raises(AssertionError, match="zero"):
        check_gradient(energy, np.zeros_like(X), X, h=1e-6, rtol=1e-6)
    with pytest.raises(AssertionError, match="trivially zero"):
        check_jacobian(lambda x: 0 * x, lambda d: 0 * d, X, h=1e-6, rtol=1e-6)
    with pytest.raises(AssertionError, match="trivially zero"):
        assert_close(np.array([1e-9]), np.array([1e-9]), 1e-6, nontrivial=1e-6)
    with pytest.raises(AssertionError, match="shape"):
        assert_close(np.zeros(3), np.zeros(4), 1e-6)
    with pytest.raises(AssertionError, match="not finite"):
        assert_close(np.array([np.nan]), np.array([1.0]), 1e-6)


def test_relative_error_has_a_floor_and_a_norm():
    assert rel_error(np.array([1e-9]), np.array([2e-9])) == pytest.approx(0.5)
    assert rel_error(np.array([1e-9]), np.array([2e-9]), floor=1.0) == pytest.approx(1e-9)
    a, b = np.array([3.0, 4.0]), np.array([3.0, 4.1])
    assert rel_error(a, b, ord=2) == pytest.approx(0.1 / np.linalg.norm(b))


def test_differences_and_their_orders():
    d = np.ones_like(X)
    exact = np.vdot(gradient(X), d)
    e2 = [abs(central(energy, X, d, h) - exact) for h in (1e-2, 5e-3)]
    e4 = [abs(richardson(energy, X, d, h) - exact) for h in (1e-2, 5e-3)]
    assert 3.5 < e2[0] / e2[1] < 4.5  # O(h²)
    assert 12 < e4[0] / e4[1] < 20  # O(h⁴)
    # along_axes: a row-wise f, every row at once, derivative along each axis last
    J = along_axes(lambda p: np.stack([p[:, 0] * p[:, 1], np.sin(p[:, 2])], axis=1), X, 1e-6)
    assert J.shape == (7, 2, 3)
    np.testing.assert_allclose(J[:, 0, :2], X[:, [1, 0]], atol=1e-9)
    np.testing.assert_allclose(J[:, 1, 2], np.cos(X[:, 2]), atol=1e-9)


def _area(P):
    return 0.5 * ((P[1, 0] - P[0, 0]) * (P[2, 1] - P[0, 1]) - (P[2, 0] - P[0, 0]) * (P[1, 1] - P[0, 1]))


def test_degenerate_configurations_are_what_they_say():
    cases = degenerate_triangles(0.02)
    for name, (Xr, x) in cases.items():
        assert Xr.shape == (3, 2) and x.shape == (3, 3) and _area(Xr) > 0, name  # counter-clockwise at rest
    ref = _area(cases["regular"][0])
    assert _area(cases["sliver rest"][0]) < 2e-3 * ref and _area(cases["needle rest"][0]) < 2e-3 * ref
    deformed = {n: _area(x[:, [0, 2]]) for n, (_, x) in cases.items()}
    assert abs(deformed["near-zero area state"]) < 1e-5 * ref
    assert deformed["inverted state"] < 0
    pens = contact_penetrations(1e-3, 1e-7)
    assert (pens < 0).any() and ((pens > 0) & (pens < 1e-3)).any() and (pens > 1e-3).any()
    assert np.abs(pens).min() >= 20 * 1e-7 and np.abs(pens - 1e-3).min() >= 20 * 1e-7

"""The predictor as the node drives it, on SC's Fig. 5 scene: a strip pinned at
one end, partly draped on a frictionless sphere, lengthened by 30 % of its
material length while cached samples are taken at 10 % and 20 %."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from sens_testmodel import strip_over_sphere

from couture.sensitivity import Predictor
from couture.solvers import get_solver

LENGTH = 0.8
DYN_STEPS = 10
"""kinetic-damping steps the dynamics baseline gets: about the predictor's on-line time"""
DYN_ALIVE = 200
"""steps after which the same baseline has converged (it is a working solver)"""


def solve(model, x_start):
    r = get_solver("newton").solve(model, x_start, tol=1e-9, max_iters=800)
    assert r.converged, r.diagnosis
    return r.x


@pytest.fixture(scope="module")
def fig5():
    model = strip_over_sphere(length=LENGTH)
    x0 = solve(model, model.mesh.x0)
    # pointer motion d1 [m] drags the free end along the strip; interior follows linearly
    psi = np.zeros((model.n, 2, 2))
    psi[:, 0, 0] = model.X[:, 0] / LENGTH
    psi[:, 1, 1] = model.X[:, 1] / LENGTH
    X0 = model.X.copy()
    cache = {}

    def truth(d, x_start):
        key = tuple(d)
        if key not in cache:
            m = strip_over_sphere(length=LENGTH)
            m.set_rest_positions(X0 + psi @ np.asarray(d, float))
            cache[key] = solve(m, x_start)
        return cache[key]

    return model, x0, psi, truth


def rms(a, b):
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def test_fig5_error_order_dynamics_linear_gmls(fig5):
    model, x0, psi, truth = fig5
    p = Predictor()
    p.set_equilibrium(model, x0)
    info = p.refactor()
    assert info.regularization == "none"  # the exact linearisation: no floor unless it must
    S = p.press(psi)
    assert S.shape == (model.n, 3, 2) and np.abs(S).max() > 0.1
    dT = np.array([0.3 * LENGTH, 0.0])
    xT = truth(dT, x0)

    lin = p.drag(dT, method="linear")
    assert lin.method == "linear"
    # progressive samples at 10 % and 20 %: solver equilibria warm-started from the prediction
    for frac in (0.1, 0.2):
        d = np.array([frac * LENGTH, 0.0])
        p.add_sample(d, truth(d, p.drag(d).x))
    gm = p.drag(dT)
    assert gm.method == "gmls" and gm.samples == 3

    # dynamics only: kinetic-damping steps from the old state. Given the
    # predictor's on-line time (press + prediction, a few tens of ms) it had
    # often taken no step and returned x0, so "worse than linear" could not
    # fail. Here it gets a fixed number of steps instead (no timing): DYN_STEPS
    # is about the predictor's on-line time (measured: press 23 ms + predict
    # 4 ms; a kinetic step 2-5 ms on this 148-vertex strip), and the baseline
    # is shown alive: given DYN_ALIVE steps it reaches the truth far below
    # the GMLS error (measured with contact stiffness 1000 mu: at 30 steps already
    # 5e-3 m rms, below linear's 2.6e-2; at 100 steps 3e-11 m).
    mT = p.model_for(dT)
    e_still = rms(x0, xT)
    dyn = get_solver("kinetic").solve(mT, x0, tol=1e-12, max_iters=DYN_STEPS)
    alive = get_solver("kinetic").solve(mT, x0, tol=1e-12, max_iters=DYN_ALIVE)

    e_dyn, e_lin, e_gmls = rms(dyn.x, xT), rms(lin.x, xT), rms(gm.x, xT)
    # with the exact linearisation (no floor) the linear prediction is already
    # good at 30 % (rms 11.6 mm; 25.6 mm with SC's always-on floor) and the two
    # GMLS samples keep it there (11.8 mm): measured, not a ranking to keep
    assert e_dyn > 5 * max(e_lin, e_gmls), (e_dyn, e_lin, e_gmls)
    assert e_gmls < 1.2 * e_lin
    # the force residuals at the edited rest shape are not distances to the truth
    # (both predictions push vertices into the sphere's contact layer: relative
    # residuals in the thousands for cm-level errors)
    # alive: given DYN_ALIVE steps the dynamics reach an equilibrium of the edited
    # strip, within 1 % of the edit's motion from Newton's (the strip over the
    # frictionless sphere has more than one: with contact stiffness 100 mu kinetic
    # settles 1.45 mm rms from Newton's, both at residual 1e-12)
    assert alive.converged and alive.residual <= 1e-10, alive.diagnosis
    assert rms(alive.x, xT) < 0.02 * e_still, (rms(alive.x, xT), e_gmls, e_still)
    assert np.isfinite(gm.error_estimate) and gm.residual_s > 0

    # the distance estimate (one chord-Newton correction) is computed; on this
    # frictionless sphere it overshoots (a soft mode: see bench preview_error)
    assert np.isfinite(lin.error_m) and lin.error_m > 0

    # release: the warm start is the prediction; the solver converges from it
    xw = p.release(dT)
    assert np.allclose(xw, gm.x)


def test_gmls_reproduces_cached_equilibria_closely(fig5):
    model, x0, psi, truth = fig5
    p = Predictor()
    p.set_equilibrium(model, x0)
    p.press(psi)
    d = np.array([0.1 * LENGTH, 0.0])
    xm = truth(d, p.drag(d).x)
    p.add_sample(d, xm)
    # at the sample itself GMLS is a weighted fit (ε² = 1e-3), close to the sample
    assert rms(p.drag(d).x, xm) < 0.2 * rms(p.drag(d, method="linear").x, xm)


def test_refactor_and_samples_in_a_worker_thread_while_dragging(fig5):
    model, x0, psi, truth = fig5
    p = Predictor(error_estimate=False)
    p.set_equilibrium(model, x0)
    assert p.drag((0.01, 0.0)).method == "none"  # before press: the equilibrium itself
    worker = threading.Thread(target=p.refactor)
    worker.start()
    worker.join()
    assert not p.stale
    p.press(psi)
    d = np.array([0.08, 0.0])
    xm = truth(d, p.drag(d).x)
    out = []
    worker = threading.Thread(target=lambda: out.append(p.add_sample(d, xm)))
    worker.start()
    preds = [p.drag((0.001 * k, 0.0)) for k in range(50)]  # pointer keeps moving meanwhile
    worker.join()
    assert all(np.all(np.isfinite(q.x)) for q in preds)
    assert out[0] is not None and len(p.cache) == 2
    # a new equilibrium makes the factorization stale
    p.set_equilibrium(model, xm)
    assert p.stale

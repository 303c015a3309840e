"""A damped-dynamics phase that cannot finish never undoes Newton's progress.

Newton hands a crawl (the residual not improved by 1 % in ``stall_window``
iterations) over to damped dynamics from the best-residual state. Down a long
valley the energy falls at every Newton step while the residual hovers (the
frictionless edited skirt at 10.6k vertices turns 0.17 rad about the body that
way), so the best-residual state lies far behind; when the dynamics do not reach
their target within their share of the time, Newton goes on from the state its
own path had reached, never from the one the dynamics ended in.
"""

from __future__ import annotations

import logging

import numpy as np
from solver_testmodel import fabric

from couture.cloth import ClothModel, Scene
from couture.cloth.body import SphereBody
from couture.mesh import grid_sheet
from couture.solvers.newton import NewtonSolver


def sheet_on_sphere(nx: int = 8) -> ClothModel:
    """A 0.6 m sheet 2 cm above a 0.25 m sphere, held at its centre, frictionless:
    it settles over the sphere through folds that form and roll (a long valley)."""
    size, radius = 0.6, 0.25
    m = grid_sheet(size, size, nx, nx)
    X = m.X
    m.x0 = np.column_stack([X[:, 0] - size / 2, np.full(len(X), radius + 0.02), X[:, 1] - size / 2])
    m.pinned = np.array([int(np.argmin(np.linalg.norm(X - size / 2, axis=1)))], np.int32)
    return ClothModel(m, fabric(stretch=500.0, bend=1e-6), Scene(body=SphereBody(center=np.zeros(3), radius=radius)))


class _Handovers(logging.Handler):
    def __init__(self):
        super().__init__(logging.DEBUG)
        self.at: list[int] = []

    def emit(self, record):
        msg = record.getMessage()
        if "dynamics from" in msg:
            self.at.append(int(msg.split()[2].rstrip(":")))


def test_an_unfinished_dynamics_phase_resumes_newton_where_it_was():
    model = sheet_on_sphere()
    # a crawl after 5 iterations without residual progress; the dynamics get no time
    solver = NewtonSolver(stall_window=5, dynamics_share=1e-12)
    seen: list[tuple[int, float]] = []
    handovers = _Handovers()
    log = logging.getLogger("couture.solvers.newton")
    old = log.level
    log.addHandler(handovers)
    log.setLevel(logging.DEBUG)
    resumed: list[float] = []

    def cb(it, x, r):
        if handovers.at and not resumed:
            # the first call after the handover: the state Newton goes on from
            resumed.append(model.energy(x))
            return True
        seen.append((it, model.energy(x)))
        return False

    try:
        res = solver.solve(model, model.mesh.x0, tol=1e-12, max_iters=400, max_seconds=60, callback=cb)
    finally:
        log.removeHandler(handovers)
        log.setLevel(old)
    assert handovers.at, f"no crawl was handed over to dynamics: {res.diagnosis}"
    assert res.stats.get("dynamics_abandoned", 0) >= 1
    it_h = handovers.at[0]
    # Newton's own state at the top of the handover iteration (the first call there;
    # the dynamics' calls come after it)
    e_path = next(e for it, e in seen if it == it_h)
    # Newton went on from its own path's state, not from the best-residual one behind it
    assert resumed and resumed[0] <= e_path + 1e-12 * abs(e_path), (resumed, e_path)

"""One signature for every equilibrium solver (scikit-fem's ``solve(A, b, solver=...)`` habit).

A solver takes a :class:`couture.cloth.ClothModel` (mesh + fabric + scene
terms) and a start state, and returns a :class:`SolveResult`. Solvers never
return NaN and never hang: iteration and time caps stop them with a
``diagnosis`` that says why.

Relative force residual, used everywhere (messages, benchmarks, tests):
``||R_free||_2 / ||F_gravity||_2`` where R = F - Q is the force residual on
free (unpinned) degrees of freedom and F_gravity the total gravity force vector
(all vertices); for a scene without gravity the denominator is the norm of
the forces in balance, sqrt(sum over terms of ||f_term||²), at least mu·sqrt(A),
the membrane force of a unit strain (see ``ClothModel.residual_denominator``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np


@dataclass
class SolveResult:
    x: np.ndarray
    """equilibrium (or last finite) positions [m], shape (n, 3), float64"""
    residual: float
    """relative force residual at x (dimensionless)"""
    iterations: int
    """outer iterations (time steps for dynamic solvers, Newton steps for Newton)"""
    wall_time: float
    """[s]"""
    converged: bool
    method: str
    """solver name, e.g. 'kinetic', 'newton', 'verlet'"""
    diagnosis: str = ""
    """empty when converged; otherwise why it stopped (cap reached, stalled, diverged, ...)"""
    history: list[tuple[float, float]] = field(default_factory=list)
    """(wall time [s], relative residual) samples, for convergence plots"""
    stats: dict = field(default_factory=dict)
    """method-specific timings: assembly_s, linear_solve_s, steps, cg_iterations, ..."""


ProgressCallback = Callable[[int, np.ndarray, float], bool | None]
"""called as cb(iteration, x, relative_residual); returning True stops the solve early"""


class Solver(Protocol):
    name: str

    def solve(
        self,
        model,
        x0: np.ndarray,
        *,
        tol: float = 1e-4,
        max_iters: int = 10_000,
        max_seconds: float = 60.0,
        callback: ProgressCallback | None = None,
        friction_after: float | None = None,
        from_placement: bool = False,
    ) -> SolveResult:
        """``friction_after``: for this solve, the relative residual below which friction
        anchors act (math.inf: from the first iteration; None: the solver's own setting;
        a solver without a friction schedule ignores it). ``from_placement``: x0 is
        a placement (pieces around the body, seams open by centimetres): a solver
        whose steps can be long keeps them from carrying cloth through the body
        (Newton's surface guard); others ignore it."""
        ...

"""Swappable equilibrium solvers: one signature, see :mod:`couture.solvers.base`.

    from couture.solvers import get_solver
    result = get_solver("kinetic").solve(model, x0, tol=1e-4)

- ``kinetic``: kinetic damping on Baraff-Witkin semi-implicit steps (SC §7) with an adaptive
  time step, CG preconditioned by a reused sparse factorization (or IC(0)).
- ``newton``: Newton + Armijo line search, sparse direct factorization (accuracy reference).
- ``verlet``: Meng 2010 style mass-spring with Stoermer-Verlet (speed end; its own spring model).
- ``style3d``: the peer, NVIDIA newton's SolverStyle3D (optional extra ``couture[peer]``; its own model).

Cascadic coarse-to-fine refinement: :func:`couture.solvers.cascadic.solve_cascadic`.
"""

from __future__ import annotations

from typing import Callable

from .base import ProgressCallback, Solver, SolveResult
from .kinetic import KineticSolver
from .newton import NewtonSolver
from .peer import Style3DSolver
from .verlet import VerletSolver

SOLVERS: dict[str, Callable[..., Solver]] = {
    "kinetic": KineticSolver,
    "newton": NewtonSolver,
    "verlet": VerletSolver,
    "style3d": Style3DSolver,
}


def get_solver(name: str, **options) -> Solver:
    """A new solver by registry name; ``options`` go to its constructor."""
    try:
        factory = SOLVERS[name]
    except KeyError:
        raise ValueError(f"unknown solver {name!r}; choose from {sorted(SOLVERS)}") from None
    return factory(**options)


__all__ = [
    "SOLVERS",
    "get_solver",
    "SolveResult",
    "Solver",
    "ProgressCallback",
    "KineticSolver",
    "NewtonSolver",
    "VerletSolver",
    "Style3DSolver",
]

"""Swappable equilibrium solvers: one signature, see :mod:`couture.solvers.base`.

    from couture.solvers import get_solver
    result = get_solver("kinetic").solve(model, x0, tol=1e-4)

- ``kinetic``: kinetic damping on Baraff-Witkin semi-implicit steps (SC §7) with an adaptive
  time step, CG preconditioned by a reused sparse factorization (or IC(0)).
- ``newton``: Newton + Armijo line search, sparse direct factorization (accuracy reference).
- ``verlet``: explicit Stoermer-Verlet dynamic relaxation of the same ClothModel (FIRE damping,
  fictitious masses): no linear solves; slow to converge on stiff garments.
- ``style3d``: the peer, NVIDIA newton's SolverStyle3D (optional extra ``couture[peer]``; its own model).

``SOLVERS`` is the only list of solver names: the CLI's choices, the solver
node's configuration and the benchmarks read it. It names where each solver
lives, so reading it imports no solver (numba, scipy: about a second); a
solver's module is imported when ``get_solver`` builds one.

Cascadic coarse-to-fine refinement: :func:`couture.solvers.cascadic.solve_cascadic`.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .base import ProgressCallback, Solver, SolveResult

if TYPE_CHECKING:
    from .kinetic import KineticSolver
    from .newton import NewtonSolver
    from .peer import Style3DSolver
    from .verlet import VerletSolver

SOLVERS: dict[str, str] = {
    "kinetic": "kinetic:KineticSolver",
    "newton": "newton:NewtonSolver",
    "verlet": "verlet:VerletSolver",
    "style3d": "peer:Style3DSolver",
}
"""solver name -> ``module:Class`` inside this package (a new solver: its module and one row here)"""


def solver_class(name: str) -> type:
    """The class of registry name ``name`` (imports its module)."""
    try:
        where = SOLVERS[name]
    except KeyError:
        raise ValueError(f"unknown solver {name!r}; choose from {sorted(SOLVERS)}") from None
    module, cls = where.split(":")
    return getattr(importlib.import_module(f"{__name__}.{module}"), cls)


def get_solver(name: str, **options) -> Solver:
    """A new solver by registry name; ``options`` go to its constructor."""
    return solver_class(name)(**options)


_CLASSES = {where.split(":")[1]: name for name, where in SOLVERS.items()}


def __getattr__(attr: str) -> Any:
    """``KineticSolver`` and the other solver classes, imported on first use."""
    if attr in _CLASSES:
        return solver_class(_CLASSES[attr])
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")


__all__ = [
    "SOLVERS",
    "get_solver",
    "solver_class",
    "SolveResult",
    "Solver",
    "ProgressCallback",
    "KineticSolver",
    "NewtonSolver",
    "VerletSolver",
    "Style3DSolver",
]

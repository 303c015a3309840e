"""Gradient steps after the fixed point: Gauss-Newton on the distance to the
target with the design sensitivity of couture's own cloth model (SC §4).

The fixed point is gradient-free and simulator independent (Bartle §4); it
stalls where the drape's shape is not set by stretch alone (slack cloth
bridging a hollow, a fold). There the sensitivity ``J = ∂x/∂X = K⁻¹ ∂F/∂X``
at the latest drape (one factorization, 2n back-substitutions) gives the
Gauss-Newton step on ``|x(X) - x_target|²``:

    (JᵀJ + λI) dX = -Jᵀ (x - x_target),   λ = ``damping`` · tr(JᵀJ) / 2n

and each step is re-simulated through the same ``simulate`` as the fixed
point (a solver node), tried at full, half and quarter length, and kept only
if it lowers the Hausdorff distance. The derivative is this project's model's
(the solver node that re-simulates may be another): a step that does not help
is refused, never taken on faith.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from couture.mesh import GarmentMesh

from .fixed_point import MANNEQUIN_HEIGHT, Simulate, with_rest
from .geometry import frames3, hausdorff, stretch
from .seams import equalize_seams


@dataclass
class GradientStep:
    step: int
    accepted: bool
    length: float
    """fraction of the Gauss-Newton step taken (0: none helped)"""
    hausdorff_pct: float
    stretch_mean: float
    mean_distance_m: float
    solver: str
    seconds: float
    """[s] sensitivity and solves of this step"""


def jacobian(mesh: GarmentMesh, design, X: np.ndarray, x: np.ndarray) -> np.ndarray:
    """∂x/∂X at the drape x of rest shape X, shape (3n, 2n), from couture's cloth model."""
    from couture.cloth.model import ClothModel
    from couture.sensitivity.factor import SensitivityFactor
    from couture.solvers.service import scene_from_design

    n = mesh.n_vertices
    model = ClothModel(with_rest(mesh, X), design.fabric, scene_from_design(design))
    fac = SensitivityFactor(model, x)
    e = np.zeros((n, 2))
    rhs = np.empty((n, 3, 2 * n))
    for i in range(n):
        for c in range(2):
            e[i, c] = 1.0
            rhs[:, :, 2 * i + c] = model.dforces_dX(x, e)
            e[i, c] = 0.0
    return fac.solve(rhs).reshape(3 * n, 2 * n)


def gradient_polish(
    mesh: GarmentMesh,
    design,
    X: np.ndarray,
    x: np.ndarray,
    x_target: np.ndarray,
    simulate: Simulate,
    *,
    steps: int = 2,
    damping: float = 1e-2,
    lengths: tuple[float, ...] = (1.0, 0.5, 0.25),
    equalize: bool = True,
    height: float = MANNEQUIN_HEIGHT,
    log: Callable[[str], None] | None = print,
) -> tuple[np.ndarray, np.ndarray, list[GradientStep]]:
    """Up to ``steps`` Gauss-Newton steps from pattern X with drape x; returns
    (pattern, drape, the steps). Stops at the first step none of whose
    ``lengths`` lowers the Hausdorff distance."""
    say = log or (lambda s: None)
    n = mesh.n_vertices
    t_g = frames3(x_target, mesh.tris)
    best_h = hausdorff(x_target, x, mesh.tris)["hausdorff"]
    out: list[GradientStep] = []
    for k in range(1, steps + 1):
        t0 = time.perf_counter()
        J = jacobian(mesh, design, X, x)
        r = (x - x_target).ravel()
        JTJ = J.T @ J
        lam = damping * float(np.trace(JTJ)) / (2 * n)
        dX = -np.linalg.solve(JTJ + lam * np.eye(2 * n), J.T @ r).reshape(n, 2)
        taken = None
        for a in lengths:
            Xa = X + a * dX
            if equalize:
                Xa = equalize_seams(mesh, Xa)
            sim = simulate(Xa, x_target)
            H = hausdorff(x_target, sim.x, mesh.tris)
            if H["hausdorff"] < best_h:
                taken = (a, Xa, sim, H)
                break
        dt = time.perf_counter() - t0
        if taken is None:
            out.append(GradientStep(k, False, 0.0, 100 * best_h / height, float("nan"), float("nan"), "", dt))
            say(f"[adjust] gradient step {k}: no length of the step lowered the Hausdorff distance; stopped")
            break
        a, X, sim, H = taken
        x = sim.x
        best_h = H["hausdorff"]
        S = float(stretch(t_g, frames3(x, mesh.tris)).mean())
        out.append(GradientStep(k, True, a, 100 * best_h / height, S, H["mean"], sim.solver, dt))
        say(
            f"[adjust] gradient step {k} (length {a:g}): Hausdorff {1e3 * best_h:.1f} mm = "
            f"{100 * best_h / height:.2f} % of height, mean distance {1e3 * H['mean']:.1f} mm, stretch {S:.4f}; "
            f"{sim.solver}, {dt:.1f} s"
        )
    return X, x, out

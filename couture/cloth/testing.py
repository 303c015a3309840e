"""Test helpers for the cloth model: small random meshes and a tiny Newton
solver (an accuracy check for the model, not one of the project's solvers;
those live in couture.solvers)."""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from couture.mesh import GarmentMesh, grid_sheet


def random_drape(mesh: GarmentMesh, seed: int = 0, noise: float = 0.2, squeeze: float = 0.7) -> np.ndarray:
    """A random 3D placement of ``mesh``: the flat pattern stretched by up
    to +20 %, its left half squeezed by ``squeeze`` (so some triangles are in
    compression), plus noise of ``noise`` times the mean edge length."""
    rng = np.random.default_rng(seed)
    X = mesh.X
    e = X[mesh.tris[:, 1]] - X[mesh.tris[:, 0]]
    h = float(np.mean(np.linalg.norm(e, axis=1)))
    x = np.column_stack([X, np.zeros(len(X))])
    mid = 0.5 * (X[:, 0].min() + X[:, 0].max())
    left = X[:, 0] < mid
    x[left, 0] = mid + squeeze * (X[left, 0] - mid)
    x[~left, :2] *= 1.1
    return x + rng.normal(scale=noise * h, size=x.shape)


def small_quality_mesh(seed: int = 0) -> GarmentMesh:
    """About 60 vertices, triangle-library quality mesh with jitter."""
    return grid_sheet(0.1, 0.08, 8, 7, jitter=0.001, seed=seed)


def newton(model, x0: np.ndarray, tol: float = 1e-10, max_iters: int = 100, use_exact: bool = True):
    """Newton's method with backtracking (Armijo) line search on the energy,
    pinned dofs held. Tries the unprojected Hessian first (quadratic
    convergence near a stable equilibrium) and falls back to the PSD one
    when that direction is not a descent direction. Returns (x, history of
    relative residuals)."""
    x = np.array(x0, dtype=np.float64)
    free = model.free_dofs
    hist = [model.relative_residual(x)]
    for _ in range(max_iters):
        if hist[-1] < tol:
            break
        e0, f = model.energy_and_forces(x)
        g = -f.reshape(-1)[free]
        dirs = []
        if use_exact:
            dirs.append(False)
        dirs.append(True)
        step = None
        for project in dirs:
            H = model.stiffness(x, project=project)[free][:, free].tocsc()
            try:
                p = spla.spsolve(H, -g)
            except RuntimeError:
                continue
            if np.all(np.isfinite(p)) and p @ g < 0:
                step = p
                break
        if step is None:
            step = -g / max(np.abs(g).max(), 1e-300) * 1e-3
        t = 1.0
        slope = step @ g
        while True:
            xn = x.copy()
            xn.reshape(-1)[free] += t * step
            en = model.energy(xn)
            if en <= e0 + 1e-4 * t * slope or t < 1e-12:
                rn = model.relative_residual(xn)
                break
            # near the solution the energy change drowns in round-off: judge by the residual
            if abs(en - e0) <= 1e-11 * abs(e0):
                rn = model.relative_residual(xn)
                if rn < hist[-1]:
                    break
            t *= 0.5
        x = xn
        hist.append(rn)
    return x, hist

"""∂F/∂X at an equilibrium as a sparse matrix, assembled once per factorization.

A press needs the right-hand side ``∂F/∂X · Ψ`` (SC §4) for the Ψ the
remesher sends. ``ClothModel.dforces_dX`` computes it matrix-free, every
term per press (about half of a press at 10k vertices, the other half being
the back-substitution). At a given equilibrium x the map dX ↦ ∂F/∂X · dX is
linear, so :class:`DForcesDX` assembles it once, at refactorization time
(idle), as a (3n, 2n) block matrix of 3×2 blocks on the model's own scalar
stiffness pattern (``model.pattern``: vertex pairs of triangles, bending and
seam stencils); a press is then one sparse product with Ψ.

Terms, as in ``ClothModel.dforces_dX`` (the same derivatives, so the two
agree to round-off; seams, contact and friction do not depend on X):
membrane and gravity analytic, bending by the exact derivative of each
stencil's weights K and factor 3 / (A0 + A1), by the kernels
(``couture.cloth.kernels.membrane_gravity_dX_blocks``,
``bending_dX_blocks``) that share their per-triangle and per-stencil math
with ``membrane_dforces_dX`` and ``bending_dforces_dX`` (their orthotropic
and per-hinge twins, ``membrane_ortho_gravity_dX_blocks`` and
``bending_var_dX_blocks``, for woven or per-panel fabrics).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from couture.cloth.kernels import (
    bending_dX_blocks,
    bending_var_dX_blocks,
    membrane_gravity_dX_blocks,
    membrane_ortho_gravity_dX_blocks,
)
from couture.cloth.model import BEND_CONSTANT, GRAVITY, ClothModel


class DForcesDX:
    """``∂F/∂X`` (3n, 2n) of ``model`` at x, on the DOF rows ``dofs`` (the
    model's ``terms``, or those given).

    ``apply(psi)`` gives ``∂F/∂X · psi`` on the free DOFs ``dofs`` for psi
    (n, 2) or (n, 2, k), equal to ``model.dforces_dX(x, psi[:, :, j])[free]``
    (see the module docstring for the bending term). ``assemble_s``: wall time
    of the assembly [s]."""

    def __init__(self, model: ClothModel, x: np.ndarray, dofs: np.ndarray, terms=None):
        t0 = time.perf_counter()
        n = model.n
        x = np.ascontiguousarray(x, dtype=np.float64)
        if x.shape != (n, 3):
            raise ValueError(f"x must have shape ({n}, 3), got {x.shape}")
        pat = model.pattern
        data = np.zeros((len(pat.indices), 3, 2))
        terms = model.terms if terms is None else model._check_terms(terms)
        rho_g3 = GRAVITY * model.area_density / 3.0 if "gravity" in terms else 0.0
        if model.membrane_term == "membrane_orthotropic":
            # per-triangle elasticity and density (couture.cloth.material)
            rho = GRAVITY * model.tri_density / 3.0 if "gravity" in terms else np.zeros(len(model.tris))
            membrane_ortho_gravity_dX_blocks(
                x,
                model.tris,
                model.Dminv,
                model.tri_area,
                model.elasticity,
                "membrane_orthotropic" in terms,
                rho,
                model.tri_slots,
                data,
            )
        elif "membrane" in terms or rho_g3:
            membrane_gravity_dX_blocks(
                x,
                model.tris,
                model.Dminv,
                model.tri_area,
                model.mu,
                model.lam,
                "membrane" in terms,
                rho_g3,
                model.tri_slots,
                data,
            )
        if "bending" in terms and len(model.bend_stencils) and model.bend_directional:
            bending_var_dX_blocks(
                x,
                np.ascontiguousarray(model.X, dtype=np.float64),
                model.bend_stencils,
                model.bend_dir,
                model.bend_warp,
                BEND_CONSTANT,
                model.bend_slots,
                data,
            )
        elif "bending" in terms and len(model.bend_stencils) and model.bend_stiffness:
            bending_dX_blocks(
                x,
                np.ascontiguousarray(model.X, dtype=np.float64),
                model.bend_stencils,
                model.bend_stiffness * BEND_CONSTANT,
                model.bend_slots,
                data,
            )
        J = sp.bsr_matrix((data, pat.indices, pat.indptr), shape=(3 * n, 2 * n)).tocsr()
        self.n = n
        all_rows = len(dofs) == 3 * n and np.array_equal(dofs, np.arange(3 * n))
        self.J = J if all_rows else J[dofs]
        """∂F/∂X on the free DOF rows, (len(dofs), 2n) CSR"""
        self.assemble_s = time.perf_counter() - t0

    def apply(self, psi: np.ndarray) -> np.ndarray:
        """∂F/∂X · psi on the free DOFs: (len(dofs),) for psi (n, 2), (len(dofs), k) for (n, 2, k)."""
        psi = np.asarray(psi, dtype=np.float64)
        if psi.shape[:2] != (self.n, 2):
            raise ValueError(f"psi must have shape ({self.n}, 2[, k]), got {psi.shape}")
        return self.J @ psi.reshape(2 * self.n, -1) if psi.ndim == 3 else self.J @ psi.reshape(-1)

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
stencil's weights K and factor 3 / (A0 + A1)
(``couture.cloth.kernels.bending_stencil_weights_dir``).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from numba import njit

from couture.cloth.kernels import (
    _bending_dforce,
    _deformation,
    _membrane_dforce,
    _rest_shape_change,
    _shape_vectors,
    _stress,
    bending_stencil_weights_dir,
)
from couture.cloth.model import BEND_CONSTANT, GRAVITY, ClothModel


@njit(cache=True)
def _membrane_gravity_blocks(x, tris, Dminv, area, mu, lam, membrane, rho_g3, tri_slots, data):
    """data[slot(v, u)] (3, 2) += ∂f_v/∂X_u of the membrane (if ``membrane``)
    and gravity (weight ``rho_g3`` = ρ g / 3 per unit area; 0: none) of every
    triangle. The per-triangle force is linear in dDm = [dX1-dX0, dX2-dX0]:
    four probes (the entries of dDm) give it, each by the kernels of
    ``membrane_dforces_dX`` (``_rest_shape_change``, ``_membrane_dforce``)."""
    b = np.empty((3, 2))
    db = np.empty((3, 2))
    F = np.empty((3, 2))
    dF = np.empty((3, 2))
    E = np.empty((2, 2))
    S = np.empty((2, 2))
    dE = np.empty((2, 2))
    dS = np.empty((2, 2))
    dDm = np.empty((2, 2))
    dDi = np.empty((2, 2))
    tmp = np.empty((2, 2))
    dP = np.empty((3, 3))
    g = np.empty((4, 3, 3))  # g[probe, a, i]: ∂f_{a,i}/∂dDm[probe]
    for t in range(tris.shape[0]):
        A = area[t]
        _shape_vectors(Dminv, t, b)
        _deformation(x, tris, t, b, F)
        _stress(F, mu, lam, E, S)
        for p in range(4):
            dDm[:, :] = 0.0
            dDm[p // 2, p % 2] = 1.0
            dA = _rest_shape_change(Dminv, t, A, dDm, tmp, dDi)
            for a in range(3):
                for i in range(3):
                    g[p, a, i] = 0.0
                g[p, a, 1] -= rho_g3 * dA
            if not membrane:
                continue
            _membrane_dforce(x, tris, t, A, dA, mu, lam, b, F, S, dDi, db, dF, dE, dS, dP)
            for a in range(3):
                for i in range(3):
                    g[p, a, i] -= dP[a, i]
        # dDm[k, 0] = dX1k - dX0k, dDm[k, 1] = dX2k - dX0k: probe p = 2k + col
        for a in range(3):
            for c in range(3):
                s = tri_slots[t, a, c]
                for k in range(2):
                    if c == 0:
                        for i in range(3):
                            data[s, i, k] -= g[2 * k, a, i] + g[2 * k + 1, a, i]
                    else:
                        for i in range(3):
                            data[s, i, k] += g[2 * k + c - 1, a, i]


@njit(cache=True)
def _bending_blocks(x, X, st, coef0, bend_slots, data):
    """data[slot(v, u)] (3, 2) += ∂f_v/∂X_u of the bending term
    f = -Σ_e c fac_e K_e (K_e·x), c = ``coef0``: the exact derivative of each
    stencil's K and fac (``bending_stencil_weights_dir``, ``_bending_dforce``,
    as ``bending_dforces_dX``), one probe per stencil vertex and material axis."""
    w = np.empty(4)
    dw = np.empty(4)
    dP = np.empty((4, 3))
    d = np.zeros(8)
    for e in range(st.shape[0]):
        for q in range(4):
            for k in range(2):
                d[:] = 0.0
                d[2 * q + k] = 1.0  # vertex q of the stencil moves along material axis k
                fac, dfac = bending_stencil_weights_dir(X, st, e, d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7], w, dw)
                _bending_dforce(x, st, e, coef0, fac, dfac, w, dw, dP)
                for a in range(4):
                    slot = bend_slots[e, a, q]
                    for c in range(3):
                        data[slot, c, k] -= dP[a, c]


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
        if "membrane" in terms or rho_g3:
            _membrane_gravity_blocks(
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
        if "bending" in terms and len(model.bend_stencils) and model.bend_stiffness:
            _bending_blocks(
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

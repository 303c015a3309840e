"""The bending matrix and material constants the sensitivity solve needs.

The isometric bending model (Bergou et al. 2006) has a constant Hessian
``k_b * (Q ⊗ I3)`` with Q (n, n) built from the flat rest mesh only. The
sensitivity solve adds ``(k_floor - k_b)⁺ * Q`` to the stiffness (SC's h = 1/100
floor), so it needs Q per unit bending stiffness, k_b and the membrane Lamé
parameters: all read from the cloth model, Q from its own stencils and
weights (``couture.cloth.kernels.bending_weights``), so the floor uses exactly
the model's discretisation and constant.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from couture.cloth.model import BEND_CONSTANT, ClothModel, bending_weights


def length_scale(X: np.ndarray) -> float:
    """Garment length scale L [m]: the diagonal of the bounding box of the pattern X (n, 2)."""
    X = np.asarray(X)
    return float(np.linalg.norm(X.max(axis=0) - X.min(axis=0)))


def model_bending(model: ClothModel) -> tuple[float, sp.csr_matrix]:
    """(k_b [N m], Q (n, n) per unit k_b [1/m²·m²]) of a cloth model at its
    current rest shape: the bending energy is ``k_b/2 Σ_c x[:, c]·Q x[:, c]``."""
    st = np.asarray(model.bend_stencils)
    n = model.n
    if len(st) == 0:
        return model.bend_stiffness, sp.csr_matrix((n, n))
    Kw, fac = bending_weights(model.X, st)
    coef = BEND_CONSTANT * fac
    k = st.shape[1]
    vals = coef[:, None, None] * Kw[:, :, None] * Kw[:, None, :]
    rows = np.repeat(st[:, :, None], k, axis=2)
    cols = np.repeat(st[:, None, :], k, axis=1)
    Q = sp.coo_matrix((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(n, n)).tocsr()
    Q.sum_duplicates()
    return model.bend_stiffness, Q


def model_lame(model: ClothModel) -> tuple[float, float]:
    """Membrane Lamé parameters (λ, μ) [N/m] of a cloth model."""
    return float(model.lam), float(model.mu)

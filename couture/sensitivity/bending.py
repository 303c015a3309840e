"""Bending Hessian and the model accessors the sensitivity solve needs.

The isometric bending model (Bergou et al. 2006) has a constant Hessian
``k_b * (Q ⊗ I3)`` with Q (n, n) built from the flat rest mesh only. The
sensitivity solve adds ``(k_floor - k_b)⁺ * Q`` to the stiffness (SC's h = 1/100
floor), so it needs Q per unit bending stiffness, k_b and the membrane Lamé
parameters. The ClothModel is asked first; Q is computed from the mesh here
when it does not expose one.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def bergou_q(X: np.ndarray, tris: np.ndarray) -> sp.csr_matrix:
    """Scalar isometric-bending matrix Q (n, n), PSD, such that the bending
    energy is ``E = k_b / 2 * sum_c x[:, c] @ Q @ x[:, c]`` [J] for bending
    stiffness k_b [N m]. Q annihilates affine functions of the flat rest X.

    Per interior edge (i, j) with opposite vertices k, l (Bergou 2006, eq. 7):
    ``Q_e = 3 / (A_0 + A_1) * K K^T``, K the cotangent stencil.
    """
    X = np.asarray(X, dtype=np.float64)
    tris = np.asarray(tris, dtype=np.int64)
    n = len(X)
    m = len(tris)
    # half-edges keyed by sorted vertex pair
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    opp = np.concatenate([tris[:, 2], tris[:, 0], tris[:, 1]])
    tri_of = np.tile(np.arange(m), 3)
    key = np.sort(e, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    ks = key[order]
    same = np.all(ks[1:] == ks[:-1], axis=1)
    a = order[:-1][same]
    b = order[1:][same]
    i, j = key[a, 0], key[a, 1]
    k, l = opp[a], opp[b]
    P = X
    def cross(u, v):
        return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]

    area2 = np.abs(cross(P[tris[:, 1]] - P[tris[:, 0]], P[tris[:, 2]] - P[tris[:, 0]]))
    A0 = 0.5 * area2[tri_of[a]]
    A1 = 0.5 * area2[tri_of[b]]

    def cot(u, v):
        return np.einsum("ij,ij->i", u, v) / np.maximum(np.abs(cross(u, v)), 1e-300)

    e0 = P[j] - P[i]
    e1 = P[k] - P[i]
    e2 = P[l] - P[i]
    e3 = P[k] - P[j]
    e4 = P[l] - P[j]
    c01, c02 = cot(e0, e1), cot(e0, e2)
    c03, c04 = cot(-e0, e3), cot(-e0, e4)
    K = np.column_stack([c03 + c04, c01 + c02, -c01 - c03, -c02 - c04])
    idx = np.column_stack([i, j, k, l])
    coef = 3.0 / (A0 + A1)
    vals = coef[:, None, None] * K[:, :, None] * K[:, None, :]
    rows = np.repeat(idx[:, :, None], 4, axis=2)
    cols = np.repeat(idx[:, None, :], 4, axis=1)
    Q = sp.coo_matrix((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(n, n)).tocsr()
    Q.sum_duplicates()
    return Q


def length_scale(X: np.ndarray) -> float:
    """Garment length scale L [m]: the diagonal of the bounding box of the pattern X."""
    X = np.asarray(X)
    return float(np.linalg.norm(X.max(axis=0) - X.min(axis=0)))


def _get(obj, names):
    for nm in names:
        if obj is not None and hasattr(obj, nm):
            v = getattr(obj, nm)
            return v() if callable(v) else v
    return None


def model_bending(model) -> tuple[float, sp.csr_matrix]:
    """(k_b [N m], Q (n, n) per unit k_b) of a cloth model at its current rest
    shape. couture.cloth.ClothModel: Q from its own stencils and weights (so the
    floor uses exactly the model's discretisation and constant); other models:
    ``bending_matrix()`` per unit k_b, else Bergou's Q from ``model.mesh``."""
    k_b = float(_get(model, ["bend_stiffness"]) or 0.0)
    if hasattr(model, "bend_stencils") and hasattr(model, "X"):
        from couture.cloth.model import BEND_CONSTANT, bending_weights

        st = np.asarray(model.bend_stencils)
        n = model.n
        if len(st) == 0:
            return k_b, sp.csr_matrix((n, n))
        Kw, fac = bending_weights(model.X, st)
        coef = BEND_CONSTANT * np.asarray(fac)
        k = st.shape[1]
        vals = coef[:, None, None] * Kw[:, :, None] * Kw[:, None, :]
        rows = np.repeat(st[:, :, None], k, axis=2)
        cols = np.repeat(st[:, None, :], k, axis=1)
        Q = sp.coo_matrix((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(n, n)).tocsr()
        Q.sum_duplicates()
        return k_b, Q
    Q = _get(model, ["bending_matrix"])
    if Q is None:
        Q = bergou_q(model.mesh.X, model.mesh.tris)
    return k_b, sp.csr_matrix(Q)


def model_lame(model) -> tuple[float, float]:
    """Membrane Lamé parameters (λ, μ) [N/m] of a cloth model."""
    for src in (model, getattr(model, "fabric", None)):
        lam = _get(src, ["lame_lambda", "lam", "lambda_"])
        mu = _get(src, ["lame_mu", "mu"])
        if lam is not None and mu is not None:
            return float(lam), float(mu)
    raise AttributeError("cannot find the membrane Lamé parameters (lame_lambda, lame_mu) on the model or its fabric")

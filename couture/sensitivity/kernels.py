"""Numba kernels of the sensitivity node (explicit input and output arrays).

``bending_dforces_dX`` is the bending part of ∂F/∂X·dX without assembling a
matrix: couture.cloth's ``dforces_dX`` differentiates the bending matrix by
rebuilding it at X ± h dX in numpy, which is ~90 % of a press at 10k vertices.
Here each stencil's weights are differenced locally (same weights, same
constant), and the force change is scattered directly. ``fast_dforces_dX``
checks itself against the model once per model (see ``SensitivityFactor``).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _stencil_weights(X, st, e, dX, h, w):
    """w (4,) and returns fac = 3/(A0+A1) of stencil e at X + h dX (couture.cloth.model.bending_weights)."""
    i0, i1, i2, i3 = st[e, 0], st[e, 1], st[e, 2], st[e, 3]
    p0x = X[i0, 0] + h * dX[i0, 0]
    p0y = X[i0, 1] + h * dX[i0, 1]
    ex = X[i1, 0] + h * dX[i1, 0] - p0x
    ey = X[i1, 1] + h * dX[i1, 1] - p0y
    ax = X[i2, 0] + h * dX[i2, 0] - p0x
    ay = X[i2, 1] + h * dX[i2, 1] - p0y
    bx = X[i3, 0] + h * dX[i3, 0] - p0x
    by = X[i3, 1] + h * dX[i3, 1] - p0y
    le2 = ex * ex + ey * ey
    le = np.sqrt(le2)
    tx, ty = ex / le, ey / le
    A0 = 0.5 * abs(ex * ay - ey * ax)
    A1 = 0.5 * abs(ex * by - ey * bx)
    k2 = le2 / (2.0 * A0)
    k3 = le2 / (2.0 * A1)
    s2 = ax * tx + ay * ty
    s3 = bx * tx + by * ty
    k1 = -(k2 * s2 + k3 * s3) / le
    w[0] = -(k1 + k2 + k3)
    w[1] = k1
    w[2] = k2
    w[3] = k3
    return 3.0 / (A0 + A1)


@njit(cache=True)
def bending_dforces_dX(x, X, dX, st, coef0, h, df):
    """df (n, 3) -= d/dε [c fac(ε) w(ε) (w(ε)·x)] per stencil, central difference
    with step h; coef0 = k_b * BEND_CONSTANT. f_bend = -Q x, Q = Σ c fac w wᵀ."""
    wp = np.empty(4)
    wm = np.empty(4)
    for e in range(st.shape[0]):
        fp = _stencil_weights(X, st, e, dX, h, wp)
        fm = _stencil_weights(X, st, e, dX, -h, wm)
        for c in range(3):
            sp = 0.0
            sm = 0.0
            for a in range(4):
                sp += wp[a] * x[st[e, a], c]
                sm += wm[a] * x[st[e, a], c]
            for a in range(4):
                df[st[e, a], c] -= coef0 * (fp * wp[a] * sp - fm * wm[a] * sm) / (2.0 * h)


def fast_dforces_dX(model, x: np.ndarray, dX: np.ndarray) -> np.ndarray:
    """couture.cloth.ClothModel.dforces_dX(x, dX): the model's own terms except
    bending (``terms=``), plus the bending part by :func:`bending_dforces_dX`."""
    from couture.cloth.model import BEND_CONSTANT

    x = np.ascontiguousarray(x, dtype=np.float64)
    dX = np.ascontiguousarray(dX, dtype=np.float64).reshape(model.n, 2)
    others = [t for t in model.terms if t != "bending"]
    df = model.dforces_dX(x, dX, terms=others) if others else np.zeros((model.n, 3))
    st = np.ascontiguousarray(model.bend_stencils, dtype=np.int64)
    if "bending" in model.terms and len(st):
        h = model.bend_step(dX)
        if h > 0:
            bending_dforces_dX(x, model.X, dX, st, model.bend_stiffness * BEND_CONSTANT, h, df)
    return df


def supports_fast_dforces_dX(model) -> bool:
    """A couture.cloth.ClothModel whose dforces_dX takes ``terms``."""
    import inspect

    if not all(hasattr(model, a) for a in ("bend_stencils", "bend_step", "terms", "bend_stiffness", "X")):
        return False
    try:
        return "terms" in inspect.signature(model.dforces_dX).parameters
    except (TypeError, ValueError):
        return False

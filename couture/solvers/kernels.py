"""Numba kernels of the equilibrium solvers (newton's ``kernels.py`` habit).

Free functions with explicit input and output arrays; the solver classes own
state and loops. All sparse matrices are CSR with sorted column indices.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# --------------------------------------------------------------------------
# incomplete Cholesky IC(0) + PCG
# --------------------------------------------------------------------------


@njit(cache=True)
def ic0_factor(indptr, indices, data, dscale, shift, out):
    """IC(0) of ``S + shift*I`` where S = D^-1/2 A D^-1/2 (unit diagonal).

    ``indptr/indices/data`` hold the lower triangle of A (diagonal last in each
    row); ``dscale`` = diag(A)^-1/2; ``out`` receives L's values on the same
    pattern. Returns the row index of a breakdown (pivot not positive) or -1.
    """
    n = len(indptr) - 1
    for i in range(n):
        a0 = indptr[i]
        a1 = indptr[i + 1]
        for p in range(a0, a1 - 1):
            k = indices[p]
            # s = S_ik - sum_{j<k} L_ij L_kj   (two-pointer merge of rows i and k)
            s = data[p] * dscale[i] * dscale[k]
            q = a0
            r = indptr[k]
            r1 = indptr[k + 1] - 1
            while q < p and r < r1:
                cq = indices[q]
                cr = indices[r]
                if cq == cr:
                    s -= out[q] * out[r]
                    q += 1
                    r += 1
                elif cq < cr:
                    q += 1
                else:
                    r += 1
            out[p] = s / out[r1]
        d = 1.0 + shift
        for p in range(a0, a1 - 1):
            d -= out[p] * out[p]
        if not (d > 1e-12):
            return i
        out[a1 - 1] = np.sqrt(d)
    return -1


@njit(cache=True)
def _ic0_apply(Lp, Li, Lx, dscale, r, z, y):
    """z = D^-1/2 (L L^T)^-1 D^-1/2 r; y is scratch."""
    n = len(Lp) - 1
    for i in range(n):
        s = r[i] * dscale[i]
        for p in range(Lp[i], Lp[i + 1] - 1):
            s -= Lx[p] * y[Li[p]]
        y[i] = s / Lx[Lp[i + 1] - 1]
    for i in range(n - 1, -1, -1):
        zi = y[i] / Lx[Lp[i + 1] - 1]
        y[i] = zi
        for p in range(Lp[i], Lp[i + 1] - 1):
            y[Li[p]] -= Lx[p] * zi
    for i in range(n):
        z[i] = y[i] * dscale[i]


@njit(cache=True)
def _spmv(Ap, Ai, Ax, x, y):
    n = len(Ap) - 1
    for i in range(n):
        s = 0.0
        for p in range(Ap[i], Ap[i + 1]):
            s += Ax[p] * x[Ai[p]]
        y[i] = s


@njit(cache=True)
def pcg_ic0(Ap, Ai, Ax, Lp, Li, Lx, dscale, b, x, rtol, maxiter, use_ic):
    """Preconditioned CG on SPD A (full CSR) from the start x (overwritten).

    Preconditioner: IC(0) factor L (``use_ic``) or Jacobi (dscale²).
    Stops at ||r|| <= rtol ||b||. Returns (iterations, ||r||/||b||).
    """
    n = len(b)
    r = np.empty(n)
    z = np.empty(n)
    p = np.empty(n)
    q = np.empty(n)
    y = np.empty(n)
    _spmv(Ap, Ai, Ax, x, q)
    bn = 0.0
    for i in range(n):
        r[i] = b[i] - q[i]
        bn += b[i] * b[i]
    bn = np.sqrt(bn)
    if bn == 0.0:
        for i in range(n):
            x[i] = 0.0
        return 0, 0.0
    rn = 0.0
    for i in range(n):
        rn += r[i] * r[i]
    rn = np.sqrt(rn)
    if rn <= rtol * bn:
        return 0, rn / bn
    if use_ic:
        _ic0_apply(Lp, Li, Lx, dscale, r, z, y)
    else:
        for i in range(n):
            z[i] = r[i] * dscale[i] * dscale[i]
    rz = 0.0
    for i in range(n):
        p[i] = z[i]
        rz += r[i] * z[i]
    it = 0
    while it < maxiter:
        it += 1
        _spmv(Ap, Ai, Ax, p, q)
        pq = 0.0
        for i in range(n):
            pq += p[i] * q[i]
        if not (pq > 0.0):
            break
        alpha = rz / pq
        rn = 0.0
        for i in range(n):
            x[i] += alpha * p[i]
            r[i] -= alpha * q[i]
            rn += r[i] * r[i]
        rn = np.sqrt(rn)
        if rn <= rtol * bn or not np.isfinite(rn):
            break
        if use_ic:
            _ic0_apply(Lp, Li, Lx, dscale, r, z, y)
        else:
            for i in range(n):
                z[i] = r[i] * dscale[i] * dscale[i]
        rz_new = 0.0
        for i in range(n):
            rz_new += r[i] * z[i]
        beta = rz_new / rz
        rz = rz_new
        for i in range(n):
            p[i] = z[i] + beta * p[i]
    return it, rn / bn


@njit(cache=True)
def gather_add(dst, src, idx, scale):
    """dst[k] = scale * src[idx[k]]"""
    for k in range(len(idx)):
        dst[k] = scale * src[idx[k]]

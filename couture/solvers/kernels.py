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


# --------------------------------------------------------------------------
# Verlet mass-spring kernels
# --------------------------------------------------------------------------


@njit(cache=True)
def spring_forces(x, sp_i, sp_j, sp_rest, sp_k, f):
    """f += Hookean spring forces; returns spring energy [J]."""
    E = 0.0
    for s in range(len(sp_i)):
        i = sp_i[s]
        j = sp_j[s]
        d0 = x[j, 0] - x[i, 0]
        d1 = x[j, 1] - x[i, 1]
        d2 = x[j, 2] - x[i, 2]
        l = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if l < 1e-300:
            continue
        e = l - sp_rest[s]
        E += 0.5 * sp_k[s] * e * e
        c = sp_k[s] * e / l
        f[i, 0] += c * d0
        f[i, 1] += c * d1
        f[i, 2] += c * d2
        f[j, 0] -= c * d0
        f[j, 1] -= c * d1
        f[j, 2] -= c * d2
    return E


@njit(cache=True)
def verlet_step(x, x_prev, f, inv_m, free, h2, keep):
    """Stoermer-Verlet with velocity retention ``keep`` (1 - damping).

    x_new = x + keep (x - x_prev) + h² f / m for free vertices; pinned stay.
    Writes x_prev <- x and x <- x_new in place; returns (Σ m v² proxy) = Σ |Δx|²/inv_m.
    """
    ke = 0.0
    for i in range(x.shape[0]):
        if not free[i]:
            x_prev[i, 0] = x[i, 0]
            x_prev[i, 1] = x[i, 1]
            x_prev[i, 2] = x[i, 2]
            continue
        for c in range(3):
            xn = x[i, c] + keep * (x[i, c] - x_prev[i, c]) + h2 * f[i, c] * inv_m[i]
            dx = xn - x[i, c]
            ke += dx * dx / inv_m[i]
            x_prev[i, c] = x[i, c]
            x[i, c] = xn
    return ke


@njit(cache=True)
def project_seams(x, se, sa, sb, sw, inv_m, iters):
    """Zero-length seam constraints: emitter e meets (1-w) x_a + w x_b (PBD projection)."""
    for _ in range(iters):
        for s in range(len(se)):
            e = se[s]
            a = sa[s]
            b = sb[s]
            w = sw[s]
            we = inv_m[e]
            wa = inv_m[a] * (1.0 - w) * (1.0 - w)
            wb = inv_m[b] * w * w
            den = we + wa + wb
            if den <= 0.0:
                continue
            for c in range(3):
                C = x[e, c] - ((1.0 - w) * x[a, c] + w * x[b, c])
                lam = C / den
                x[e, c] -= inv_m[e] * lam
                x[a, c] += inv_m[a] * (1.0 - w) * lam
                x[b, c] += inv_m[b] * w * lam


@njit(cache=True)
def project_lengths(x, ci, cj, rest, inv_m, stiffness, iters):
    """Gauss-Seidel distance-constraint projection (Jakobsen / PBD) of edges to their rest lengths."""
    for _ in range(iters):
        for s in range(len(ci)):
            i = ci[s]
            j = cj[s]
            wi = inv_m[i]
            wj = inv_m[j]
            w = wi + wj
            if w <= 0.0:
                continue
            d0 = x[j, 0] - x[i, 0]
            d1 = x[j, 1] - x[i, 1]
            d2 = x[j, 2] - x[i, 2]
            l = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            if l < 1e-300:
                continue
            c = stiffness * (l - rest[s]) / (l * w)
            x[i, 0] += wi * c * d0
            x[i, 1] += wi * c * d1
            x[i, 2] += wi * c * d2
            x[j, 0] -= wj * c * d0
            x[j, 1] -= wj * c * d1
            x[j, 2] -= wj * c * d2

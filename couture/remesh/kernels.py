"""Numba kernels of the remesher: (positive) mean value coordinates, Delaunay
edge flips, point location. Free functions over explicit arrays; the
orchestration lives in psi.py, quality.py and transfer.py.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, inline="always")
def _cross(ax, ay, bx, by):
    return ax * by - ay * bx


# --------------------------------------------------------------------------
# mean value coordinates
# --------------------------------------------------------------------------


@njit(cache=True, parallel=True)
def mvc_dense(P, edges, Q, W):
    """Mean value coordinates (Floater 2003; Hormann & Floater 2006 for
    non-convex polygons with holes) of points Q w.r.t. the boundary P.

    P (nb, 2) boundary vertices; edges (ne, 2) into P, oriented with the
    domain on their left (outline CCW, holes CW); Q (nq, 2) points inside;
    W (nq, nb) output, rows sum to one. Edge (a, b) seen under the signed
    angle α gives tan(α/2)/r_a to a and tan(α/2)/r_b to b.
    """
    nq = Q.shape[0]
    for q in prange(nq):
        x = Q[q, 0]
        y = Q[q, 1]
        for j in range(W.shape[1]):
            W[q, j] = 0.0
        tot = 0.0
        for e in range(edges.shape[0]):
            a = edges[e, 0]
            b = edges[e, 1]
            ax = P[a, 0] - x
            ay = P[a, 1] - y
            bx = P[b, 0] - x
            by = P[b, 1] - y
            ra = np.sqrt(ax * ax + ay * ay)
            rb = np.sqrt(bx * bx + by * by)
            c = _cross(ax, ay, bx, by)
            den = ra * rb + ax * bx + ay * by
            if den <= 0.0:
                continue  # α = ±π: the point lies on the edge, never inside the domain
            t = c / den  # tan(α/2)
            W[q, a] += t / ra
            W[q, b] += t / rb
            tot += t / ra + t / rb
        for j in range(W.shape[1]):
            W[q, j] /= tot


@njit(cache=True, parallel=True)
def pmvc_dense(P, edges, Q, W):
    """Positive mean value coordinates (Lipman, Kopf, Cohen-Or, Levin 2007).

    Same arguments as :func:`mvc_dense`. The mean value integral
    ∫ f(p(θ)) / ρ(θ) dθ is taken over the boundary *visible* from the point
    only: along each direction θ the first boundary hit p(θ) at distance
    ρ(θ). The visible boundary is found by an angular sweep over the
    front-facing edges (for an interior point the first hit along any ray is
    an exit, hence a front-facing edge), split at every edge endpoint angle;
    on each elementary angular piece the nearest edge is visible, and the
    piece q0 -> q1 on it contributes exactly tan(α/2)/r0 at q0 and
    tan(α/2)/r1 at q1, which are spread linearly onto the edge's end vertices.
    Weights are positive; the visible pieces tile the full circle, so linear
    functions are reproduced exactly.
    """
    nq = Q.shape[0]
    ne = edges.shape[0]
    two_pi = 2.0 * np.pi
    for q in prange(nq):
        x = Q[q, 0]
        y = Q[q, 1]
        for j in range(W.shape[1]):
            W[q, j] = 0.0
        # front-facing edges as angular intervals [s, s + len], split at +pi
        s_ang = np.empty(2 * ne)
        e_ang = np.empty(2 * ne)
        eid = np.empty(2 * ne, np.int64)
        m = 0
        for e in range(ne):
            a = edges[e, 0]
            b = edges[e, 1]
            ax = P[a, 0] - x
            ay = P[a, 1] - y
            bx = P[b, 0] - x
            by = P[b, 1] - y
            if _cross(ax, ay, bx, by) <= 0.0:
                continue
            t0 = np.arctan2(ay, ax)
            d = np.arctan2(by, bx) - t0
            if d < 0.0:
                d += two_pi
            t1 = t0 + d
            s_ang[m] = t0
            e_ang[m] = min(t1, np.pi)
            eid[m] = e
            m += 1
            if t1 > np.pi:
                s_ang[m] = -np.pi
                e_ang[m] = t1 - two_pi
                eid[m] = e
                m += 1
        order = np.argsort(s_ang[:m])
        # breakpoints: all interval ends
        bp = np.empty(2 * m + 2)
        for i in range(m):
            bp[2 * i] = s_ang[i]
            bp[2 * i + 1] = e_ang[i]
        bp[2 * m] = -np.pi
        bp[2 * m + 1] = np.pi
        bp = np.sort(bp)
        active = np.empty(m, np.int64)
        n_act = 0
        nxt = 0  # next interval (in start order) to activate
        tot = 0.0
        for k in range(bp.shape[0] - 1):
            p0 = bp[k]
            p1 = bp[k + 1]
            if p1 - p0 < 1e-13:
                continue
            pm = 0.5 * (p0 + p1)
            while nxt < m and s_ang[order[nxt]] <= pm:
                active[n_act] = order[nxt]
                n_act += 1
                nxt += 1
            # drop finished intervals, pick the nearest edge along the mid ray
            dx = np.cos(pm)
            dy = np.sin(pm)
            best = -1
            best_rho = np.inf
            i = 0
            while i < n_act:
                iv = active[i]
                if e_ang[iv] <= pm:
                    n_act -= 1
                    active[i] = active[n_act]
                    continue
                e = eid[iv]
                a = edges[e, 0]
                b = edges[e, 1]
                ex = P[b, 0] - P[a, 0]
                ey = P[b, 1] - P[a, 1]
                den = _cross(dx, dy, ex, ey)
                if den != 0.0:
                    rho = _cross(P[a, 0] - x, P[a, 1] - y, ex, ey) / den
                    if rho > 0.0 and rho < best_rho:
                        best_rho = rho
                        best = e
                i += 1
            if best < 0:
                continue
            a = edges[best, 0]
            b = edges[best, 1]
            axr = P[a, 0] - x
            ayr = P[a, 1] - y
            ex = P[b, 0] - P[a, 0]
            ey = P[b, 1] - P[a, 1]
            # the piece's end points on the edge, at angles p0 and p1
            d0x = np.cos(p0)
            d0y = np.sin(p0)
            d1x = np.cos(p1)
            d1y = np.sin(p1)
            s0 = _cross(axr, ayr, d0x, d0y) / _cross(d0x, d0y, ex, ey)
            s1 = _cross(axr, ayr, d1x, d1y) / _cross(d1x, d1y, ex, ey)
            s0 = min(max(s0, 0.0), 1.0)
            s1 = min(max(s1, 0.0), 1.0)
            q0x = axr + s0 * ex
            q0y = ayr + s0 * ey
            q1x = axr + s1 * ex
            q1y = ayr + s1 * ey
            r0 = np.sqrt(q0x * q0x + q0y * q0y)
            r1 = np.sqrt(q1x * q1x + q1y * q1y)
            den = r0 * r1 + q0x * q1x + q0y * q1y
            if den <= 0.0 or r0 == 0.0 or r1 == 0.0:
                continue
            t = _cross(q0x, q0y, q1x, q1y) / den  # tan(α/2)
            w0 = t / r0
            w1 = t / r1
            W[q, a] += w0 * (1.0 - s0) + w1 * (1.0 - s1)
            W[q, b] += w0 * s0 + w1 * s1
            tot += w0 + w1
        for j in range(W.shape[1]):
            W[q, j] /= tot


# --------------------------------------------------------------------------
# Delaunay edge flips
# --------------------------------------------------------------------------


@njit(cache=True)
def _orient(X, a, b, c):
    return (X[b, 0] - X[a, 0]) * (X[c, 1] - X[a, 1]) - (X[b, 1] - X[a, 1]) * (X[c, 0] - X[a, 0])


@njit(cache=True)
def _incircle(X, a, b, c, d):
    """> 0 when d lies inside the circumcircle of the CCW triangle (a, b, c)."""
    adx = X[a, 0] - X[d, 0]
    ady = X[a, 1] - X[d, 1]
    bdx = X[b, 0] - X[d, 0]
    bdy = X[b, 1] - X[d, 1]
    cdx = X[c, 0] - X[d, 0]
    cdy = X[c, 1] - X[d, 1]
    ad = adx * adx + ady * ady
    bd = bdx * bdx + bdy * bdy
    cd = cdx * cdx + cdy * cdy
    det = adx * (bdy * cd - bd * cdy) - ady * (bdx * cd - bd * cdx) + ad * (bdx * cdy - bdy * cdx)
    scale = (ad + bd + cd) ** 2 + 1e-300
    return det / scale


@njit(cache=True)
def _edge_key(a, b, n):
    if a < b:
        return a * n + b
    return b * n + a


@njit(cache=True)
def _is_fixed(key, fixed_sorted):
    if fixed_sorted.shape[0] == 0:
        return False
    i = np.searchsorted(fixed_sorted, key)
    return i < fixed_sorted.shape[0] and fixed_sorted[i] == key


@njit(cache=True)
def lawson_flips(X, T, N, fixed_sorted, max_passes):
    """Lawson's flip algorithm in place on CCW triangles T with neighbours N
    (N[t, i]: triangle across the edge opposite T[t, i], -1 on the boundary).
    Never flips fixed edges (keys a * n + b, a < b, sorted) nor an edge whose
    quad is not strictly convex. Returns the number of flips."""
    n = X.shape[0]
    m = T.shape[0]
    flips = 0
    for _ in range(max_passes):
        changed = 0
        for t in range(m):
            for i in range(3):
                u = N[t, i]
                if u < 0:
                    continue
                a = T[t, i]
                p = T[t, (i + 1) % 3]
                qv = T[t, (i + 2) % 3]
                j = 0
                while T[u, j] == p or T[u, j] == qv:
                    j += 1
                bv = T[u, j]
                if _incircle(X, a, p, qv, bv) <= 1e-12:
                    continue
                if _is_fixed(_edge_key(p, qv, n), fixed_sorted):
                    continue
                if _orient(X, a, p, bv) <= 0.0 or _orient(X, bv, qv, a) <= 0.0:
                    continue  # quad not strictly convex
                if _orient(X, a, p, qv) <= 0.0 or _orient(X, bv, qv, p) <= 0.0:
                    continue  # an inverted triangle: leave the region to a remesh
                # neighbours before the flip
                ntp = N[t, (i + 1) % 3]  # across (qv, a)
                ntq = N[t, (i + 2) % 3]  # across (a, p)
                # in u = (bv, qv, p) cyclically: across (p, bv) is opposite qv, across (bv, qv) opposite p
                nuq = -1
                nup = -1
                for k in range(3):
                    if T[u, k] == qv:
                        nuq = N[u, k]
                    elif T[u, k] == p:
                        nup = N[u, k]
                # t' = (a, p, bv), u' = (bv, qv, a)
                T[t, 0] = a
                T[t, 1] = p
                T[t, 2] = bv
                N[t, 0] = nuq
                N[t, 1] = u
                N[t, 2] = ntq
                T[u, 0] = bv
                T[u, 1] = qv
                T[u, 2] = a
                N[u, 0] = ntp
                N[u, 1] = t
                N[u, 2] = nup
                if nuq >= 0:
                    for k in range(3):
                        if N[nuq, k] == u:
                            N[nuq, k] = t
                if ntp >= 0:
                    for k in range(3):
                        if N[ntp, k] == t:
                            N[ntp, k] = u
                changed += 1
                break  # t changed: its other edges are revisited next pass
        flips += changed
        if changed == 0:
            break
    return flips


@njit(cache=True)
def triangle_quality(X, T, out):
    """2·sqrt(3)·r_in / l_max per triangle: 1 for equilateral, 0 degenerate,
    negative for inverted triangles (signed area)."""
    for t in range(T.shape[0]):
        a = T[t, 0]
        b = T[t, 1]
        c = T[t, 2]
        lab = np.hypot(X[b, 0] - X[a, 0], X[b, 1] - X[a, 1])
        lbc = np.hypot(X[c, 0] - X[b, 0], X[c, 1] - X[b, 1])
        lca = np.hypot(X[a, 0] - X[c, 0], X[a, 1] - X[c, 1])
        area2 = _orient(X, a, b, c)
        per = lab + lbc + lca
        lmax = max(lab, max(lbc, lca))
        if lmax <= 0.0:
            out[t] = 0.0
        else:
            out[t] = 2.0 * np.sqrt(3.0) * (area2 / per) / lmax  # r_in = 2A / per = area2 / per


# --------------------------------------------------------------------------
# point location (uniform grid)
# --------------------------------------------------------------------------


@njit(cache=True)
def build_grid(X, T, lo, cell, nx, ny):
    """Bucket triangles by the grid cells their bounding boxes cover (CSR)."""
    count = np.zeros(nx * ny + 1, np.int64)
    for t in range(T.shape[0]):
        x0 = min(X[T[t, 0], 0], min(X[T[t, 1], 0], X[T[t, 2], 0]))
        x1 = max(X[T[t, 0], 0], max(X[T[t, 1], 0], X[T[t, 2], 0]))
        y0 = min(X[T[t, 0], 1], min(X[T[t, 1], 1], X[T[t, 2], 1]))
        y1 = max(X[T[t, 0], 1], max(X[T[t, 1], 1], X[T[t, 2], 1]))
        i0 = min(max(int((x0 - lo[0]) / cell), 0), nx - 1)
        i1 = min(max(int((x1 - lo[0]) / cell), 0), nx - 1)
        j0 = min(max(int((y0 - lo[1]) / cell), 0), ny - 1)
        j1 = min(max(int((y1 - lo[1]) / cell), 0), ny - 1)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                count[j * nx + i + 1] += 1
    for k in range(nx * ny):
        count[k + 1] += count[k]
    items = np.empty(count[nx * ny], np.int64)
    fill = count[:-1].copy()
    for t in range(T.shape[0]):
        x0 = min(X[T[t, 0], 0], min(X[T[t, 1], 0], X[T[t, 2], 0]))
        x1 = max(X[T[t, 0], 0], max(X[T[t, 1], 0], X[T[t, 2], 0]))
        y0 = min(X[T[t, 0], 1], min(X[T[t, 1], 1], X[T[t, 2], 1]))
        y1 = max(X[T[t, 0], 1], max(X[T[t, 1], 1], X[T[t, 2], 1]))
        i0 = min(max(int((x0 - lo[0]) / cell), 0), nx - 1)
        i1 = min(max(int((x1 - lo[0]) / cell), 0), nx - 1)
        j0 = min(max(int((y0 - lo[1]) / cell), 0), ny - 1)
        j1 = min(max(int((y1 - lo[1]) / cell), 0), ny - 1)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                items[fill[j * nx + i]] = t
                fill[j * nx + i] += 1
    return count, items


@njit(cache=True)
def _bary(X, T, t, px, py, out):
    a = T[t, 0]
    b = T[t, 1]
    c = T[t, 2]
    d = _orient(X, a, b, c)
    if d == 0.0:
        return False
    l1 = ((X[c, 0] - X[b, 0]) * (py - X[b, 1]) - (X[c, 1] - X[b, 1]) * (px - X[b, 0])) / d
    l2 = ((X[a, 0] - X[c, 0]) * (py - X[c, 1]) - (X[a, 1] - X[c, 1]) * (px - X[c, 0])) / d
    out[0] = l1
    out[1] = l2
    out[2] = 1.0 - l1 - l2
    return True


@njit(cache=True)
def _closest_on_triangle(X, T, t, px, py, out):
    """Squared distance to the triangle's boundary and the barycentric of the closest point."""
    best = np.inf
    for k in range(3):
        a = T[t, k]
        b = T[t, (k + 1) % 3]
        ex = X[b, 0] - X[a, 0]
        ey = X[b, 1] - X[a, 1]
        ll = ex * ex + ey * ey
        s = 0.0
        if ll > 0.0:
            s = ((px - X[a, 0]) * ex + (py - X[a, 1]) * ey) / ll
            s = min(max(s, 0.0), 1.0)
        dx = X[a, 0] + s * ex - px
        dy = X[a, 1] + s * ey - py
        d2 = dx * dx + dy * dy
        if d2 < best:
            best = d2
            out[0] = 0.0
            out[1] = 0.0
            out[2] = 0.0
            out[k] = 1.0 - s
            out[(k + 1) % 3] = s
    return best


@njit(cache=True)
def locate(X, T, count, items, lo, cell, nx, ny, P, tri_out, bary_out, tol):
    """For each point: the containing triangle and barycentrics, else the
    nearest triangle and the barycentrics of its closest point."""
    lam = np.empty(3)
    cl = np.empty(3)
    for q in range(P.shape[0]):
        px = P[q, 0]
        py = P[q, 1]
        ci = min(max(int((px - lo[0]) / cell), 0), nx - 1)
        cj = min(max(int((py - lo[1]) / cell), 0), ny - 1)
        found = -1
        bestlam = -np.inf
        c = cj * nx + ci
        for k in range(count[c], count[c + 1]):
            t = items[k]
            if _bary(X, T, t, px, py, lam):
                mn = min(lam[0], min(lam[1], lam[2]))
                if mn > bestlam:
                    bestlam = mn
                    found = t
                    bary_out[q, 0] = lam[0]
                    bary_out[q, 1] = lam[1]
                    bary_out[q, 2] = lam[2]
        if found >= 0 and bestlam >= -tol:
            tri_out[q] = found
            continue
        # outside every triangle: ring search for the nearest one
        best = np.inf
        besttri = -1
        r = 0
        rmax = max(nx, ny)
        while r <= rmax:
            for i in range(ci - r, ci + r + 1):
                for j in range(cj - r, cj + r + 1):
                    if i < 0 or j < 0 or i >= nx or j >= ny:
                        continue
                    if max(abs(i - ci), abs(j - cj)) != r:
                        continue
                    c = j * nx + i
                    for k in range(count[c], count[c + 1]):
                        t = items[k]
                        d2 = _closest_on_triangle(X, T, t, px, py, cl)
                        if d2 < best:
                            best = d2
                            besttri = t
                            bary_out[q, 0] = cl[0]
                            bary_out[q, 1] = cl[1]
                            bary_out[q, 2] = cl[2]
            if besttri >= 0 and np.sqrt(best) <= r * cell:
                break
            r += 1
        tri_out[q] = besttri

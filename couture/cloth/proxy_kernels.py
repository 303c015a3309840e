"""Numba kernels of the ellipsoid proxy (``couture.cloth.proxy``): the exact
signed distance to one ellipsoid and to a union of ellipsoids, with explicit
output arrays.

An ellipsoid is (center c (3,), rotation R (3, 3) whose columns are its axes,
semi-axes a (3,)); a world point p has local coordinates y = Rᵀ (p - c).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def ellipsoid_closest(y, a, x):
    """Signed distance [m] from local point y (3,) to the ellipsoid of semi-axes
    a (3,) (negative inside); writes the closest surface point into x (3,).

    The closest point is x_i = a_i² y_i / (t + a_i²) with t the root of
    F(t) = Σ (a_i y_i / (t + a_i²))² - 1 in t > -min a² (Eberly). With
    s = t + min a² and b_i = a_i² - min a², F is convex and decreasing in s > 0,
    so Newton from a point left of the root climbs to it monotonically; the
    start is the largest of several lower bounds of the root."""
    amin2 = min(a[0] * a[0], min(a[1] * a[1], a[2] * a[2]))
    scale = max(a[0], max(a[1], a[2]))
    tiny = 1e-13 * scale
    yy = np.empty(3)
    b = np.empty(3)
    w = np.empty(3)
    for i in range(3):
        yy[i] = y[i]
        b[i] = a[i] * a[i] - amin2
    # y on a symmetry plane of the smallest axis: nudge it off so the root is
    # bracketed (the limit is the degenerate solution of a point inside)
    for i in range(3):
        if b[i] == 0.0 and abs(yy[i]) < tiny:
            yy[i] = tiny
    bmax = max(b[0], max(b[1], b[2]))
    norm_ay = 0.0
    lo = 0.0
    for i in range(3):
        w[i] = (a[i] * yy[i]) ** 2
        norm_ay += w[i]
        lo = max(lo, a[i] * abs(yy[i]) - b[i])
    lo = max(lo, np.sqrt(norm_ay) - bmax)
    s = lo
    for _ in range(200):
        F = -1.0
        dF = 0.0
        for i in range(3):
            d = s + b[i]
            F += w[i] / (d * d)
            dF -= 2.0 * w[i] / (d * d * d)
        if F <= 0.0 or dF == 0.0:
            break
        step = -F / dF
        s += step
        if step <= 1e-15 * s:
            break
    f = 0.0
    dist2 = 0.0
    for i in range(3):
        x[i] = a[i] * a[i] * yy[i] / (s + b[i])
        f += (y[i] / a[i]) ** 2
        dist2 += (y[i] - x[i]) ** 2
    d = np.sqrt(dist2)
    return d if f >= 1.0 else -d


@njit(cache=True, inline="always")
def _world_normal(x, k, rot, radii):
    """Outward unit normal of ellipsoid k at its surface point x (local frame):
    proportional to x / a², turned back to world axes."""
    n0 = x[0] / (radii[k, 0] ** 2)
    n1 = x[1] / (radii[k, 1] ** 2)
    n2 = x[2] / (radii[k, 2] ** 2)
    nn = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    n0 /= nn
    n1 /= nn
    n2 /= nn
    return (
        rot[k, 0, 0] * n0 + rot[k, 0, 1] * n1 + rot[k, 0, 2] * n2,
        rot[k, 1, 0] * n0 + rot[k, 1, 1] * n1 + rot[k, 1, 2] * n2,
        rot[k, 2, 0] * n0 + rot[k, 2, 1] * n1 + rot[k, 2, 2] * n2,
    )


@njit(cache=True, inline="always")
def _merge(best, g0, g1, g2, d, x, k, rot, radii, blend):
    """Fold ellipsoid k (signed distance d, closest point x) into the running
    minimum (best, its gradient g): the exact min for blend = 0, else the
    polynomial smooth min min(a, b) - blend h²/4, h = max(blend - |a - b|, 0) /
    blend (C¹: it rounds the concave creases where ellipsoids meet, outward:
    by blend/4 where two meet, less than blend in all, since a fold lowers the
    value only while the new distance is within blend of it). Returns (best, g0, g1, g2, whether k is now the
    nearest)."""
    if d >= best + blend:
        return best, g0, g1, g2, False
    w0, w1, w2 = _world_normal(x, k, rot, radii)
    if best - d >= blend:  # k wins outright (always, for blend = 0 and d < best)
        return d, w0, w1, w2, True
    h = (blend - abs(best - d)) / blend
    if d < best:
        a_new, a_old = 1.0 - 0.5 * h, 0.5 * h
    else:
        a_new, a_old = 0.5 * h, 1.0 - 0.5 * h
    s = min(best, d) - 0.25 * blend * h * h
    return s, a_old * g0 + a_new * w0, a_old * g1 + a_new * w1, a_old * g2 + a_new * w2, d < best


@njit(cache=True)
def union_phi_grad(points, centers, rot, radii, rmax, phi, grad, which):
    """Signed distance to the union of K ellipsoids, min_k of each one's exact
    signed distance (exact outside the union; inside, the depth in the
    deepest ellipsoid, a lower bound of the depth in the union), its gradient
    (the outward unit normal at the closest point of the winning ellipsoid)
    and that ellipsoid's index.

    points (n, 3); centers (K, 3); rot (K, 3, 3); radii (K, 3); rmax (K,) the
    largest semi-axis; outputs phi (n,), grad (n, 3), which (n,) int64.
    |p - c_k| - rmax_k is a lower bound of ellipsoid k's signed distance (the
    ellipsoid lies in that ball), so most ellipsoids are skipped unevaluated."""
    K = centers.shape[0]
    lb = np.empty(K)
    y = np.empty(3)
    x = np.empty(3)
    for n in range(points.shape[0]):
        first = 0
        for k in range(K):
            dx = points[n, 0] - centers[k, 0]
            dy = points[n, 1] - centers[k, 1]
            dz = points[n, 2] - centers[k, 2]
            lb[k] = np.sqrt(dx * dx + dy * dy + dz * dz) - rmax[k]
            if lb[k] < lb[first]:
                first = k
        best = np.inf
        bk = -1
        g0 = 0.0
        g1 = 0.0
        g2 = 0.0
        for j in range(K + 1):
            k = first if j == 0 else j - 1
            if j > 0 and (k == first or lb[k] >= best):
                continue
            for i in range(3):
                y[i] = (
                    rot[k, 0, i] * (points[n, 0] - centers[k, 0])
                    + rot[k, 1, i] * (points[n, 1] - centers[k, 1])
                    + rot[k, 2, i] * (points[n, 2] - centers[k, 2])
                )
            d = ellipsoid_closest(y, radii[k], x)
            if d < best:
                best = d
                bk = k
                g0, g1, g2 = _world_normal(x, k, rot, radii)
        phi[n] = best
        grad[n, 0] = g0
        grad[n, 1] = g1
        grad[n, 2] = g2
        which[n] = bk


@njit(cache=True)
def tree_phi_grad(points, roots, child0, child1, leaf_of, sph_c, sph_r, centers, rot, radii, blend, phi, grad, which):
    """union_phi_grad through a sphere tree (branch and bound): node m's ball
    (sph_c[m], sph_r[m]) holds every leaf ellipsoid below it, so
    |p - sph_c| - sph_r bounds their signed distances from below and a subtree
    whose bound is no better than the best found is skipped.

    roots (r,) node indices; child0/child1 (N,) children (-1 at a leaf);
    leaf_of (N,) the leaf's index into centers/rot/radii (-1 inside);
    blend [m]: see _merge (0: the exact min); outputs as union_phi_grad."""
    N = child0.shape[0]
    stack = np.empty(N + roots.shape[0] + 1, np.int64)
    y = np.empty(3)
    x = np.empty(3)
    for n in range(points.shape[0]):
        best = np.inf
        bk = -1
        g0 = 0.0
        g1 = 0.0
        g2 = 0.0
        top = 0
        for r in range(roots.shape[0]):
            stack[top] = roots[r]
            top += 1
        while top > 0:
            top -= 1
            m = stack[top]
            dx = points[n, 0] - sph_c[m, 0]
            dy = points[n, 1] - sph_c[m, 1]
            dz = points[n, 2] - sph_c[m, 2]
            if np.sqrt(dx * dx + dy * dy + dz * dz) - sph_r[m] >= best + blend:
                continue
            k = leaf_of[m]
            if k < 0:
                # nearer child last, so it is searched first
                a = child0[m]
                b = child1[m]
                da = (
                    (points[n, 0] - sph_c[a, 0]) ** 2
                    + (points[n, 1] - sph_c[a, 1]) ** 2
                    + (points[n, 2] - sph_c[a, 2]) ** 2
                )
                db = (
                    (points[n, 0] - sph_c[b, 0]) ** 2
                    + (points[n, 1] - sph_c[b, 1]) ** 2
                    + (points[n, 2] - sph_c[b, 2]) ** 2
                )
                if da < db:
                    stack[top] = b
                    stack[top + 1] = a
                else:
                    stack[top] = a
                    stack[top + 1] = b
                top += 2
                continue
            for i in range(3):
                y[i] = (
                    rot[k, 0, i] * (points[n, 0] - centers[k, 0])
                    + rot[k, 1, i] * (points[n, 1] - centers[k, 1])
                    + rot[k, 2, i] * (points[n, 2] - centers[k, 2])
                )
            # the affine map to the unit sphere stretches lengths by a_min..a_max,
            # so the signed distance is at least a_min (r - 1) outside, a_max (r - 1) inside
            r = np.sqrt((y[0] / radii[k, 0]) ** 2 + (y[1] / radii[k, 1]) ** 2 + (y[2] / radii[k, 2]) ** 2)
            if r >= 1.0:
                bound = (r - 1.0) * min(radii[k, 0], min(radii[k, 1], radii[k, 2]))
            else:
                bound = (r - 1.0) * max(radii[k, 0], max(radii[k, 1], radii[k, 2]))
            if bound >= best + blend:
                continue
            d = ellipsoid_closest(y, radii[k], x)
            best, g0, g1, g2, took = _merge(best, g0, g1, g2, d, x, k, rot, radii, blend)
            if took:
                bk = k
        phi[n] = best
        grad[n, 0] = g0
        grad[n, 1] = g1
        grad[n, 2] = g2
        which[n] = bk


@njit(cache=True, inline="always")
def _bound(px, py, pz, k, centers, rot, radii, y):
    """Lower bound of ellipsoid k's signed distance at p (a_min (r - 1) outside,
    a_max (r - 1) inside); leaves the local coordinates in y."""
    for i in range(3):
        y[i] = (
            rot[k, 0, i] * (px - centers[k, 0])
            + rot[k, 1, i] * (py - centers[k, 1])
            + rot[k, 2, i] * (pz - centers[k, 2])
        )
    r = np.sqrt((y[0] / radii[k, 0]) ** 2 + (y[1] / radii[k, 1]) ** 2 + (y[2] / radii[k, 2]) ** 2)
    amax = max(radii[k, 0], max(radii[k, 1], radii[k, 2]))
    # and the ball of radius a_max: |p - c| - a_max (tighter far from a flat one)
    ball = np.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]) - amax
    if r >= 1.0:
        return max(ball, (r - 1.0) * min(radii[k, 0], min(radii[k, 1], radii[k, 2])))
    return max(ball, (r - 1.0) * amax)


@njit(cache=True)
def cell_candidates(cell_centers, half_diag, center_phi, centers, rot, radii, blend, keep):
    """keep (n_cells, K) bool: leaf k can be the nearest (lowest signed distance)
    somewhere in the cell: bound_k(c) - h <= min_j phi_j(c) + h (phi is
    1-Lipschitz, so within the cell phi_k >= bound_k(c) - h and the minimum is
    <= its value at the centre + h); + blend, the reach of the smooth min.
    center_phi: the exact min at the centres."""
    y = np.empty(3)
    for c in range(cell_centers.shape[0]):
        lim = center_phi[c] + 2.0 * half_diag + blend
        for k in range(centers.shape[0]):
            keep[c, k] = (
                _bound(cell_centers[c, 0], cell_centers[c, 1], cell_centers[c, 2], k, centers, rot, radii, y) <= lim
            )


@njit(cache=True)
def grid_phi_grad(
    points, origin, cell, shape, cell_start, cell_items, cell_far, centers, rot, radii, blend, phi, grad, which, outside
):
    """union_phi_grad over each point's cell's candidate leaves (cell_items
    [cell_start[c]:cell_start[c+1]]); a point outside the grid, or in a cell
    far from the body (cell_far[c]), is only marked in
    outside (n,) bool for the caller to answer."""
    y = np.empty(3)
    x = np.empty(3)
    for n in range(points.shape[0]):
        ix = int(np.floor((points[n, 0] - origin[0]) / cell))
        iy = int(np.floor((points[n, 1] - origin[1]) / cell))
        iz = int(np.floor((points[n, 2] - origin[2]) / cell))
        if ix < 0 or iy < 0 or iz < 0 or ix >= shape[0] or iy >= shape[1] or iz >= shape[2]:
            outside[n] = True
            continue
        c = (ix * shape[1] + iy) * shape[2] + iz
        if cell_far[c]:
            outside[n] = True
            continue
        outside[n] = False
        best = np.inf
        bk = -1
        g0 = 0.0
        g1 = 0.0
        g2 = 0.0
        for j in range(cell_start[c], cell_start[c + 1]):
            k = cell_items[j]
            if _bound(points[n, 0], points[n, 1], points[n, 2], k, centers, rot, radii, y) >= best + blend:
                continue
            d = ellipsoid_closest(y, radii[k], x)
            best, g0, g1, g2, took = _merge(best, g0, g1, g2, d, x, k, rot, radii, blend)
            if took:
                bk = k
        phi[n] = best
        grad[n, 0] = g0
        grad[n, 1] = g1
        grad[n, 2] = g2
        which[n] = bk

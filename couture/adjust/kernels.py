"""Numba kernels of pattern adjustment: exact closest points on triangles."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _closest_on_triangle(p, a, b, c):
    """Closest point to p on triangle abc (Ericson, Real-Time Collision Detection 5.1.5)."""
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = ab @ ap
    d2 = ac @ ap
    if d1 <= 0.0 and d2 <= 0.0:
        return a.copy()
    bp = p - b
    d3 = ab @ bp
    d4 = ac @ bp
    if d3 >= 0.0 and d4 <= d3:
        return b.copy()
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return a + v * ab
    cp = p - c
    d5 = ab @ cp
    d6 = ac @ cp
    if d6 >= 0.0 and d5 <= d6:
        return c.copy()
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return a + w * ac
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return b + w * (c - b)
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return a + ab * v + ac * w


@njit(cache=True)
def closest_points_candidates(points, cand, V, F, out_points, out_dist, out_face):
    """For each point i, the closest point on the candidate faces ``cand[i]``
    (rows of F into V): writes the point, its distance and the face."""
    for i in range(points.shape[0]):
        p = points[i]
        best = np.inf
        for j in range(cand.shape[1]):
            f = cand[i, j]
            q = _closest_on_triangle(p, V[F[f, 0]], V[F[f, 1]], V[F[f, 2]])
            d = np.sqrt(((q - p) ** 2).sum())
            if d < best:
                best = d
                out_points[i] = q
                out_face[i] = f
        out_dist[i] = best

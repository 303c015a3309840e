"""Numba kernels of pattern adjustment: exact closest points on triangles
(Ericson's point-triangle test, shared with the body distance in couture.cloth.kernels)."""

from __future__ import annotations

import numpy as np
from numba import njit

from couture.cloth.kernels import _closest_on_triangle


@njit(cache=True)
def closest_points_candidates(points, cand, V, F, out_points, out_dist, out_face):
    """For each point i, the closest point on the candidate faces ``cand[i]``
    (rows of F into V): writes the point, its distance and the face."""
    for i in range(points.shape[0]):
        p = points[i]
        best = np.inf
        q = np.empty(3)
        for j in range(cand.shape[1]):
            f = cand[i, j]
            _closest_on_triangle(p, V[F[f, 0]], V[F[f, 1]], V[F[f, 2]], q)
            d = np.sqrt(((q - p) ** 2).sum())
            if d < best:
                best = d
                out_points[i] = q
                out_face[i] = f
        out_dist[i] = best

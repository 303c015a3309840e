"""Curves, fixed-count sampling and polygon predicates (numpy only)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Curve:
    """A line (2 points) or a cubic Bézier (4 points), in metres."""

    pts: np.ndarray

    def eval(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, float)[:, None]
        P = self.pts
        if len(P) == 2:
            return (1 - t) * P[0] + t * P[1]
        s = 1 - t
        return s**3 * P[0] + 3 * s * s * t * P[1] + 3 * s * t * t * P[2] + t**3 * P[3]

    def deriv(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, float)[:, None]
        P = self.pts
        if len(P) == 2:
            return np.broadcast_to(P[1] - P[0], (len(t), 2)).copy()
        s = 1 - t
        return 3 * s * s * (P[1] - P[0]) + 6 * s * t * (P[2] - P[1]) + 3 * t * t * (P[3] - P[2])

    def length(self, n: int = 64) -> float:
        p = self.eval(np.linspace(0, 1, n + 1))
        return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def line(a, b) -> Curve:
    return Curve(np.array([a, b], float))


def bezier(a, b, c, d) -> Curve:
    return Curve(np.array([a, b, c, d], float))


def polyline_length(P: np.ndarray, closed: bool = False) -> float:
    Q = np.vstack([P, P[:1]]) if closed else P
    return float(np.linalg.norm(np.diff(Q, axis=0), axis=1).sum())


def signed_area(P: np.ndarray) -> float:
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def outward_normals(T: np.ndarray) -> np.ndarray:
    """Outward unit normals of a CCW boundary from its tangents (right of travel)."""
    n = np.stack([T[:, 1], -T[:, 0]], axis=1)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def point_in_polygon(pts: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Even-odd rule, vectorized; pts (m, 2), poly (k, 2) -> bool (m,)."""
    x, y = pts[:, 0:1], pts[:, 1:2]
    a, b = poly, np.roll(poly, -1, axis=0)
    cond = (a[None, :, 1] > y) != (b[None, :, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = a[None, :, 0] + (y - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / (b[None, :, 1] - a[None, :, 1])
    return (np.count_nonzero(cond & (x < xi), axis=1) % 2) == 1


def _box_pairs(A: np.ndarray, B: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i < j) of the edges A[i] -> B[i] whose bounding boxes
    overlap (grown by ``margin``): a sweep along x (edges sorted by their
    left end; each pairs with those starting within its x-extent), then the
    y-extents. O(k log k + pairs) instead of every pair."""
    k = len(A)
    lo = np.minimum(A, B) - margin
    hi = np.maximum(A, B) + margin
    order = np.argsort(lo[:, 0], kind="stable")
    xs = lo[order, 0]
    end = np.searchsorted(xs, hi[order, 0], side="right")
    start = np.arange(1, k + 1)
    n = np.maximum(end - start, 0)
    if not n.sum():
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    p = np.repeat(np.arange(k), n)
    q = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n) + np.repeat(start, n)
    i, j = order[p], order[q]
    keep = (lo[i, 1] <= hi[j, 1]) & (lo[j, 1] <= hi[i, 1])
    i, j = i[keep], j[keep]
    return np.minimum(i, j), np.maximum(i, j)


def self_intersections(P: np.ndarray, closed: bool = True) -> list[tuple[int, int]]:
    """Pairs (i, j), i < j, sorted, of non-adjacent polyline edges that cross
    (properly, or collinear and overlapping).

    Edge i runs from P[i] to P[i+1] (wrapping when closed). Only edges whose
    bounding boxes overlap are tested (:func:`_box_pairs`), so an imported
    outline of thousands of points costs milliseconds, not every pair.
    """
    P = np.asarray(P, dtype=np.float64)
    A = P
    B = np.roll(P, -1, axis=0) if closed else P[1:]
    if not closed:
        A = P[:-1]
    k = len(A)
    if k < 2:
        return []
    scale = max(float(np.ptp(P, axis=0).max()), 1e-12)
    eps = 1e-12 * scale * scale
    ii, jj = _box_pairs(A, B, 1e-9 * scale)
    gap = jj - ii
    far = (gap > 1) & ~(closed & (gap == k - 1))
    ii, jj = ii[far], jj[far]

    def orient(p, q, r):
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])

    a1, b1, a2, b2 = A[ii], B[ii], A[jj], B[jj]
    d1 = orient(a1, b1, a2)
    d2 = orient(a1, b1, b2)
    d3 = orient(a2, b2, a1)
    d4 = orient(a2, b2, b1)
    cross = (d1 * d2 < -eps) & (d3 * d4 < -eps)
    coll = (np.abs(d1) <= eps) & (np.abs(d2) <= eps)
    if coll.any():
        # collinear edges overlapping along their line
        ea = b1 - a1
        t0 = ((a2 - a1) * ea).sum(-1)
        t1 = ((b2 - a1) * ea).sum(-1)
        L2 = (ea * ea).sum(-1)
        ov = np.maximum(np.minimum(t0, t1), 0) < np.minimum(np.maximum(t0, t1), L2) - eps
        cross |= coll & ov
    hit = np.column_stack([ii[cross], jj[cross]])
    hit = hit[np.lexsort((hit[:, 1], hit[:, 0]))]
    return [(int(a), int(b)) for a, b in hit]


def segments_cross(P: np.ndarray, Q: np.ndarray) -> bool:
    """Whether any edge of closed polyline P crosses any edge of closed polyline Q."""
    R = np.vstack([P, Q])
    # edges of the concatenation that join P to Q are excluded by testing pairs across
    k = len(P)
    A1, B1 = P, np.roll(P, -1, axis=0)
    A2, B2 = Q, np.roll(Q, -1, axis=0)

    def orient(p, q, r):
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])

    del R, k
    a1, b1 = A1[:, None], B1[:, None]
    a2, b2 = A2[None], B2[None]
    return bool(np.any((orient(a1, b1, a2) * orient(a1, b1, b2) < 0) & (orient(a2, b2, a1) * orient(a2, b2, b1) < 0)))

"""``couture.pattern.geometry.self_intersections`` tests only the edge pairs
whose bounding boxes overlap; it finds exactly what testing every pair finds
(a brute force written here), on random and degenerate polylines."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from couture.pattern.geometry import self_intersections


def brute_force(P: np.ndarray, closed: bool = True) -> list[tuple[int, int]]:
    A = P if closed else P[:-1]
    B = np.roll(P, -1, axis=0) if closed else P[1:]
    k = len(A)
    scale = max(float(np.ptp(P, axis=0).max()), 1e-12)
    eps = 1e-12 * scale * scale

    def orient(p, q, r):
        return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])

    out = []
    for i in range(k):
        for j in range(i + 2, k):
            if closed and j - i == k - 1:
                continue
            d1, d2 = orient(A[i], B[i], A[j]), orient(A[i], B[i], B[j])
            d3, d4 = orient(A[j], B[j], A[i]), orient(A[j], B[j], B[i])
            hit = d1 * d2 < -eps and d3 * d4 < -eps
            if abs(d1) <= eps and abs(d2) <= eps:
                e = B[i] - A[i]
                t0, t1, L2 = (A[j] - A[i]) @ e, (B[j] - A[i]) @ e, e @ e
                hit |= max(min(t0, t1), 0) < min(max(t0, t1), L2) - eps
            if hit:
                out.append((i, j))
    return out


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    k=st.integers(3, 40),
    grid=st.sampled_from([0, 3, 5]),
    closed=st.booleans(),
)
def test_same_pairs_as_every_pair(seed, k, grid, closed):
    """Random polylines, some on a coarse integer grid (collinear overlaps,
    shared points, edges touching end to end)."""
    rng = np.random.default_rng(seed)
    P = rng.integers(0, grid, size=(k, 2)).astype(float) if grid else rng.normal(size=(k, 2))
    assert self_intersections(P, closed=closed) == brute_force(P, closed=closed)


@pytest.mark.parametrize("n", [200, 4000])
def test_a_fine_circle_has_none_and_a_figure_eight_one(n):
    """A many-point outline, as FreeSewing's curves come: a circle has no
    crossing; a figure eight has exactly one, between its two lobes."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    circle = np.column_stack([np.cos(t), np.sin(t)])
    assert self_intersections(circle) == []
    eight = np.column_stack([np.sin(t), np.sin(t) * np.cos(t)])
    hits = self_intersections(eight + 1e-3 * np.column_stack([np.zeros(n), np.cos(t)]))
    assert len(hits) == 1
    if n == 200:
        assert hits == brute_force(eight + 1e-3 * np.column_stack([np.zeros(n), np.cos(t)]))

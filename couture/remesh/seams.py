"""Seam springs between mesh boundaries (SC §7, "emitting" and "receiving" vertices).

For each :class:`~couture.pattern.drafted.SeamSpec` both segments (on a
panel's outline, or on a hole: the two sides of a diamond dart) are walked
by arc length in the rest pattern, normalized to [0, 1] (so unequal lengths
map proportionally: the longer side gathers or pleats), with segment b
walked backwards when ``reverse``. Every mesh vertex of the *emitting* side
gets one zero-length spring to the point at the same normalized arc length on
the *receiving* side's boundary polyline: edge (a, b) and weight w.

Which side emits: the one with more mesh vertices. Emitting from one side
only is deliberate. Springs from both sides would demand that each side's
vertices lie on the other side's polyline, which allows the sewn curve to
bend only where both sides have a vertex: a seam that locks into straight
pieces whenever the two discretizations differ. One-sided, the sewn curve
bends at every receiver vertex, and emitting from the denser side leaves no
receiver edge without a spring (no gaps for the other panel to slip through).
Receiver endpoints are pinned too: the first and last emitters land exactly
on the receiver segment's end vertices.

Double springs are dropped: a spring from a vertex onto itself (the tip of
a dart, where both legs meet) and a repeated (emitter, receiving vertex)
pair (a corner shared by two seams that both land on the same vertex).
"""

from __future__ import annotations

import numpy as np

from couture.pattern.drafted import DraftedPattern, Panel

_SNAP = 1e-9  # receiver weights this close to 0 or 1 are the edge's end vertex


def _segment(panel: Panel, name: str):
    for s in panel.segments:
        if s.name == name:
            return s
    raise KeyError(f"panel {panel.name!r} has no segment {name!r}; it has {[s.name for s in panel.segments]}")


def segment_chain(result, panel_index: int, panel: Panel, seg_name: str) -> np.ndarray:
    """Mesh vertices along a segment, from its start polyline vertex to its stop
    vertex (wrapping), inserted boundary points included, shape (c,), int32.

    An outline segment walks the panel's outline loop; a hole segment
    (``Segment.hole = h``, the sides of a diamond dart) walks the loop of
    hole h (``BoundaryLoop.loop = h + 1``), in the hole's drafted (clockwise)
    order."""
    seg = _segment(panel, seg_name)
    li = seg.hole + 1
    loop = next((lp for lp in result.loops if lp.panel == panel_index and lp.loop == li), None)
    if loop is None:
        raise KeyError(f"segment {panel.name}/{seg_name} lies on loop {li}, which the mesh does not have")
    k = loop.n_poly
    start, stop = seg.start % k, seg.stop % k
    if start == stop:
        raise ValueError(f"segment {panel.name}/{seg_name} is empty (start == stop)")
    for v in (start, stop):
        if loop.poly_to_mesh[v] < 0:
            raise ValueError(f"segment {panel.name}/{seg_name}: end vertex {v} was not kept in the mesh")
    c = len(loop.chain)
    j0 = int(np.flatnonzero((loop.chain_edge == start) & (loop.chain_t == 0.0))[0])
    j1 = int(np.flatnonzero((loop.chain_edge == stop) & (loop.chain_t == 0.0))[0])
    n = (j1 - j0) % c + 1
    return loop.chain[(j0 + np.arange(n)) % c]


def _arc(X: np.ndarray, chain: np.ndarray) -> np.ndarray:
    d = np.diff(X[chain], axis=0)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(d[:, 0], d[:, 1]))])
    if s[-1] <= 0:
        raise ValueError("seam segment has zero length")
    return s / s[-1]


def match_chains(X: np.ndarray, emit_chain: np.ndarray, recv_chain: np.ndarray):
    """Emitter vertex -> receiver edge (a, b) and weight w at equal normalized arc length."""
    ue = _arc(X, emit_chain)
    ur = _arc(X, recv_chain)
    j = np.clip(np.searchsorted(ur, ue, side="right") - 1, 0, len(ur) - 2)
    w = (ue - ur[j]) / np.maximum(ur[j + 1] - ur[j], 1e-300)
    w = np.clip(w, 0.0, 1.0)
    w[w < _SNAP] = 0.0
    w[w > 1.0 - _SNAP] = 1.0
    edges = np.column_stack([recv_chain[j], recv_chain[j + 1]])
    return emit_chain.astype(np.int32), edges.astype(np.int32), w


def seam_springs(drafted: DraftedPattern, result):
    """All seam springs of a drafted pattern on a mesh.

    Returns (emitters (k,) int32, receiving edges (k, 2) int32, weights (k,)
    float64, seam index of each spring (k,) int32).
    """
    X = result.mesh.X
    names = [p.name for p in drafted.panels]
    E, R, W, S = [], [], [], []
    seen: set[tuple[int, int]] = set()
    for si, seam in enumerate(drafted.seams):
        ia, ib = names.index(seam.a_panel), names.index(seam.b_panel)
        ca = segment_chain(result, ia, drafted.panels[ia], seam.a_segment)
        cb = segment_chain(result, ib, drafted.panels[ib], seam.b_segment)
        if seam.reverse:
            cb = cb[::-1]
        emit, recv = (ca, cb) if len(ca) >= len(cb) else (cb, ca)
        e, edges, w = match_chains(X, emit, recv)
        for v, (a, b), wi in zip(e.tolist(), edges.tolist(), w.tolist(), strict=True):
            target = a if wi == 0.0 else (b if wi == 1.0 else -1)
            if target == v:
                continue  # dart tip sewn to itself
            if target >= 0:
                if (v, target) in seen:
                    continue
                seen.add((v, target))
            E.append(v)
            R.append((a, b))
            W.append(wi)
            S.append(si)
    return (
        np.asarray(E, np.int32),
        np.asarray(R, np.int32).reshape(-1, 2),
        np.asarray(W, np.float64),
        np.asarray(S, np.int32),
    )

"""Drafted pattern -> quality constrained-Delaunay garment mesh (SC §6, §7).

Every panel is meshed on its own by Shewchuk's ``triangle`` ('pq30a<area>'),
with one maximum triangle area shared by all panels so the element size is
uniform over the garment, and the panels are merged into one
:class:`~couture.mesh.GarmentMesh`. Polyline vertices of the drafted outlines
and holes become mesh vertices at exactly their drafted positions (never
moved); polyline edges longer than the target spacing are subdivided first
(so the boundary spacing matches the interior) and ``triangle`` may split
boundary edges further to meet the angle bound (no 'Y': a sharp dart tip
would otherwise force slivers). Every boundary mesh vertex therefore lies on
one polyline edge at a known parameter, which is all Ψ needs: an edit's
motion on the boundary is the linear interpolation of the polyline Jacobian.

One exception, for the coarse level: when the drafted polyline is much
denser than the target spacing (``couture.pattern`` drafts at 1 cm, a
1.6k-vertex garment has about 3 cm spacing), keeping every polyline vertex
would blow the vertex budget and grade the mesh badly, so only a subset is
kept: every segment end and every corner, and otherwise vertices about one
spacing apart; the boundary edges are then chords between kept vertices and
Ψ interpolates J linearly along them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import triangle as tr

from couture.mesh import GarmentMesh
from couture.pattern.drafted import DraftedPattern, Panel

LEVEL_TARGETS = {"coarse": 1600, "fine": 10000}
"""default vertex counts of the two cascadic levels for a whole garment (SC Table 1)"""

# triangle's 'q30a<A>' meshes have about 0.8 interior vertices per bound
# area A (measured on the four slopers at 1.6k and 10k vertices: 0.71..0.82)
_INTERIOR_PER_AREA = 0.8
_COUNT_TOLERANCE = 0.07  # re-mesh once with a corrected bound beyond this relative miss
_FLAT_GAP = 0.05  # [m] between panels laid out flat when a panel has no placement


@dataclass
class BoundaryLoop:
    """One drafted polyline loop (outline or hole) of a panel, as it lies in the mesh.

    ``chain`` walks the loop in drafted order from its first kept polyline
    vertex, with the inserted points in between; mesh vertex ``chain[j]`` sits
    at ``(1 - chain_t[j]) * P[chain_edge[j]] + chain_t[j] * P[chain_next[j]]``
    of the drafted polyline P (k vertices); polyline vertices have t = 0.
    With every polyline vertex kept (the default whenever the polyline is not
    much denser than the mesh) ``chain_next = chain_edge + 1 (mod k)``; a
    coarse mesh of a dense polyline keeps a subset (segment ends and corners
    always) and its boundary edges are chords between kept vertices.
    """

    panel: int
    """panel index (into ``GarmentMesh.panel_names``)"""
    loop: int
    """0: outline; j + 1: hole j"""
    poly_to_mesh: np.ndarray
    """mesh vertex of each polyline vertex, shape (k,), int32; -1 for a vertex not kept"""
    chain: np.ndarray
    """mesh vertices along the loop, shape (c,), int32, c >= k"""
    chain_edge: np.ndarray
    """polyline edge index i (edge from vertex i to i + 1 mod k) of each chain vertex, shape (c,), int32"""
    chain_t: np.ndarray
    """parameter on that edge in [0, 1), shape (c,), float64"""
    chain_next: np.ndarray
    """polyline vertex at the other end of that edge (the next kept vertex), shape (c,), int32"""

    @property
    def n_poly(self) -> int:
        return len(self.poly_to_mesh)


@dataclass
class RemeshResult:
    """A garment mesh and where the drafted pattern lies in it."""

    mesh: GarmentMesh
    loops: list[BoundaryLoop]
    """every outline and hole of every panel, panel by panel, outline first"""
    panel_vertices: list[np.ndarray]
    """mesh vertices of each panel, shape (n_p,), int32 (panels are disjoint in the mesh)"""
    vertex_panel: np.ndarray
    """panel index of each mesh vertex, shape (n,), int32"""
    seam_names: list[tuple[str, str, str, str]] = field(default_factory=list)
    """(a_panel, a_segment, b_panel, b_segment) of each SeamSpec, in drafted order"""
    seam_of_spring: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    """index into ``seam_names`` of each seam spring, shape (k,), int32"""
    timings: dict[str, float] = field(default_factory=dict)
    """wall times of the stages [s]"""

    def panel_loops(self, panel: int) -> list[BoundaryLoop]:
        return [lp for lp in self.loops if lp.panel == panel]

    def boundary_vertices(self) -> np.ndarray:
        """All boundary mesh vertices, loop by loop in chain order, shape (b,), int32."""
        return np.concatenate([lp.chain for lp in self.loops]).astype(np.int32)

    def polyline_offsets(self) -> dict[tuple[int, int], int]:
        """Offset of each (panel, loop) in the stacked polyline vertex vector."""
        off, out = 0, {}
        for lp in self.loops:
            out[(lp.panel, lp.loop)] = off
            off += lp.n_poly
        return out

    def boundary_matrix(self) -> sp.csr_matrix:
        """Linear map from stacked polyline values (all loops, drafted order) to
        boundary mesh vertices (``boundary_vertices()`` order), shape (b, k_total).

        Row j holds (1 - t) at the polyline edge's start and t at its end.
        """
        rows, cols, vals = [], [], []
        row0 = col0 = 0
        for lp in self.loops:
            c, k = len(lp.chain), lp.n_poly
            r = row0 + np.arange(c)
            i0 = col0 + lp.chain_edge
            i1 = col0 + lp.chain_next
            rows += [r, r]
            cols += [i0, i1]
            vals += [1.0 - lp.chain_t, lp.chain_t]
            row0 += c
            col0 += k
        m = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(row0, col0))
        m.eliminate_zeros()
        return m

    def stack_polylines(self, drafted: DraftedPattern) -> np.ndarray:
        """Drafted outline and hole vertices stacked in ``loops`` order, shape (k_total, 2)."""
        parts = []
        for lp in self.loops:
            panel = drafted.panel(self.mesh.panel_names[lp.panel])
            parts.append(panel.outline if lp.loop == 0 else panel.holes[lp.loop - 1])
        return np.concatenate(parts).astype(np.float64)


def target_spacing(total_area: float, target_vertices: int) -> float:
    """Edge length [m] of an equilateral mesh with ``target_vertices`` over ``total_area`` [m²]."""
    return float(np.sqrt(2.0 * total_area / (np.sqrt(3.0) * max(target_vertices, 3))))


def polygon_area(P: np.ndarray) -> float:
    """Signed area [m²] of a closed polyline (positive counter-clockwise)."""
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def panel_area(panel: Panel) -> float:
    return abs(polygon_area(panel.outline)) - sum(abs(polygon_area(h)) for h in panel.holes)


_CORNER_ANGLE = np.deg2rad(15.0)  # polyline turns sharper than this are always kept


def _kept_vertices(P: np.ndarray, h: float, must: np.ndarray) -> np.ndarray:
    """Indices of the polyline vertices a mesh of spacing h keeps.

    All of them unless the polyline is much denser than h; then a subset
    about h apart by arc length, always including ``must`` (segment ends) and
    corners, so seams and darts stay exact.
    """
    k = len(P)
    d = np.roll(P, -1, axis=0) - P
    length = np.hypot(d[:, 0], d[:, 1])
    if np.median(length) >= 0.5 * h or k < 8:
        return np.arange(k)
    din = np.roll(d, 1, axis=0)
    turn = np.abs(np.arctan2(din[:, 0] * d[:, 1] - din[:, 1] * d[:, 0], (din * d).sum(axis=1)))
    fixed = np.zeros(k, bool)
    fixed[turn > _CORNER_ANGLE] = True
    fixed[np.asarray(must, np.int64) % k] = True
    if not fixed.any():
        fixed[0] = True
    start = int(np.flatnonzero(fixed)[0])
    keep = np.zeros(k, bool)
    keep[start] = True
    acc = 0.0
    for j in range(1, k + 1):
        i = (start + j) % k
        acc += length[(i - 1) % k]
        if i == start:
            break
        # keep at spacing h; drop a free vertex too close to the next fixed one
        nxt = length[i]
        if fixed[i] or (acc >= 0.8 * h and not (fixed[(i + 1) % k] and nxt < 0.4 * h)):
            keep[i] = True
            acc = 0.0
    return np.flatnonzero(keep)


def _subdivide_loop(P: np.ndarray, h: float, kept: np.ndarray):
    """Chords between kept polyline vertices split to spacing h.

    Returns points, their chord's start and end polyline vertex, and t."""
    A = P[kept]
    d = np.roll(A, -1, axis=0) - A
    length = np.hypot(d[:, 0], d[:, 1])
    m = np.maximum(1, np.ceil(length / h - 1e-9).astype(np.int64))
    chord = np.repeat(np.arange(len(kept)), m)
    start = np.repeat(np.cumsum(m) - m, m)
    t = (np.arange(len(chord)) - start) / np.repeat(m, m)
    pts = A[chord] + t[:, None] * d[chord]
    pts[t == 0] = A[chord[t == 0]]  # bit-exact drafted positions
    return pts, kept[chord].astype(np.int32), np.roll(kept, -1)[chord].astype(np.int32), t


def _point_inside(loop: np.ndarray) -> np.ndarray:
    """A point strictly inside a simple polygon (for triangle's hole seeds)."""
    k = len(loop)
    out = tr.triangulate({"vertices": loop, "segments": np.column_stack([np.arange(k), (np.arange(k) + 1) % k])}, "pQ")
    t = out["triangles"]
    V = out["vertices"]
    e1 = V[t[:, 1]] - V[t[:, 0]]
    e2 = V[t[:, 2]] - V[t[:, 0]]
    area = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    return V[t[np.argmax(area)]].mean(axis=0)


def _segment_ends(panel: Panel, loop: int) -> np.ndarray:
    """Polyline vertices that must stay mesh vertices on loop ``loop`` (0: the
    outline, h + 1: hole h): the ends of the segments lying on it (seams start
    and stop exactly there)."""
    ends = [v for s in panel.segments if s.hole == loop - 1 for v in (s.start, s.stop)]
    return np.asarray(ends, np.int64)


def _triangulate_panel(panel: Panel, h: float, area_bound: float, hole_seeds: list[np.ndarray]):
    """Mesh one panel. Returns (V, tris, per-loop (chain_vertex, edge, next, t) in output indices)."""
    loops = [np.asarray(panel.outline, np.float64)] + [np.asarray(hh, np.float64) for hh in panel.holes]
    pts, segs, seg_loop_parts, seg_edge_parts, seg_next_parts, seg_t0_parts = [], [], [], [], [], []
    off = 0
    for li, P in enumerate(loops):
        kept = _kept_vertices(P, h, _segment_ends(panel, li))
        q, e, nx, t = _subdivide_loop(P, h, kept)
        c = len(q)
        pts.append(q)
        segs.append(off + np.column_stack([np.arange(c), (np.arange(c) + 1) % c]))
        seg_loop_parts.append(np.full(c, li))
        seg_edge_parts.append(e)
        seg_next_parts.append(nx)
        seg_t0_parts.append(t)
        off += c
    V_in = np.concatenate(pts)
    n_in = len(V_in)
    S = np.concatenate(segs)
    seg_loop = np.concatenate(seg_loop_parts)
    seg_edge = np.concatenate(seg_edge_parts)
    seg_next = np.concatenate(seg_next_parts)
    seg_t0 = np.concatenate(seg_t0_parts)
    data = {
        "vertices": V_in,
        "segments": S,
        # markers are 1-based: triangle uses 0 for "not on a segment"
        "segment_markers": np.arange(1, len(S) + 1, dtype=np.int32)[:, None],
    }
    if hole_seeds:
        data["holes"] = np.asarray(hole_seeds)
    out = tr.triangulate(data, f"pq30a{area_bound:.17f}Q")
    V = out["vertices"]
    T = out["triangles"].astype(np.int32)
    if len(V) >= n_in and not np.array_equal(V[:n_in], V_in):
        raise RuntimeError("triangle moved or merged drafted boundary vertices (duplicate polyline points?)")

    # every output subsegment carries the marker of the input segment it came from
    osegs = out["segments"]
    omark = out["segment_markers"].ravel() - 1
    loops_out = []
    for li, P in enumerate(loops):
        sel = np.flatnonzero(seg_loop[omark] == li)
        # collect the (unique) vertices on each input segment with their position along the loop
        verts = np.concatenate([osegs[sel, 0], osegs[sel, 1]])
        iseg = np.concatenate([omark[sel], omark[sel]])
        key = {}
        for v, s in zip(verts.tolist(), iseg.tolist(), strict=True):
            if v < n_in:
                # an input vertex: it starts input segment v (segments are v -> v+1 within a loop)
                s = v
                e, nx, t = int(seg_edge[s]), int(seg_next[s]), float(seg_t0[s])
            else:
                e, nx = int(seg_edge[s]), int(seg_next[s])
                a, b = P[e], P[nx]
                d = b - a
                t = float(np.dot(V[v] - a, d) / np.dot(d, d))
                t = min(max(t, 0.0), 1.0 - 1e-15)
            key[v] = (e, t, nx)
        order = sorted(key.items(), key=lambda kv: kv[1][:2])
        chain_v = np.array([v for v, _ in order], np.int32)
        chain_e = np.array([et[0] for _, et in order], np.int32)
        chain_t = np.array([et[1] for _, et in order], np.float64)
        chain_n = np.array([et[2] for _, et in order], np.int32)
        loops_out.append((chain_v, chain_e, chain_t, chain_n))
    return V, T, loops_out


def _orient_ccw(X: np.ndarray, T: np.ndarray) -> np.ndarray:
    e1 = X[T[:, 1]] - X[T[:, 0]]
    e2 = X[T[:, 2]] - X[T[:, 0]]
    cw = (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) < 0
    T = T.copy()
    T[cw] = T[cw][:, [0, 2, 1]]
    return T


def _mesh_panels(drafted: DraftedPattern, h: float, area_bound: float, hole_seeds):
    return [_triangulate_panel(p, h, area_bound, hole_seeds[i]) for i, p in enumerate(drafted.panels)]


def _place(drafted: DraftedPattern, X: np.ndarray, vertex_panel: np.ndarray) -> np.ndarray:
    """Initial 3D positions: the pattern engineer's placement, else flat and side by side."""
    x0 = np.zeros((len(X), 3))
    shift = 0.0
    for pi, panel in enumerate(drafted.panels):
        idx = np.flatnonzero(vertex_panel == pi)
        P = X[idx]
        if panel.placement is not None:
            from couture.pattern.placement import place  # lazy: the pattern package is optional here

            x0[idx] = place(panel, P)
        else:
            lo, hi = panel.outline[:, 0].min(), panel.outline[:, 0].max()
            x0[idx, 0] = P[:, 0] - lo + shift
            x0[idx, 1] = P[:, 1]
            shift += (hi - lo) + _FLAT_GAP
    return x0


def mesh_pattern(
    drafted: DraftedPattern, target_vertices: int, *, level: str = "fine", generation: int = 0
) -> RemeshResult:
    """Mesh every panel of a drafted pattern and sew the seams (SC §6, §7).

    ``target_vertices`` is for the whole garment; the result lands within
    about ±10 % of it unless the drafted polylines alone are denser than that
    (all their vertices are kept). Triangles are counter-clockwise in X.
    """
    import time

    from couture.remesh.seams import seam_springs

    t_start = time.perf_counter()
    if not drafted.panels:
        raise ValueError("mesh_pattern: the drafted pattern has no panels")
    for p in drafted.panels:
        # Ψ and the seam walk rely on the contract's orientation: domain on the left
        if polygon_area(p.outline) <= 0:
            raise ValueError(f"mesh_pattern: panel {p.name!r}: outline must be counter-clockwise")
        if any(polygon_area(hh) >= 0 for hh in p.holes):
            raise ValueError(f"mesh_pattern: panel {p.name!r}: holes must be clockwise")
    total_area = sum(panel_area(p) for p in drafted.panels)
    h = target_spacing(total_area, target_vertices)
    hole_seeds = [[_point_inside(np.asarray(hh, np.float64)) for hh in p.holes] for p in drafted.panels]

    # interior vertices ≈ _INTERIOR_PER_AREA · A / area_bound (measured on the
    # slopers and fixtures); the boundary count is known before triangulating
    nb_est = 0
    for p in drafted.panels:
        for li, P in enumerate([p.outline] + list(p.holes)):
            P = np.asarray(P, np.float64)
            nb_est += len(_subdivide_loop(P, h, _kept_vertices(P, h, _segment_ends(p, li)))[0])
    want_interior = max(target_vertices - nb_est, 0.25 * target_vertices)
    area_bound = _INTERIOR_PER_AREA * total_area / want_interior
    parts = _mesh_panels(drafted, h, area_bound, hole_seeds)
    n = sum(len(V) for V, _, _ in parts)
    if abs(n - target_vertices) > _COUNT_TOLERANCE * target_vertices:
        # interior count scales as 1/area bound; boundary vertices are fixed by h
        nb = sum(sum(len(c[0]) for c in lo) for _, _, lo in parts)
        want_interior = max(target_vertices - nb, 0.25 * target_vertices)
        area_bound *= max(n - nb, 1) / want_interior
        parts = _mesh_panels(drafted, h, area_bound, hole_seeds)
    t_tri = time.perf_counter()

    Xs, Ts, tri_panel_parts, loops, panel_vertices, vertex_panel_parts = [], [], [], [], [], []
    off = 0
    for pi, (V, T, lo) in enumerate(parts):
        used = np.zeros(len(V), bool)
        used[T.ravel()] = True
        remap = np.full(len(V), -1, np.int64)
        remap[used] = off + np.arange(used.sum())
        Xp = V[used]
        Tp = remap[T]
        Xs.append(Xp)
        Ts.append(Tp)
        tri_panel_parts.append(np.full(len(T), pi, np.int32))
        panel_vertices.append(np.arange(off, off + len(Xp), dtype=np.int32))
        vertex_panel_parts.append(np.full(len(Xp), pi, np.int32))
        for li, (cv, ce, ct, cn) in enumerate(lo):
            cm = remap[cv]
            if (cm < 0).any():
                raise RuntimeError(f"panel {drafted.panels[pi].name!r}: a boundary vertex is in no triangle")
            k = len(drafted.panels[pi].outline) if li == 0 else len(drafted.panels[pi].holes[li - 1])
            is_poly = ct == 0.0
            poly_to_mesh = np.full(k, -1, np.int64)
            poly_to_mesh[ce[is_poly]] = cm[is_poly]
            loops.append(BoundaryLoop(pi, li, poly_to_mesh.astype(np.int32), cm.astype(np.int32), ce, ct, cn))
        off += len(Xp)
    X = np.concatenate(Xs)
    tris = _orient_ccw(X, np.concatenate(Ts))
    vertex_panel = np.concatenate(vertex_panel_parts)
    tri_panel = np.concatenate(tri_panel_parts)
    x0 = _place(drafted, X, vertex_panel)
    mesh = GarmentMesh(
        X=X,
        tris=tris,
        x0=x0,
        tri_panel=tri_panel,
        panel_names=[p.name for p in drafted.panels],
        panel_grain=np.array([p.grain for p in drafted.panels], dtype=np.float64),
        level=level,
        generation=generation,
    )
    result = RemeshResult(mesh=mesh, loops=loops, panel_vertices=panel_vertices, vertex_panel=vertex_panel)
    t_place = time.perf_counter()
    emit, edges, w, which = seam_springs(drafted, result)
    mesh.seam_emitters = emit
    mesh.seam_edges = edges
    mesh.seam_weights = w
    result.seam_of_spring = which
    result.seam_names = [(s.a_panel, s.a_segment, s.b_panel, s.b_segment) for s in drafted.seams]
    t_end = time.perf_counter()
    result.timings = {
        "triangulate": t_tri - t_start,
        "assemble_place": t_place - t_tri,
        "seams": t_end - t_place,
        "total": t_end - t_start,
    }
    return result

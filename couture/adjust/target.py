"""Target garments for direct 3D edits (Bartle et al. 2016 §3), on the source drape's mesh.

Both edits keep the mesh (vertices, triangles, panels, seams): the target is a
new position per vertex, so the pattern found for it is a new rest shape of
the same :class:`~couture.mesh.GarmentMesh`.

Hem (length) edit, :func:`hem_edit`. The hem loop slides up along the
garment by ``|dh|`` (world height, y up) and the garment below a fixed top
part is *cut*, not squashed: every vertex below ``y_fix`` slides up along
the source drape's own surface to a height that maps [y_hem, y_fix] linearly
onto [y_hem + |dh|, y_fix]. The target therefore lies on the source surface
(its fit, normals and flare are the source's: the garment cut 15 cm shorter),
only the mesh is redistributed over the part that remains. ``y_fix`` leaves
the top ``keep`` fraction of the garment's height exactly in place (the
waist and hip fit). Lengthening (dh > 0) is the same map the other way,
[y_hem, y_fix] onto [y_hem - dh, y_fix], on the source surface *continued*
below its hem: a ribbon from each hem edge (the openings below ``y_fix``)
straight along the drape's own downward direction there, so a flared skirt
gets longer along its flare (an A-line stays an A-line), a straight one
straight down; the hem may not pass the floor.

Fit edit, :func:`waist_edit`. The loop at the mannequin's waist height (or,
where an opening crosses that height, as a skirt's waistline does, the cloth
just below it, :func:`loop_height`) is offset away from the body (radially from the torso axis) by the distance
that grows its girth (convex-hull perimeter of the garment's section, what
a tape reads) by ``dg``; the offset fades smoothly (raised cosine) to zero
at ``band`` above and below, so the bust, shoulders and hem stay fixed.
A space deformation: two coincident points (a closed seam) move alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from couture.pattern.mannequin import TORSO_AXIS_Z, WAIST_Y

from .geometry import SurfaceDistance


@dataclass
class Target:
    x: np.ndarray
    """target positions [m], shape (n, 3)"""
    edit: str
    """'hem' or 'waist'"""
    amount: float
    """[m] asked: hem rise (negative: shorter) or girth change"""
    achieved: float
    """[m] measured on the target: mean rise of the hem's lowest vertices (negated) or girth change"""
    info: dict


def opening_edges(mesh) -> np.ndarray:
    """Boundary edges (a, b) of a garment mesh that no seam closes: its
    openings (waist, hem, neckline, armholes). An edge counts as sewn when
    both its ends are seam vertices (emitters or receiving edges' ends)."""
    from .seams import boundary_edges

    sewn = np.zeros(mesh.n_vertices, bool)
    sewn[mesh.seam_emitters] = True
    sewn[mesh.seam_edges.ravel()] = True
    E = boundary_edges(mesh.tris)
    return E[~(sewn[E[:, 0]] & sewn[E[:, 1]])]


def hem_loop(openings: np.ndarray, y: np.ndarray, sewn: np.ndarray | None = None, reach: float = 0.15) -> np.ndarray:
    """The vertices of the hem: the opening loops (``openings`` (k, 2) edges
    joined where they share a vertex, and across a seam where ``sewn``
    (m, 2) pairs two of their vertices: a seam's end at the hem sews one
    panel's hem corner to the next one's) whose lowest point is within
    ``reach`` of the garment's height above the lowest opening: a skirt's
    one loop, however uneven; both trouser legs; a shirt's body hem, not its
    short sleeves' cuffs (22 cm higher)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    ends = np.unique(openings)
    if sewn is not None and len(sewn):
        at_opening = np.isin(sewn, ends).all(axis=1)  # a seam's end at the opening, not its run up the seam
        pairs = np.concatenate([openings, sewn[at_opening]])
    else:
        pairs = openings
    n = len(y)
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    y_low = float(y[ends].min())
    low_of = {lab: float(y[ends[label[ends] == lab]].min()) for lab in np.unique(label[ends])}
    hems = [lab for lab, lo in low_of.items() if lo <= y_low + reach * float(y.max() - y_low)]
    return ends[np.isin(label[ends], hems)]


def _down_tangents(x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Per vertex: the unit direction straight down the surface (steepest
    descent of the height in the tangent plane of the area-weighted normal)."""
    n_f = np.cross(x[tris[:, 1]] - x[tris[:, 0]], x[tris[:, 2]] - x[tris[:, 0]])
    n = np.zeros_like(x)
    for k in range(3):
        np.add.at(n, tris[:, k], n_f)
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-15)[:, None]
    g = np.array([0.0, -1.0, 0.0]) + n[:, 1:2] * n  # -e_y minus its normal part
    return g / np.maximum(np.linalg.norm(g, axis=1), 1e-15)[:, None]


def _hem_extension(
    x: np.ndarray, tris: np.ndarray, hem: np.ndarray, drop: float, *, row: float = 0.02, min_slope: float = 0.3
) -> tuple[np.ndarray, np.ndarray]:
    """The surface ``(x, tris)`` continued below its hem edges ``hem`` (k, 2):
    a ribbon, row by row, each hem vertex extended straight along the
    drape's own downward direction there (its flare), far enough to reach
    ``drop`` [m] lower. Returns (vertices, triangles)."""
    d = _down_tangents(x, tris)
    v = np.unique(hem)
    dv = d[v]
    if (-dv[:, 1] < min_slope).mean() > 0.25:
        raise ValueError(
            "hem edit: the drape runs nearly horizontally at its hem (a quarter of the hem slopes less than "
            f"{np.degrees(np.arcsin(min_slope)):.0f} degrees): it cannot be continued downward along itself"
        )
    # steeper than min_slope everywhere, so every ribbon reaches the depth
    dv[:, 1] = np.minimum(dv[:, 1], -min_slope)
    dv /= np.linalg.norm(dv, axis=1)[:, None]
    length = 1.5 * drop / min_slope + 2 * row
    rows = max(2, int(np.ceil(length / row)))
    at = np.full(len(x), -1, np.int64)
    at[v] = np.arange(len(v))
    V = np.concatenate([x] + [x[v] + (r * length / rows) * dv for r in range(1, rows + 1)])
    idx = lambda r, i: i if r == 0 else len(x) + (r - 1) * len(v) + at[i]  # noqa: E731
    F = [tris]
    for r in range(rows):
        a0, b0 = idx(r, hem[:, 0]), idx(r, hem[:, 1])
        a1, b1 = idx(r + 1, hem[:, 0]), idx(r + 1, hem[:, 1])
        F.append(np.column_stack([a0, b0, b1]))
        F.append(np.column_stack([a0, b1, a1]))
    return V, np.concatenate(F)


def hem_edit(
    x_src: np.ndarray,
    tris: np.ndarray,
    dh: float,
    *,
    keep: float = 0.35,
    slide_steps: int = 12,
    openings: np.ndarray | None = None,
    vertex_panel: np.ndarray | None = None,
    sewn: np.ndarray | None = None,
) -> Target:
    """Shorten (dh < 0) or lengthen (dh > 0) a draped garment by ``|dh|``
    [m], see the module docstring. Lengthening continues the drape below its
    hem: ``openings`` (:func:`opening_edges`; default every boundary edge)
    name the edges it may grow from, those below the fixed top part.

    With ``vertex_panel`` (each vertex's panel) only the *hem's* panels
    change: those the hem loop runs through (:func:`hem_loop`: the opening
    through the lowest point, followed across the seams ``sewn`` closes; a
    shirt's front and back, not its short sleeves, whose cuffs are loops of
    their own; every gore of a skirt, however uneven its hem), and the fixed
    top part reaches down to the lowest point of every other panel, so a seam
    between a hem panel and another one (an armhole) stays closed."""
    if not (np.isfinite(dh) and dh != 0):
        raise ValueError(f"hem edit: dh = {dh!r} m; give a non-zero length change (negative: shorter)")
    y = x_src[:, 1]
    y_top, y_hem = float(y.max()), float(y.min())
    length = y_top - y_hem
    y_fix = y_top - keep * length
    moving = np.ones(len(y), bool)
    if vertex_panel is not None:
        if openings is None:
            from .seams import boundary_edges

            openings = boundary_edges(tris)
        loop = hem_loop(np.asarray(openings), y, sewn)
        hem_panels = np.unique(vertex_panel[loop])
        moving = np.isin(vertex_panel, hem_panels)
        if (~moving).any():
            y_fix = min(y_fix, float(y[~moving].min()))
    if -dh >= y_fix - y_hem:
        raise ValueError(
            f"hem edit: shortening by {-dh:.3f} m leaves nothing below the fixed top part "
            f"(the garment's {y_fix - y_hem:.3f} m below y = {y_fix:.3f} m may change: its top "
            f"{keep:.0%} and every panel without the hem stay)"
        )
    if dh > 0:
        from couture.pattern.mannequin import FLOOR_Y

        if y_hem - dh < FLOOR_Y:
            raise ValueError(
                f"hem edit: lengthening by {dh:.3f} m puts the hem {y_hem - dh - FLOOR_Y:+.3f} m "
                "from the floor: below it"
            )
        if openings is None:
            from .seams import boundary_edges

            openings = boundary_edges(tris)
        openings = np.asarray(openings)
        hem = openings[(y[openings] < y_fix).all(axis=1) & moving[openings].all(axis=1)]
        if not len(hem):
            raise ValueError("hem edit: the garment has no open edge below its fixed top part to lengthen from")
    own = moving[tris].all(axis=1)  # slide on the hem's panels only, never onto a sleeve
    own_tris = tris[own] if own.any() else tris
    if dh > 0:
        surf = SurfaceDistance(*_hem_extension(x_src, own_tris, hem, dh))
    else:
        surf = SurfaceDistance(x_src, own_tris)
    below = (y < y_fix) & moving
    y_new = y.copy()
    s = (y_fix - y[below]) / (y_fix - y_hem)  # 0 at y_fix, 1 at the lowest point
    y_new[below] = y_fix - s * (y_fix - y_hem + dh)
    x = x_src.copy()
    idx = np.nonzero(below)[0]
    p = x[idx].copy()
    y0 = y[idx]
    # slide in small steps, each projected back onto the (continued) source
    # surface (a path along the cloth, not a jump across a fold), then settle at the height
    for k in range(1, slide_steps + 6):
        yk = y0 + (y_new[idx] - y0) * min(1.0, k / slide_steps)
        q = p.copy()
        q[:, 1] += yk - p[:, 1]
        p, _, _ = surf.closest(q)
    x[idx] = p
    low = y <= y_hem + 0.02 * length
    achieved = float((x[low, 1] - y[low]).mean())
    return Target(
        x=x,
        edit="hem",
        amount=dh,
        achieved=-achieved,
        info={
            "y_top": y_top,
            "y_hem": y_hem,
            "y_fix": y_fix,
            "keep": keep,
            "hem_rise_mean": achieved,
            "height_error_max": float(np.abs(x[idx, 1] - y_new[idx]).max()),
        },
    )


def section_girth(x: np.ndarray, tris: np.ndarray, y0: float) -> float:
    """Tape-measure girth [m] of a garment at height y0: the perimeter of the
    convex hull (in x-z) of where its edges cross the plane y = y0."""
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    ya, yb = x[e[:, 0], 1] - y0, x[e[:, 1], 1] - y0
    cross = (ya * yb < 0) | (ya == 0)
    a, b = e[cross, 0], e[cross, 1]
    t = (ya[cross] / np.where(ya[cross] == yb[cross], 1.0, ya[cross] - yb[cross]))[:, None]
    P = (x[a] + t * (x[b] - x[a]))[:, [0, 2]]
    if len(P) < 3:
        raise ValueError(f"the garment does not go round at height y = {y0:.3f} m")
    return _hull_perimeter(P)


def _hull_perimeter(P: np.ndarray) -> float:
    from scipy.spatial import ConvexHull

    loop = P[ConvexHull(P).vertices]
    return float(np.linalg.norm(loop - np.roll(loop, 1, axis=0), axis=1).sum())


def _radial_offset(x: np.ndarray, d: float, y0: float, band: float) -> np.ndarray:
    r = x[:, [0, 2]] - np.array([0.0, TORSO_AXIS_Z])
    rn = np.linalg.norm(r, axis=1)
    u = r / np.maximum(rn, 1e-9)[:, None]
    s = np.abs(x[:, 1] - y0) / band
    fade = np.where(s < 1.0, 0.5 * (1.0 + np.cos(np.pi * np.minimum(s, 1.0))), 0.0)
    out = x.copy()
    out[:, 0] += d * fade * u[:, 0]
    out[:, 2] += d * fade * u[:, 1]
    return out


TORSO_SPAN = np.radians(40.0)
"""[rad] a piece of a waist loop counts as the torso's when it goes this far
round the torso axis (a panel of an 8-gore skirt: 45 degrees; a sleeve
hanging beside the body at that height: about 25)"""


def loop_height(x: np.ndarray, openings: np.ndarray, y: float, *, margin: float = 0.01, reach: float = 0.15) -> float:
    """``y``, or where the garment ``x`` goes all the way round nearest below
    it: a plane that crosses an opening (``openings`` (k, 2) edges, e.g. a
    skirt's waistline, which sags and rises around the body) cuts no whole
    loop of cloth, so the loop moves below the openings it meets, by
    ``margin`` more. Raises ValueError beyond ``reach`` below ``y``."""
    openings = np.asarray(openings).reshape(-1, 2)
    lo = np.minimum(x[openings[:, 0], 1], x[openings[:, 1], 1])
    hi = np.maximum(x[openings[:, 0], 1], x[openings[:, 1], 1])

    def crossing(h: float) -> np.ndarray:
        return (lo <= h) & (hi >= h)

    h, moved = float(y), False
    while crossing(h).any():
        h = float(lo[crossing(h)].min()) - 1e-4
        moved = True
        if h < y - reach:
            raise ValueError(
                f"the garment has an opening at every height from y = {y:.3f} m to {reach:.2f} m below: "
                "no loop of cloth goes round there"
            )
    if moved:
        h -= margin
        while crossing(h).any():
            h = float(lo[crossing(h)].min()) - 1e-4 - margin
    return h


def waist_edit(
    x_src: np.ndarray,
    tris: np.ndarray,
    dg: float,
    *,
    y_loop: float = WAIST_Y,
    band: float = 0.12,
    openings: np.ndarray | None = None,
) -> Target:
    """Loosen (dg > 0) or tighten a draped garment's girth at ``y_loop`` by
    ``dg`` [m], see the module docstring. With ``openings``
    (:func:`opening_edges`) the loop moves below an opening it would cut
    (:func:`loop_height`: a skirt's waist is its top edge; its loop is the
    cloth just below)."""
    if not (np.isfinite(dg) and dg != 0):
        raise ValueError(f"waist edit: dg = {dg!r} m; give a non-zero girth change (negative: tighter)")
    y_asked = float(y_loop)
    if openings is not None:
        y_loop = loop_height(x_src, openings, y_loop)
    loop = material_loop(x_src, tris, y_loop, min_span=TORSO_SPAN)
    g0 = loop.girth(x_src)
    d = dg / (2 * np.pi)
    for _ in range(4):  # secant on the measured girth (the hull is not exactly a circle)
        g = loop.girth(_radial_offset(x_src, d, y_loop, band)) - g0
        if abs(g - dg) < 1e-5:
            break
        d *= dg / g if g != 0 else 1.0
    x = _radial_offset(x_src, d, y_loop, band)
    return Target(
        x=x,
        edit="waist",
        amount=dg,
        achieved=loop.girth(x) - g0,
        info={"girth_source": g0, "offset": d, "y_loop": y_loop, "y_asked": y_asked, "band": band},
    )


def waist_room(x_src: np.ndarray, tris: np.ndarray, y_loop: float, body, offset: float) -> float:
    """[m] how much the drape's girth at ``y_loop`` can shrink before its
    cloth meets the body: each point of the loop moved in (radially, as the
    edit moves it) until it is ``offset`` (the solver's contact layer) from
    the ``body`` (anything with ``phi_grad``). A pattern tighter than that
    only stretches the cloth over the body; its drape's girth stays."""
    loop = material_loop(x_src, tris, y_loop, min_span=TORSO_SPAN)
    P = loop.points(x_src)
    r = P[:, [0, 2]] - np.array([0.0, TORSO_AXIS_Z])
    rn = np.linalg.norm(r, axis=1)
    u = r / np.maximum(rn, 1e-9)[:, None]
    # march each point in along its ray (2 mm steps, never past the axis) to
    # where the body is first within `offset`: a loose garment's flank may be
    # far from the skin along the ray though the torso's side is near
    steps = np.linspace(0.0, 1.0, 1 + int(np.ceil(rn.max() / 0.002)))
    s = rn[:, None] * steps[None, :]  # (k, m) distances moved in
    Q3 = np.repeat(P[:, None, :], len(steps), axis=1)
    Q3[..., 0] -= s * u[:, None, 0]
    Q3[..., 2] -= s * u[:, None, 1]
    phi, _ = body.phi_grad(Q3.reshape(-1, 3))
    hit = phi.reshape(s.shape) <= offset
    first = np.where(hit.any(axis=1), hit.argmax(axis=1), len(steps) - 1)
    rows = np.arange(len(P))
    hi = s[rows, first]  # within `offset` (or the axis)
    lo = s[rows, np.maximum(first - 1, 0)]  # clear of it
    for _ in range(40):  # bisect to where phi = offset along the ray
        mid = 0.5 * (lo + hi)
        M = P.copy()
        M[:, 0] -= mid * u[:, 0]
        M[:, 2] -= mid * u[:, 1]
        inside = body.phi_grad(M)[0] <= offset
        hi, lo = np.where(inside, mid, hi), np.where(inside, lo, mid)
    s_in = np.where(hit.any(axis=1), lo, rn)
    Q = r - s_in[:, None] * u
    return max(0.0, _hull_perimeter(P[:, [0, 2]]) - _hull_perimeter(Q))


@dataclass
class MaterialLoop:
    """A curve of cloth: where a drape crossed the plane y = y0, held as
    material points (``(1 - t) X[i0] + t X[i1]`` on mesh edges), one segment
    per crossed triangle. Its length can be read in any configuration of the
    same mesh: the drape's (3D) or a pattern's (2D rest positions, the cloth
    along the loop: darts and gaps between panels are not counted)."""

    i0: np.ndarray
    """(k,) first vertex of the edge each point lies on"""
    i1: np.ndarray
    """(k,) second vertex"""
    t: np.ndarray
    """(k,) where on the edge (0: at i0)"""
    seg: np.ndarray
    """(m, 2) the two points of each crossed triangle's segment"""
    y0: float

    def points(self, X: np.ndarray) -> np.ndarray:
        return X[self.i0] + self.t[:, None] * (X[self.i1] - X[self.i0])

    def length(self, X: np.ndarray) -> float:
        """[m] the loop's length in configuration X (n, 2 or 3)."""
        P = self.points(np.asarray(X, np.float64))
        return float(np.linalg.norm(P[self.seg[:, 1]] - P[self.seg[:, 0]], axis=1).sum())

    def girth(self, x: np.ndarray) -> float:
        """[m] tape-measure girth of the loop in drape ``x``: the perimeter of
        the convex hull (in x-z) of its points (:func:`section_girth` of the
        drape it was cut from, for any later drape of the same mesh)."""
        return _hull_perimeter(self.points(np.asarray(x, np.float64))[:, [0, 2]])

    def gradient(self, X: np.ndarray) -> np.ndarray:
        """d length / d X, shape of X."""
        X = np.asarray(X, np.float64)
        P = self.points(X)
        d = P[self.seg[:, 1]] - P[self.seg[:, 0]]
        u = d / np.maximum(np.linalg.norm(d, axis=1), 1e-15)[:, None]
        gP = np.zeros_like(P)  # d length / d point
        np.add.at(gP, self.seg[:, 1], u)
        np.add.at(gP, self.seg[:, 0], -u)
        g = np.zeros_like(X)
        np.add.at(g, self.i0, (1.0 - self.t)[:, None] * gP)
        np.add.at(g, self.i1, self.t[:, None] * gP)
        return g


def material_loop(x: np.ndarray, tris: np.ndarray, y0: float, *, min_span: float = 0.0) -> MaterialLoop:
    """The cloth of drape ``x`` at height ``y0`` (see :class:`MaterialLoop`).
    A vertex exactly at ``y0`` counts as above it. ``min_span`` > 0 [rad]:
    only the pieces that go that far round the torso axis (the torso's cloth,
    not a sleeve beside it)."""
    x = np.asarray(x, np.float64)
    above = x[:, 1] >= y0
    tris = np.asarray(tris)
    cut = above[tris].any(axis=1) & ~above[tris].all(axis=1)
    if not cut.any():
        raise ValueError(f"the garment does not reach height y = {y0:.3f} m: no loop there")
    key: dict[tuple[int, int], int] = {}
    i0: list[int] = []
    i1: list[int] = []
    t: list[float] = []
    seg: list[list[int]] = []
    for tri in tris[cut]:
        ends = []
        for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
            if above[a] == above[b]:
                continue
            a, b = (int(a), int(b)) if a < b else (int(b), int(a))
            k = key.get((a, b))
            if k is None:
                k = key[(a, b)] = len(i0)
                ya, yb = x[a, 1] - y0, x[b, 1] - y0
                i0.append(a)
                i1.append(b)
                t.append(ya / (ya - yb))
            ends.append(k)
        seg.append(ends)
    loop = MaterialLoop(np.array(i0), np.array(i1), np.array(t, np.float64), np.array(seg, np.int64), float(y0))
    return _around_torso(loop, x, min_span) if min_span > 0 else loop


def _around_torso(loop: MaterialLoop, x: np.ndarray, min_span: float) -> MaterialLoop:
    """Only the pieces of ``loop`` (connected runs of segments) that go some
    way round the torso axis (an angle of at least ``min_span`` [rad] seen
    from it): a sleeve hanging at that height crosses the plane too, as a
    small ring beside the body, and is no part of the garment's girth."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    k = len(loop.t)
    g = coo_matrix((np.ones(len(loop.seg)), (loop.seg[:, 0], loop.seg[:, 1])), shape=(k, k))
    _, comp = connected_components(g, directed=False)
    P = loop.points(x)
    ang = np.arctan2(P[:, 0], P[:, 2] - TORSO_AXIS_Z)
    keep = np.zeros(k, bool)
    for c in np.unique(comp):
        a = np.sort(ang[comp == c])
        gaps = np.diff(np.concatenate([a, a[:1] + 2 * np.pi]))
        if 2 * np.pi - gaps.max() >= min_span:
            keep[comp == c] = True
    if not keep.any():
        raise ValueError(f"no cloth goes round the body at y = {loop.y0:.3f} m")
    new = np.cumsum(keep) - 1
    seg = loop.seg[keep[loop.seg[:, 0]]]
    return MaterialLoop(loop.i0[keep], loop.i1[keep], loop.t[keep], new[seg], loop.y0)

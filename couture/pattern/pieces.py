"""Free-form pieces (``schemas.design.Piece``: imported patterns) as drafted
panels: the outline as given, its segments between corners (``e0``, ``e1``,
...), and the rings that place them round the body. ``couture.pattern.draft``
adds them to the sloper's panels, so that validation, the remesher, the
solvers and the exports treat them like any other panel."""

from __future__ import annotations

import numpy as np

from couture.pattern import mannequin as M
from couture.pattern.drafted import Panel, Placement, Segment, segment_points
from couture.pattern.errors import PatternError
from couture.pattern.geometry import signed_area
from couture.pattern.slopers.base import Ring
from schemas.design import Design, Piece, Stroke

FLAT_Z = 0.45
"""[m] a 'flat' piece lies in the plane z = FLAT_Z, in front of the body"""


def segment_name(i: int) -> str:
    return f"e{i}"


def _array(piece: Piece, pts, what: str) -> np.ndarray:
    try:
        P = np.asarray(pts, float).reshape(-1, 2)
    except (TypeError, ValueError):
        raise PatternError(piece.name, f"{what} is not a list of [x, y] points") from None
    if not np.all(np.isfinite(P)):
        raise PatternError(piece.name, f"{what} has NaN/inf coordinates")
    return P


def piece_panel(piece: Piece) -> Panel:
    """The panel of one free-form piece (placement left to the rings)."""
    if not piece.name:
        raise PatternError("pieces", "a piece has no name")
    P = _array(piece, piece.outline, "outline")
    k = len(P)
    if k < 3:
        raise PatternError(piece.name, f"outline has {k} vertices (at least 3)")
    if signed_area(P) <= 0:
        raise PatternError(piece.name, "outline is not counter-clockwise (or has no area)")
    holes = [_array(piece, h, f"hole {i}") for i, h in enumerate(piece.holes)]
    corners = list(piece.corners) or [0]
    if any(not (0 <= c < k) for c in corners) or any(b <= a for a, b in zip(corners, corners[1:], strict=False)):
        raise PatternError(piece.name, f"corners {corners} are not increasing outline indices in [0, {k})")
    segments = []
    for i, c in enumerate(corners):
        stop = corners[(i + 1) % len(corners)]
        segments.append(Segment(segment_name(i), c, stop % k))
    return Panel(piece.name, P, holes, segments, grain=piece.grain)


def segment_span(k: int, start: int, stop: int) -> np.ndarray:
    """Outline indices of a piece segment from ``start`` to ``stop`` (both
    included, wrapping; ``start == stop``: the whole outline round)."""
    n = (stop - start) % k or k
    return (start + np.arange(n + 1)) % k


class PolylineSeg:
    """A piece segment (a polyline from corner to corner) as a map u in
    [0, 1] -> R^2, u its arc-length fraction, with the interface of
    ``couture.pattern.draft.SegEval`` that curve strokes and their edit frames
    use: a curve stroke displaces its vertices along the normal by the
    stroke's spline at their u (the corners, u = 0 and 1, stay put), so the
    vertex count never changes."""

    def __init__(self, P: np.ndarray):
        self.P = np.asarray(P, float)
        d = np.linalg.norm(np.diff(self.P, axis=0), axis=1)
        total = float(d.sum())
        if total <= 0:
            raise PatternError("pieces", "a segment has zero length")
        self.u = np.concatenate([[0.0], np.cumsum(d)]) / total
        self.n = len(self.P) - 1
        # vertex tangents dX/du (central differences, one-sided at the ends): smooth enough for a frame
        self._T = np.gradient(self.P, self.u, axis=0) if len(self.P) > 2 else np.tile(self.P[1] - self.P[0], (2, 1))
        self.disp = None

    def _interp(self, V: np.ndarray, u) -> np.ndarray:
        u = np.clip(np.atleast_1d(np.asarray(u, float)), 0.0, 1.0)
        return np.column_stack([np.interp(u, self.u, V[:, 0]), np.interp(u, self.u, V[:, 1])])

    def base(self, u) -> np.ndarray:
        return self._interp(self.P, u)

    def tangent(self, u) -> np.ndarray:
        return self._interp(self._T, u)

    def normal(self, u) -> np.ndarray:
        T = self.tangent(u)
        n = np.stack([T[:, 1], -T[:, 0]], axis=1)
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)

    def eval(self, u) -> np.ndarray:
        u = np.atleast_1d(np.asarray(u, float))
        P = self.base(u)
        if self.disp is not None:
            P = P + self.disp(u)[:, None] * self.normal(u)
        return P

    def samples(self) -> np.ndarray:
        """The segment's vertices (displaced), shape (n + 1, 2), both corners included."""
        return self.eval(self.u)

    def length(self) -> float:
        return float(np.linalg.norm(np.diff(self.samples(), axis=0), axis=1).sum())


def piece_segments(panel: Panel) -> dict[str, PolylineSeg]:
    """The segments of a piece's panel as curve-stroke carriers, by name."""
    k = len(panel.outline)
    return {s.name: PolylineSeg(panel.outline[segment_span(k, s.start, s.stop)]) for s in panel.segments}


def apply_piece_curves(panel: Panel, segs: dict[str, PolylineSeg]) -> None:
    """Move the vertices of the panel's curved segments (those whose
    ``disp`` a curve stroke set) onto their displaced positions, in place."""
    k = len(panel.outline)
    for s in panel.segments:
        seg = segs.get(s.name)
        if seg is not None and seg.disp is not None:
            idx = segment_span(k, s.start, s.stop)
            panel.outline[idx[1:-1]] = seg.samples()[1:-1]


def point_weights(piece: Piece, i: int, element: str) -> tuple[np.ndarray, np.ndarray]:
    """(indices, weights) of the outline points that follow a move of point
    ``i`` (``pt:<piece>:<i>``): the point itself (weight 1) and every point
    between it and the nearest corner on either side, by its arc-length
    fraction toward that corner (1 at ``i``, 0 at the corner): the two
    segments next to a corner stretch to it, keeping their shape's
    character (a straight edge stays straight, a curve stays a curve), and
    every other corner stays put. The weights are those of the piece as given."""
    P = _array(piece, piece.outline, "outline")
    k = len(P)
    if not 0 <= i < k:
        raise PatternError(element, f"piece {piece.name!r} has no outline point {i} (it has {k})")
    others = sorted(set(piece.corners or [0]) - {i})
    if not others:
        raise PatternError(element, f"piece {piece.name!r} has no corner besides point {i} to anchor the move")
    nxt = next((c for c in others if c > i), others[0])
    prv = next((c for c in reversed(others) if c < i), others[-1])
    idx, w = [np.array([i])], [np.array([1.0])]
    for stop, step in ((nxt, 1), (prv, -1)):
        n = ((stop - i) * step) % k
        run = (i + step * np.arange(n + 1)) % k
        d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P[run], axis=0), axis=1))])
        if d[-1] > 0:
            idx.append(run[1:-1])
            w.append(1.0 - d[1:-1] / d[-1])
    return np.concatenate(idx), np.concatenate(w)


def piece_panels(design: Design) -> list[Panel]:
    """Every free-form piece of the design as a panel; a 'flat' piece gets its
    plane placement here, a ringed one from :func:`piece_rings`. A 'Cut 2'
    pair that is not a mirror pair is refused (:func:`check_mirror_pairs`)."""
    check_mirror_pairs(design)
    out = []
    x = -0.5
    for pc in design.pieces:
        p = piece_panel(pc)
        if pc.placement.ring in ("flat", "inside"):  # a facing: flat until laid inside its piece
            lo, hi = p.outline.min(0), p.outline.max(0)
            p.placement = Placement(
                "plane",
                np.array([x - lo[0], pc.placement.height - hi[1], FLAT_Z]),
                u=np.array([1.0, 0.0, 0.0]),
                v=np.array([0.0, 1.0, 0.0]),
            )
            x += hi[0] - lo[0] + 0.05
        out.append(p)
    return out


SLEEVE_DOWN = 0.03
"""[m] a sleeve's top lies this far down its arm's placement axis from the arm
root point (clear of the shoulder, as the shirt sloper's sleeves)"""
LEG_MARGIN = 0.02
"""[m] clearance of a trouser leg's ring (as the trousers sloper's)"""


def leg_frame(leg: str, height: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """A leg's placement frame: (axis point at world height ``height`` [m],
    unit axis up the leg, unit front direction across it, the angle [rad] of
    the leg's inner side, where its ring stays open)."""
    sign = 1.0 if leg == "left" else -1.0
    a = M.LEFT_LEG_AXIS * np.array([sign, 1.0, 1.0])
    a = a / np.linalg.norm(a)
    top = M.LEFT_LEG_TOP * np.array([sign, 1.0, 1.0])
    origin = top + a * ((height - top[1]) / a[1])
    f = np.array([0.0, 0.0, 1.0]) - a[2] * a
    f /= np.linalg.norm(f)
    b = np.cross(a, f)
    inner = np.array([-sign, 0.0, 0.0])
    return origin, a, f, float(np.arctan2(inner @ b, inner @ f))


def arm_front_at_plus_x(arm: str) -> bool:
    """Whether a sleeve on ``arm`` ('left' or 'right') has its material +x
    half (theta > 0 from the top of the arm) toward the body's front."""
    from couture.pattern.slopers.shirt import _arm_frame

    a, f = _arm_frame(1.0 if arm == "left" else -1.0)
    return bool(np.cross(a, f)[2] > 0)


ARMPIT_CLEAR = 0.003
"""[m] a top's sides and straps start at least this far from the body's
surface, its arms and shoulders included (``couture.pattern.slopers.base.Ring.armpit_clear``)"""
NECK_MARGIN = 0.01
"""[m] clearance of a collar's ring round the neck"""
POINT_MARGIN = 0.015
"""[m] default clearance of a piece laid at an arrangement point"""
POINT_REACH = 0.04
"""[m] a piece at an arrangement point clears the body's sections this far
above and below each of its rows (``Ring.section_reach``): one piece alone
cannot lean on its neighbours' girth, so a table row that undercuts the body
would put it inside"""


def point_ring(pc: Piece, body: str = "default") -> Ring:
    """The ring of one piece laid at its arrangement point (``placement.point``,
    :mod:`couture.pattern.landmarks`): wrapped round the body's local axis
    there, its centre (the middle of its height and width) at the point's
    height and angle, ``placement.clearance`` outside the body's section (the
    piece does not shrink it: a narrow piece leaves the rest of the way round
    open)."""
    from couture.pattern.landmarks import arrangement_point
    from couture.pattern.slopers.shirt import _cap_radius

    if not pc.placement.point:
        raise PatternError(pc.name, "placement ring 'point' needs an arrangement point (placement.point)")
    try:
        pt = arrangement_point(body, pc.placement.point)
    except ValueError as e:
        raise PatternError(pc.name, str(e)) from None
    P = _array(pc, pc.outline, "outline")
    yc = 0.5 * float(P[:, 1].min() + P[:, 1].max())
    clear = pc.placement.clearance if pc.placement.clearance is not None else POINT_MARGIN
    arm = pt.section.endswith("_arm")
    return Ring(
        [pc.name],
        [pt.angle],
        pt.origin - yc * pt.axis,
        axis=pt.axis.copy(),
        ref=pt.ref.copy(),
        section=pt.section,
        margin=clear,
        min_margin=clear,
        anchor_y=yc,
        body_radius=_cap_radius if arm else None,
        section_reach=POINT_REACH,
    )


def piece_rings(design: Design, body: str = "default") -> list[Ring]:
    """The rings of the design's ringed pieces, each in ``position`` order: the
    torso ring, its top (material y = 0) at the first piece's ``height`` [m]
    (taken at the default mannequin and moved to the body's own waist), and
    a waistband's ring likewise (its own height, above the torso ring); a
    leg's ring about that leg's axis, from its waist height likewise, open at
    the inner side (the trousers sloper's leg rings); an arm's ring about the
    arm, its top a little down from the shoulder (the shirt sloper's sleeve
    rings); a collar's ring round the neck, its top at the first piece's
    ``height`` on the default body, moved with the body's neck base
    (:func:`couture.pattern.landmarks.neck`); one ring per piece laid at an
    arrangement point (:func:`point_ring`)."""
    from couture.pattern.slopers.shirt import _arm_frame, _cap_radius

    rings: list[Ring] = []
    for pc in design.pieces:
        if pc.placement.ring == "point":
            rings.append(point_ring(pc, body))
    for kind in ("torso", "band", "neck", "left_leg", "right_leg", "left_arm", "right_arm"):
        ringed = sorted((pc for pc in design.pieces if pc.placement.ring == kind), key=lambda pc: pc.placement.position)
        if not ringed:
            continue
        first = ringed[0].placement
        names = [pc.name for pc in ringed]
        angles = [first.angle] + [0.0] * (len(ringed) - 1)
        if kind in ("torso", "band"):
            top = kind == "torso" and first.landmark == "neck"
            rings.append(
                Ring(
                    names,
                    angles,
                    np.array([0.0, first.height, M.TORSO_AXIS_Z]),
                    section="torso",
                    landmark="neck" if top else "waist",
                    top_rows_as_full=True,
                    armpit_clear=ARMPIT_CLEAR if top else None,
                )
            )
        elif kind == "neck":
            # ``height``: the collar's top on the default body; fit_ring moves it with the body's neck base
            clear = first.clearance if first.clearance is not None else NECK_MARGIN
            rings.append(
                Ring(
                    names,
                    angles,
                    np.array([0.0, first.height, M.TORSO_AXIS_Z]),
                    section="torso",
                    landmark="neck",
                    margin=clear,
                    min_margin=min(clear, NECK_MARGIN),
                )
            )
        elif kind.endswith("_leg"):
            leg = kind.split("_")[0]
            origin, a, f, gap = leg_frame(leg, first.height)
            rings.append(
                Ring(
                    names, angles, origin, axis=a, ref=f, margin=LEG_MARGIN, section=kind, gap_at=gap, landmark="waist"
                )
            )
        else:
            sign = 1.0 if kind == "left_arm" else -1.0
            a, f = _arm_frame(sign)
            origin = M.LEFT_ARM_SHOULDER * np.array([sign, 1.0, 1.0]) - SLEEVE_DOWN * a
            rings.append(Ring(names, angles, origin, axis=a, ref=f, body_radius=_cap_radius, section=kind))
    return rings


# ------------------------------------------------------------------ 'Cut 2' pairs

MIRROR = np.array([-1.0, 1.0])
"""a 'Cut 2' twin's point moves by this times the edited piece's point (x mirrored)"""
MIRROR_TOL = 1e-6
"""[m] a pair's outlines are mirror images within this (``check_mirror_pairs``)"""


def mirror_twin(design: Design, piece: Piece) -> tuple[int, Piece] | None:
    """(index in ``design.pieces``, piece) of ``piece``'s 'Cut 2' twin
    (``Piece.mirror_of``), None without one."""
    if not piece.mirror_of:
        return None
    j = next((j for j, pc in enumerate(design.pieces) if pc.name == piece.mirror_of), None)
    if j is None or design.pieces[j] is piece:
        raise PatternError(piece.name, f"mirror_of names no other piece {piece.mirror_of!r}")
    _check_pair(piece, design.pieces[j])
    return j, design.pieces[j]


def twin_points(piece: Piece, idx) -> np.ndarray:
    """The twin's outline indices mirroring ``piece``'s outline indices ``idx``."""
    return (piece.mirror_index - np.asarray(idx, int)) % len(piece.outline)


def _corners(piece: Piece) -> list[int]:
    return list(piece.corners) or [0]


def twin_segment(piece: Piece, twin: Piece, segment: str, element: str = "") -> str:
    """The name of the twin's segment that mirrors ``piece``'s ``segment``
    (it runs the other way: from the mirror of the segment's end to that of its start)."""
    cs = _corners(piece)
    names = [segment_name(i) for i in range(len(cs))]
    if segment not in names:
        raise PatternError(element or piece.name, f"piece {piece.name!r} has no segment {segment!r} (it has {names})")
    i = names.index(segment)
    start, stop = (int(x) for x in twin_points(piece, [cs[(i + 1) % len(cs)], cs[i]]))
    tc = _corners(twin)
    if start not in tc or tc[(tc.index(start) + 1) % len(tc)] != stop:
        raise PatternError(
            element or piece.name,
            f"segment {segment} of {piece.name!r} has no mirror segment on its twin {twin.name!r} (corners differ)",
        )
    return segment_name(tc.index(start))


def mirror_outline(piece: Piece, twin: Piece) -> np.ndarray:
    """The twin's outline as the mirror image of ``piece``'s, (k, 2) [m]: its
    point j at (c - x, y) of point (mirror_index - j) mod k, the axis c the one
    the twin's first point gives now."""
    P = np.asarray(piece.outline, float)
    src = twin_points(piece, np.arange(len(P)))
    c = float(twin.outline[0][0]) + P[src[0], 0]
    Q = P[src] * MIRROR
    Q[:, 0] += c
    return Q


def check_mirror_pairs(design: Design) -> None:
    """Refuse a design whose 'Cut 2' pairs (``Piece.mirror_of``) do not name
    each other or are not mirror images (point count, corners, outline to
    ``MIRROR_TOL``), naming the pieces and the first point off."""
    for pc in design.pieces:
        mirror_twin(design, pc)


def _check_pair(pc: Piece, tw: Piece) -> None:
    """Refuse a pair that does not name each other or is not mirrored (see :func:`check_mirror_pairs`)."""
    if tw.mirror_of != pc.name or tw.mirror_index != pc.mirror_index:
        raise PatternError(
            pc.name,
            f"is marked the mirror of {tw.name!r}, which does not name it back with the same mirror_index "
            f"({tw.mirror_of!r}, {tw.mirror_index} against {pc.mirror_index})",
        )
    k = len(pc.outline)
    if len(tw.outline) != k:
        raise PatternError(pc.name, f"has {k} outline points, its mirror {tw.name!r} {len(tw.outline)}")
    if not 0 <= pc.mirror_index < k:
        raise PatternError(pc.name, f"mirror_index {pc.mirror_index} is not an outline index in [0, {k})")
    if sorted(int(c) for c in twin_points(pc, _corners(pc))) != _corners(tw):
        raise PatternError(pc.name, f"its corners are not the mirror of {tw.name!r}'s")
    gap = np.linalg.norm(mirror_outline(pc, tw) - np.asarray(tw.outline, float), axis=1)
    j = int(np.argmax(gap))
    if gap[j] > MIRROR_TOL:
        raise PatternError(
            pc.name,
            f"point {j} of its mirror {tw.name!r} is {1e3 * gap[j]:.3g} mm off the mirror image of its point "
            f"{int(twin_points(pc, [j])[0])}: a 'Cut 2' pair edits as one (edit one, or drop mirror_of from both)",
        )


def with_mirrored_curve(design: Design, stroke_id: str) -> Design:
    """``design`` with the curve stroke ``stroke_id`` mirrored onto its piece's
    'Cut 2' twin (a stroke on the twin's mirror segment, replaced or added:
    control point i at [s, dn] there is point n-1-i at [1 - s, dn], the
    segment running the other way and its normal still outward); the design
    itself when that piece has no twin."""
    import copy

    st = next((s for s in design.strokes if s.id == stroke_id), None)
    if st is None or st.kind != "curve":
        raise PatternError(stroke_id, "no curve stroke with that id")
    piece = next((pc for pc in design.pieces if pc.name == st.panel), None)
    found = None if piece is None else mirror_twin(design, piece)
    if piece is None or found is None:
        return design
    twin = found[1]
    seg = twin_segment(piece, twin, str(st.params.get("segment")), stroke_id)
    pts = [[1.0 - float(s), float(dn)] for s, dn in reversed(st.params["points"])]
    old = next(
        (s for s in design.strokes if s.kind == "curve" and s.panel == twin.name and s.params.get("segment") == seg),
        None,
    )
    new = Stroke(
        id=old.id if old else f"curve-{twin.name}-{seg}",
        kind="curve",
        panel=twin.name,
        params={"segment": seg, "points": pts},
    )
    d = copy.copy(design)
    d.strokes = [s for s in design.strokes if old is None or s.id != old.id] + [new]
    return d


COLLAR_REACH = 0.02
"""[m] a collar laid on its neckline clears the torso's section this far above each point (the neck leans forward)"""


def _part_map(cm: np.ndarray, op: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One sewn part of a collar: (material x, material y, world position) of
    its neck edge's points ``cm`` (k, 2) on the neckline ``op`` (m, 3) as
    placed, matched by arc-length fraction, material x increasing and the
    neckline's angle about the torso axis increasing with it."""
    if cm[0, 0] > cm[-1, 0]:
        cm = cm[::-1]
    th = np.arctan2(op[:, 0], op[:, 2] - M.TORSO_AXIS_Z)
    if (th[-1] - th[0] + np.pi) % (2 * np.pi) - np.pi < 0:
        op = op[::-1]

    def frac(Q: np.ndarray) -> np.ndarray:
        d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))])
        return d / max(d[-1], 1e-12)

    u, v = frac(cm), frac(op)
    world = np.column_stack([np.interp(u, v, op[:, c]) for c in range(3)])
    return cm[:, 0], cm[:, 1], world


BRIDGE_LIFT = 0.5
"""a collar's bridge between two neckline pieces that start apart (the
front's and the back's neck points, their shoulder seam still open) rises
this fraction of the gap above the straight line (over the shoulder's top)"""


def _bridged(xs: list, ys: list, ws: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sewn parts' (material x, material y, world) points in material x
    order, one position per x: where a part starts away from where the one
    before ended (the neckline pieces' common corner, placed apart until the
    solver sews their seam), the collar's corner stays on the first and a
    few points in the next fraction of a centimetre of cloth arc over to the
    second (``BRIDGE_LIFT``), not through the body between them."""
    parts = sorted(zip(xs, ys, ws, strict=True), key=lambda p: float(p[0][0]))
    X, Y, W = [parts[0][0]], [parts[0][1]], [parts[0][2]]
    for x, y, w in parts[1:]:
        xe, A = float(X[-1][-1]), W[-1][-1]
        B = w[0]
        nxt = x[x > xe + 1e-9]
        if np.linalg.norm(B - A) > 0.01 and len(nxt):
            d = 0.4 * (float(nxt[0]) - xe)
            sb = np.array([0.25, 0.5, 0.75, 1.0])
            arc = (1 - sb)[:, None] * A + sb[:, None] * B
            arc[:, 1] += BRIDGE_LIFT * float(np.linalg.norm(B - A)) * np.sin(np.pi * sb)
            X.append(xe + d * sb)
            Y.append(np.full(len(sb), float(Y[-1][-1])))
            W.append(arc)
        keep = x > float(X[-1][-1]) + 1e-9
        X.append(x[keep])
        Y.append(y[keep])
        W.append(w[keep])
    return np.concatenate(X), np.concatenate(Y), np.concatenate(W)


def collar_placements(
    design: Design, panels: dict[str, Panel], seams: list, body: str = "default"
) -> dict[str, Placement]:
    """'grid' placements of the design's collars (ring 'neck') that are sewn
    to placed panels: the collar's neck edge laid on the neckline as its
    pieces are placed (each sewn part on its segment, by arc-length
    fraction; an unsewn end carried on along the neckline's tangent), the
    collar standing straight up from it, every point above the neck's base
    then pushed out from the torso axis to the collar's clearance outside
    the body's section there (and ``COLLAR_REACH`` above). A neckline lower than the neck (a
    scoop) thus gets its band where it is sewn, not round the neck; a collar
    sewn to nothing keeps its ring round the neck. ``seams``: the drafted
    ``SeamSpec`` list."""
    from couture.pattern.placement import place
    from couture.pattern.sections import sections

    out: dict[str, Placement] = {}
    for pc in design.pieces:
        if pc.placement.ring != "neck" or pc.name not in panels:
            continue
        C = panels[pc.name]
        segs = {g.name: g for g in C.segments}
        xs, ys, ws = [], [], []
        for sp in seams:
            if sp.a_panel == pc.name and sp.b_panel != pc.name:
                mine, other, oseg = sp.a_segment, sp.b_panel, sp.b_segment
            elif sp.b_panel == pc.name and sp.a_panel != pc.name:
                mine, other, oseg = sp.b_segment, sp.a_panel, sp.a_segment
            else:
                continue
            P = panels.get(other)
            if P is None or P.placement is None or P.placement.kind == "plane" or mine not in segs:
                continue
            pseg = next((g for g in P.segments if g.name == oseg), None)
            if pseg is None:
                continue
            x, y, w = _part_map(segment_points(C, segs[mine]), place(P, segment_points(P, pseg)))
            xs.append(x)
            ys.append(y)
            ws.append(w)
        if not xs:
            continue
        x, y, w = _bridged(xs, ys, ws)
        lo, hi = C.outline.min(axis=0), C.outline.max(axis=0)
        gx = np.unique(np.concatenate([np.linspace(lo[0], hi[0], max(2, int(np.ceil((hi[0] - lo[0]) / 0.01)) + 1)), x]))
        bottom = np.column_stack([np.interp(gx, x, w[:, c]) for c in range(3)])
        yb = np.interp(gx, x, y)
        # past the sewn parts (an overlap, an unsewn end): on along the neckline's end tangents
        for end, sel in ((0, gx < x[0]), (-1, gx > x[-1])):
            if sel.any() and len(x) > 1:
                a, b = (0, 1) if end == 0 else (-2, -1)
                t = (w[b] - w[a]) / max(x[b] - x[a], 1e-9)
                t = t / max(np.linalg.norm(t), 1e-12)
                bottom[sel] = w[end] + (gx[sel] - x[end])[:, None] * t
        gy = np.linspace(min(lo[1], yb.min()), hi[1], max(2, int(np.ceil((hi[1] - lo[1]) / 0.01)) + 1))
        G = bottom[None, :, :] + (gy[:, None] - yb[None, :])[:, :, None] * np.array([0.0, 1.0, 0.0])
        # above the neck's base (the neck, leaning forward, and the jaw over it): outside the torso
        # table's section there (and 2 cm higher) by the clearance; below it the collar rises from a
        # neckline already outside the body, on top of the shoulders, whose horizontal sections
        # (the shoulders' hull, the arms beside) say nothing about it
        from couture.pattern.landmarks import neck

        base = neck(body).base_y
        sec = sections(body)["torso"]
        clear = pc.placement.clearance if pc.placement.clearance is not None else NECK_MARGIN
        rel = G - np.array([0.0, 0.0, M.TORSO_AXIS_Z])
        th = np.arctan2(rel[..., 0], rel[..., 2]) % (2 * np.pi)
        r = np.hypot(rel[..., 0], rel[..., 2])
        t_ax = (G[..., 1] - float(sec.origin[1])).ravel()
        K = sec.radius.shape[1]
        R = np.maximum(sec.radii(t_ax), sec.radii(t_ax + COLLAR_REACH))
        k = th.ravel() / (2 * np.pi) * K
        k0 = np.floor(k).astype(int) % K
        f = k - np.floor(k)
        need = ((1 - f) * R[np.arange(len(k)), k0] + f * R[np.arange(len(k)), (k0 + 1) % K]).reshape(r.shape) + clear
        scale = np.where(G[..., 1] > base, np.maximum(need / np.maximum(r, 1e-9), 1.0), 1.0)
        G = np.array([0.0, 0.0, M.TORSO_AXIS_Z]) + rel * np.stack([scale, np.ones_like(scale), scale], axis=-1)
        out[pc.name] = Placement("grid", np.zeros(3), grid_x=gx, grid_y=gy, grid_pos=G)
    return out


FACING_INSET = 0.003
"""[m] a facing lies this much nearer its ring's axis than the piece it faces
(a ring piece keeps at least 7 mm from the body's section: 4 mm are left)"""


def _fit_2d(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The rigid motion (rotation or reflection Q, translation t) taking the
    points A (k, 2) nearest to B (k, 2) in least squares, and its rms residual [m]."""
    ca, cb = A.mean(axis=0), B.mean(axis=0)
    U, _, Vt = np.linalg.svd((A - ca).T @ (B - cb))
    Q = U @ Vt  # reflections allowed: a facing may be drawn mirrored
    t = cb - ca @ Q
    return Q, t, float(np.sqrt(((A @ Q + t - B) ** 2).sum(axis=1).mean()))


def inside_placements(design: Design, panels: dict[str, Panel], seams: list) -> dict[str, Placement]:
    """'grid' placements of the design's facings (ring 'inside'): each laid
    on the piece it is sewn to (the one with the longest seam to it), its
    material mapped into that piece's by the rigid motion (a reflection
    allowed) that best lays its sewn edges on the edges they are sewn to (by
    arc-length fraction), placed as that piece's points there, then moved
    ``placement.clearance`` (default ``FACING_INSET``) toward that piece's
    ring axis. The two layers do not collide with each other in the solvers
    (no cloth-cloth contact). A facing sewn to no wrapped piece lies flat."""
    from couture.pattern.placement import frame, place

    out: dict[str, Placement] = {}
    for pc in design.pieces:
        if pc.placement.ring != "inside" or pc.name not in panels:
            continue
        Fc = panels[pc.name]
        segs = {g.name: g for g in Fc.segments}
        by_other: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
        for sp in seams:
            if sp.a_panel == pc.name and sp.b_panel != pc.name:
                mine, other, oseg = sp.a_segment, sp.b_panel, sp.b_segment
            elif sp.b_panel == pc.name and sp.a_panel != pc.name:
                mine, other, oseg = sp.b_segment, sp.a_panel, sp.a_segment
            else:
                continue
            P = panels.get(other)
            if P is None or P.placement is None or P.placement.kind != "wrap" or mine not in segs:
                continue
            pseg = next((g for g in P.segments if g.name == oseg), None)
            if pseg is not None:
                by_other.setdefault(other, []).append((segment_points(Fc, segs[mine]), segment_points(P, pseg)))
        if not by_other:
            continue

        sewn = {
            o: sum(float(np.linalg.norm(np.diff(b, axis=0), axis=1).sum()) for _, b in v) for o, v in by_other.items()
        }
        other = max(sewn, key=lambda o: sewn[o])
        P = panels[other]
        pl = P.placement
        assert pl is not None, "only placed pieces are faced"
        A_pts, B_pts = [], []
        for a, b in by_other[other]:
            u = np.linspace(0.0, 1.0, 21)

            def at(Q: np.ndarray, u: np.ndarray = u) -> np.ndarray:
                d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))])
                d = d / max(d[-1], 1e-12)
                return np.column_stack([np.interp(u, d, Q[:, 0]), np.interp(u, d, Q[:, 1])])

            A_pts.append(at(a))
            # a seam joins its two segments one way or the other: the one the rigid fit takes better
            fwd, bwd = at(b), at(b[::-1])
            B_pts.append(fwd if _fit_2d(at(a), fwd)[2] <= _fit_2d(at(a), bwd)[2] else bwd)
        Q, t, _ = _fit_2d(np.vstack(A_pts), np.vstack(B_pts))
        lo, hi = Fc.outline.min(axis=0), Fc.outline.max(axis=0)
        gx = np.linspace(lo[0], hi[0], max(2, int(np.ceil((hi[0] - lo[0]) / 0.01)) + 1))
        gy = np.linspace(lo[1], hi[1], max(2, int(np.ceil((hi[1] - lo[1]) / 0.01)) + 1))
        X, Y = np.meshgrid(gx, gy)
        M2 = np.column_stack([X.ravel(), Y.ravel()]) @ Q + t
        W = place(P, M2)
        a, _, _ = frame(pl)
        rel = W - np.asarray(pl.origin, float)
        radial = rel - (rel @ a)[:, None] * a
        inset = pc.placement.clearance if pc.placement.clearance is not None else FACING_INSET
        W = W - inset * radial / np.maximum(np.linalg.norm(radial, axis=1, keepdims=True), 1e-12)
        out[pc.name] = Placement("grid", np.zeros(3), grid_x=gx, grid_y=gy, grid_pos=W.reshape(len(gy), len(gx), 3))
    return out

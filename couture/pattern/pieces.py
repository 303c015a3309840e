"""Free-form pieces (``schemas.design.Piece``: imported patterns) as drafted
panels: the outline as given, its segments between corners (``e0``, ``e1``,
...), and the rings that place them round the body. ``couture.pattern.draft``
adds them to the sloper's panels, so that validation, the remesher, the
solvers and the exports treat them like any other panel."""

from __future__ import annotations

import numpy as np

from couture.pattern import mannequin as M
from couture.pattern.drafted import Panel, Placement, Segment
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
        if pc.placement.ring == "flat":
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


def piece_rings(design: Design, body: str = "default") -> list[Ring]:
    """The rings of the design's ringed pieces, each in ``position`` order: the
    torso ring, its top (material y = 0) at the first piece's ``height`` [m]
    (taken at the default mannequin and moved to the body's own waist), and
    a waistband's ring likewise (its own height, above the torso ring); a
    leg's ring about that leg's axis, from its waist height likewise, open at
    the inner side (the trousers sloper's leg rings); an arm's ring about the
    arm, its top a little down from the shoulder (the shirt sloper's sleeve
    rings)."""
    from couture.pattern.slopers.shirt import _arm_frame, _cap_radius

    rings: list[Ring] = []
    for kind in ("torso", "band", "left_leg", "right_leg", "left_arm", "right_arm"):
        ringed = sorted((pc for pc in design.pieces if pc.placement.ring == kind), key=lambda pc: pc.placement.position)
        if not ringed:
            continue
        first = ringed[0].placement
        names = [pc.name for pc in ringed]
        angles = [first.angle] + [0.0] * (len(ringed) - 1)
        if kind in ("torso", "band"):
            rings.append(
                Ring(
                    names,
                    angles,
                    np.array([0.0, first.height, M.TORSO_AXIS_Z]),
                    section="torso",
                    landmark="waist",
                    top_rows_as_full=True,
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

"""Cutting pieces from a drafted pattern: what a pattern maker cuts from cloth.

For every panel: the cut line (the sew line plus a seam allowance, its width
chosen per seam, deeper on hems), notches where seams must match, drill holes
at dart points, the grain line, and the piece's labels (name, size, how many
to cut). Pure geometry in metres; ``couture.pattern.io`` draws it as DXF
(AAMA/ASTM layers), SVG and PDF.

Conventions:

- Allowance widths belong to outline segments. ``CutSpec.widths`` names a
  segment (``"neck"``) or a panel's segment (``"front:neck"``); a width given
  for one side of a seam is the seam's width, so the other side gets it too
  unless it has its own. Segments named in ``hem_segments`` get
  ``hem_allowance``, every other one ``seam_allowance``.
- The cut line is the union of the sew polygon with, per sew edge, the
  rectangle swept outward by that edge's width and, at each convex corner, the
  mitre wedge between the two offset lines (clipped beyond ``mitre_limit``
  times the larger width). A union is a simple polygon, so the cut line never
  crosses itself; at concave turns the offset rectangles overlap and the union
  keeps their outer boundary.
- A boundary dart is bridged for the cut line (the cloth is cut across the dart
  mouth); its legs stay on the sew line, notches mark the mouth and a drill hole
  the point, ``DART_DRILL_INSET`` short of the apex.
- Notches: on every seam (dart seams excepted) at both seam ends and at the
  fractions k / n of each side's arc length (n even, so the midpoint is one;
  n = 2 ceil(L / (2 notch_spacing)) for the longer side L). Fractions, not
  distances: the two sides of an eased seam (a sleeve cap longer than its
  armhole) are sewn proportionally (``couture.remesh.seams``), so for equal
  lengths the notches sit at the same arc length from the matching seam ends,
  and for eased ones at the same fraction. Side b runs backwards when the seam
  says ``reverse``.
- Grain: ``Panel.grain`` [rad] from material +y (0: straight grain along the
  panel's vertical, as every sloper drafts it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from couture.pattern.draft import segment_points
from couture.pattern.drafted import DraftedPattern, Panel, SeamSpec, Segment
from couture.pattern.errors import PatternError
from couture.pattern.geometry import signed_area

DART_DRILL_INSET = 0.01
"""[m] a dart's drill hole sits this far short of its point (the usual marking)"""
DRILL_RADIUS = 0.0015
"""[m] drawn radius of a drill hole mark"""
MAX_ALLOWANCE = 0.2
"""[m] the widest allowance accepted (a typo such as 10 for 0.01 is an error)"""


@dataclass
class CutSpec:
    """How to turn the drafted sew lines into cutting pieces (SI units)."""

    seam_allowance: float = 0.01
    """[m] default width of the allowance outside the sew line"""
    hem_allowance: float = 0.03
    """[m] width on hem segments (turned up, so deeper)"""
    hem_segments: tuple[str, ...] = ("hem", "cuff")
    """segment names that are hems"""
    widths: dict[str, float] = field(default_factory=dict)
    """per seam widths [m]: ``"segment"`` or ``"panel:segment"`` -> width"""
    notch_spacing: float = 0.25
    """[m] the longest stretch of seam between two notches"""
    notch_depth: float = 0.006
    """[m] notch length into the allowance (never more than 0.6 of its width)"""
    end_notches: bool = True
    """notch both ends of every seam as well"""
    notch_distances: tuple[float, ...] = ()
    """[m] more notches at these arc lengths from each seam's start on side a
    (side b: from its matching end, scaled by its length when eased); an
    asymmetric notch tells the two ends of a seam apart"""
    mitre_limit: float = 4.0
    """a corner's mitre reaches at most this many allowance widths from the sew corner"""
    group: bool = True
    """one piece per set of congruent panels (same shape, or mirrored), with its cut count"""
    design_name: str = ""
    """the design's name on every label ('Style Name: ')"""
    size: str = ""
    """the size on every label ('Size: ')"""
    sheet_width: float = 1.2
    """[m] SVG / PDF sheets (and the DXF's insertion points): pieces in rows no
    wider than this (a plotter roll); 0: all in one row"""


@dataclass
class Notch:
    """A slit notch: from the cut line ``outer`` inward to ``inner`` [m]."""

    outer: np.ndarray
    inner: np.ndarray
    at: np.ndarray
    """the sew-line point the notch marks [m]"""
    seam: int
    """index into ``DraftedPattern.seams``"""
    side: str
    """'a' or 'b'"""
    s: float
    """arc length [m] of ``at`` from the seam's start on this side (b: from its matching end)"""


@dataclass
class CutPiece:
    """One piece to cut, in its panel's material coordinates [m]."""

    panel: Panel
    sew: np.ndarray
    """sew line (the drafted outline), (k, 2), CCW"""
    cut: np.ndarray
    """cut line, (m, 2), CCW, not closed"""
    edge_width: np.ndarray
    """allowance width [m] of each sew edge i (vertex i to i + 1), (k,)"""
    hole_cut: list[np.ndarray | None] = field(default_factory=list)
    """per ``panel.holes`` (their sew lines, CW): the cut line of an opening (the
    hole less the allowance; the sew line itself when too small for it), None
    for an interior (diamond) dart, which is marked and sewn, not cut"""
    notches: list[Notch] = field(default_factory=list)
    drills: list[np.ndarray] = field(default_factory=list)
    grain: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))
    """grain line [m], (2, 2): tail, head (the arrow points along the grain)"""
    symmetry_axis: np.ndarray | None = None
    """(2, 2) the axis of a panel drafted by a symmetry stroke"""
    quantity: int = 1
    mirrored: int = 0
    """how many of ``quantity`` are mirror images"""
    copies: list[str] = field(default_factory=list)
    """names of the other panels this piece stands for"""
    labels: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.panel.name


# ------------------------------------------------------------------ widths


def _check_width(what: str, w: float) -> float:
    w = float(w)
    if not math.isfinite(w) or w < 0 or w > MAX_ALLOWANCE:
        raise PatternError(what, f"allowance {w!r} m is outside [0, {MAX_ALLOWANCE}] m")
    return w


def segment_widths(pattern: DraftedPattern, spec: CutSpec) -> dict[tuple[str, str], float]:
    """(panel, segment) -> allowance width [m] for every outline segment."""
    _check_width("seam_allowance", spec.seam_allowance)
    _check_width("hem_allowance", spec.hem_allowance)
    names = {(p.name, s.name) for p in pattern.panels for s in p.segments}
    seg_names = {s for _, s in names}
    for key, w in spec.widths.items():
        _check_width(f"allowance {key}", w)
        pn, _, sn = key.rpartition(":")
        if (pn and (pn, sn) not in names) or (not pn and sn not in seg_names):
            raise PatternError(
                f"allowance {key}",
                f"no segment {key!r}: segments are {sorted(seg_names)}, on panels {sorted({a for a, _ in names})}",
            )
    explicit: dict[tuple[str, str], float] = {}
    for pn, sn in names:
        if f"{pn}:{sn}" in spec.widths:
            explicit[(pn, sn)] = spec.widths[f"{pn}:{sn}"]
        elif sn in spec.widths:
            explicit[(pn, sn)] = spec.widths[sn]
    for sp in pattern.seams:  # a seam's width on one side is the seam's width
        a, b = (sp.a_panel, sp.a_segment), (sp.b_panel, sp.b_segment)
        if a in explicit and b not in explicit:
            explicit[b] = explicit[a]
        elif b in explicit and a not in explicit:
            explicit[a] = explicit[b]
    out = {}
    for pn, sn in names:
        out[(pn, sn)] = explicit.get((pn, sn), spec.hem_allowance if sn in spec.hem_segments else spec.seam_allowance)
    return out


def _is_dart(seg: Segment) -> bool:
    return seg.name.startswith("dart:")


def _edge_widths(panel: Panel, widths: dict[tuple[str, str], float], default: float) -> np.ndarray:
    k = len(panel.outline)
    w = np.full(k, default)
    # longer segments first, so a segment nested in another (none but darts today) wins
    segs = sorted(
        (s for s in panel.segments if s.hole < 0 and not _is_dart(s)), key=lambda s: -((s.stop - s.start) % k)
    )
    for s in segs:
        n = (s.stop - s.start) % k
        w[(s.start + np.arange(n)) % k] = widths[(panel.name, s.name)]
    return w


# ------------------------------------------------------------------ the cut line


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def offset_polygon(P: np.ndarray, w: np.ndarray, mitre_limit: float = 4.0) -> np.ndarray:
    """The region within the per-edge allowance of the CCW polygon P, as its
    outer boundary: (m, 2), CCW, not closed. ``w[i]`` [m] is the width of
    edge P[i] -> P[i+1]; mitred corners, clipped at ``mitre_limit`` x width."""
    from shapely import Polygon, union_all

    P = np.asarray(P, float)
    k = len(P)
    w = np.broadcast_to(np.asarray(w, float), (k,))
    E = np.roll(P, -1, axis=0) - P
    L = np.linalg.norm(E, axis=1)
    T = _unit(E)
    N = np.stack([T[:, 1], -T[:, 0]], axis=1)  # outward for CCW
    polys = [Polygon(P)]
    for i in range(k):
        if L[i] > 1e-12 and w[i] > 0:
            j = (i + 1) % k
            polys.append(Polygon([P[i], P[j], P[j] + w[i] * N[i], P[i] + w[i] * N[i]]))
    # a wedge at each vertex j between edge i (in) and edge j (out), skipping zero-length edges
    live = np.nonzero(L > 1e-12)[0].tolist()
    for n, j in enumerate(live):
        i = live[n - 1]
        wi, wj = w[i], w[j]
        if max(wi, wj) <= 0:
            continue
        cross = T[i, 0] * T[j, 1] - T[i, 1] * T[j, 0]
        V = P[j]
        A, B = V + wi * N[i], V + wj * N[j]
        if cross <= 1e-9:
            # straight or concave: the rectangles cover the corner; the triangle
            # (inside rectangle i when concave) closes the round-off crack between them
            if abs(signed_area(np.array([V, A, B]))) > 1e-14:
                polys.append(Polygon([V, A, B]))
            continue
        # A + s T_i = B + u T_j
        M2 = np.array([[T[i, 0], -T[j, 0]], [T[i, 1], -T[j, 1]]])
        s, _ = np.linalg.solve(M2, B - A)
        Mp = A + s * T[i]
        reach = mitre_limit * max(wi, wj)
        u = (Mp - B) @ T[j]
        if np.linalg.norm(Mp - V) <= reach and s >= 0 and u <= 0:
            polys.append(Polygon([V, A, Mp, B]))
            continue
        # clip the mitre with the line normal to its bisector at distance `reach`
        m = _unit(N[i] + N[j])
        sa = (reach - (A - V) @ m) / max(T[i] @ m, 1e-12)
        sb = (reach - (B - V) @ m) / min(T[j] @ m, -1e-12)
        if sa > 0 and sb > 0:
            polys.append(Polygon([V, A, A + sa * T[i], B + sb * T[j], B]))
        else:
            polys.append(Polygon([V, A, B]))
    # the union's exterior: a gap the allowance closes over (a narrow notch in
    # the outline) is filled, it is not cut out
    U = union_all([p if p.is_valid else p.buffer(0) for p in polys])
    # a closing by 0.1 um seals the zero-width cracks round-off leaves between
    # neighbouring rectangles (they would stay in the outline as spikes)
    U = U.buffer(1e-7, join_style="mitre").buffer(-1e-7, join_style="mitre")
    if U.geom_type == "MultiPolygon":
        U = max(U.geoms, key=lambda g: g.area)
    U = U.simplify(1e-6, preserve_topology=True)  # drop the collinear points where rectangles meet
    Q = np.asarray(U.exterior.coords)[:-1]
    if signed_area(Q) < 0:
        Q = Q[::-1]
    return Q


def _boundary_darts(panel: Panel) -> tuple[np.ndarray, list[tuple[int, int, int]]]:
    """The outline's vertex indices with boundary dart legs left out (the cut
    line bridges the mouth), and per dart (mouth start, apex, mouth end)."""
    k = len(panel.outline)
    legs: dict[str, list[Segment]] = {}
    for s in panel.segments:
        if s.hole < 0 and _is_dart(s):
            head, _, tail = s.name.rpartition(":")  # dart:<id>:left, dart:<id>:right(_mirror)
            legs.setdefault(head + tail.removeprefix("left").removeprefix("right"), []).append(s)
    keep = np.ones(k, bool)
    darts = []
    for pair in legs.values():
        if len(pair) != 2:
            continue
        first, second = pair if pair[0].stop == pair[1].start else pair[::-1]
        a, apex, b = first.start, first.stop, second.stop
        keep[(a + 1 + np.arange((b - a) % k - 1)) % k] = False
        darts.append((a, apex, b))
    return np.nonzero(keep)[0], darts


def _dart_points(H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An interior (diamond) dart's two points and its two widest points: its
    four sharpest turns, the two farthest from its middle first."""
    e_in = _unit(H - np.roll(H, 1, axis=0))
    e_out = _unit(np.roll(H, -1, axis=0) - H)
    corners = H[np.argsort((e_in * e_out).sum(1))[:4]]
    c = H.mean(0)
    corners = corners[np.argsort(-np.linalg.norm(corners - c, axis=1))]
    return corners[:2], corners[2:]


def _ray_hit(poly: np.ndarray, origin: np.ndarray, d: np.ndarray, far: float) -> np.ndarray | None:
    """First crossing of the ray origin + t d (t > 0) with the closed polyline."""
    A = poly
    B = np.roll(poly, -1, axis=0)
    E = B - A
    den = d[0] * E[:, 1] - d[1] * E[:, 0]
    ok = np.abs(den) > 1e-15
    R = A - origin
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (R[:, 0] * E[:, 1] - R[:, 1] * E[:, 0]) / den
        u = (R[:, 0] * d[1] - R[:, 1] * d[0]) / den
    hit = ok & (t > -1e-12) & (t <= far) & (u >= -1e-9) & (u <= 1 + 1e-9)
    if not hit.any():
        return None
    return origin + t[hit].min() * d


def _arc(P: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])


def _at_arc(P: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray]:
    """Point and unit tangent at arc length s along the open polyline P."""
    c = _arc(P)
    i = int(np.clip(np.searchsorted(c, s, side="right") - 1, 0, len(P) - 2))
    seg = c[i + 1] - c[i]
    t = 0.0 if seg <= 0 else (s - c[i]) / seg
    return P[i] + t * (P[i + 1] - P[i]), _unit(P[i + 1] - P[i])


def notch_fractions(length: float, spacing: float, ends: bool) -> np.ndarray:
    """Where along a seam side (fractions of its length) the notches go."""
    n = 2 * max(1, math.ceil(length / (2 * spacing)))
    f = np.arange(1, n) / n
    return np.concatenate([[0.0], f, [1.0]]) if ends else f


def _notch_at(piece: CutPiece, at: np.ndarray, nrm: np.ndarray, depth: float, seam: int, side: str, s: float) -> Notch:
    """A notch marking sew point ``at``: from where the outward normal ``nrm``
    meets the cut line, ``depth`` inward (at most 0.6 of the allowance there)."""
    outer = _ray_hit(piece.cut, at + 1e-9 * nrm, nrm, 10 * MAX_ALLOWANCE)
    if outer is None:
        outer = at
    w = float(np.linalg.norm(outer - at))
    # into the allowance; with none (cut on the sew line), a slit into the piece
    inner = outer - (min(depth, 0.6 * w) if w > 1e-9 else depth) * nrm
    return Notch(outer, inner, at, seam, side, s)


def _notch(piece: CutPiece, P: np.ndarray, s: float, depth: float, seam: int, side: str, s_rep: float) -> Notch:
    """A notch at arc length s along the seam side P (at an end, normal to the
    seam's own end edge)."""
    at, t = _at_arc(P, s)
    return _notch_at(piece, at, np.array([t[1], -t[0]]), depth, seam, side, s_rep)


# ------------------------------------------------------------------ pieces


def _grain_line(panel: Panel) -> np.ndarray:
    """Arrow tail and head [m]: through the panel's middle along its grain,
    60 % of the panel's chord there (so inside the sew line)."""
    from shapely import LineString, Point, Polygon

    g = np.array([-math.sin(panel.grain), math.cos(panel.grain)])
    poly = Polygon(panel.outline)
    mid = poly.centroid if poly.contains(poly.centroid) else poly.representative_point()
    c = np.asarray(mid.coords[0])
    span = 2 * float(np.ptp(panel.outline, axis=0).max())
    chord = poly.intersection(LineString([c - span * g, c + span * g]))
    part = min(getattr(chord, "geoms", [chord]), key=lambda q: q.distance(Point(c)))
    lo, hi = np.sort((np.asarray(part.coords) - c) @ g)[[0, -1]]
    m, half = 0.5 * (lo + hi), 0.3 * (hi - lo)
    return np.array([c + (m - half) * g, c + (m + half) * g])


def _symmetry_axis(panel: Panel) -> np.ndarray | None:
    """The axis of a panel mirrored by a symmetry stroke, as the chord of the
    panel along it: the perpendicular bisector of a segment's first point and
    its mirror image's last point."""
    from shapely import LineString, Polygon

    by_name = {s.name: s for s in panel.segments if s.hole < 0}
    for s in by_name.values():
        m = by_name.get(s.name + "_mirror")
        if m is None:
            continue
        P, Q = panel.outline[s.start], panel.outline[m.stop]
        if np.linalg.norm(P - Q) < 1e-9:
            continue
        c, n = 0.5 * (P + Q), _unit(Q - P)
        d = np.array([-n[1], n[0]]) * 2 * float(np.ptp(panel.outline, axis=0).max())
        chord = Polygon(panel.outline).intersection(LineString([c - d, c + d]))
        parts = [g for g in getattr(chord, "geoms", [chord]) if g.geom_type == "LineString"]
        if parts:
            return np.asarray(max(parts, key=lambda g: g.length).coords)[[0, -1]]
    return None


def cut_pieces(pattern: DraftedPattern, spec: CutSpec | None = None) -> list[CutPiece]:
    """Every panel as a piece to cut (or, with ``spec.group``, one piece per set
    of congruent panels, counting them)."""
    spec = spec or CutSpec()
    for what, v in (("notch_spacing", spec.notch_spacing), ("notch_depth", spec.notch_depth)):
        if not (math.isfinite(v) and v > 0):
            raise PatternError(what, f"{what} = {v!r} m must be positive")
    widths = segment_widths(pattern, spec)
    pieces: dict[str, CutPiece] = {}
    for panel in pattern.panels:
        w = _edge_widths(panel, widths, spec.seam_allowance)
        idx, darts = _boundary_darts(panel)
        base = panel.outline[idx]
        # a bridged edge (mouth chord) takes the width of the edge before the dart
        cut = offset_polygon(base, w[idx], spec.mitre_limit) if w.max() > 0 else base.copy()
        piece = CutPiece(panel, panel.outline, cut, w)
        sewn_holes = {s.hole for s in panel.segments if s.hole >= 0 and _is_dart(s)}
        for h, H in enumerate(panel.holes):
            if h in sewn_holes:
                piece.hole_cut.append(None)
                c = H.mean(0)
                tips, sides = _dart_points(H)
                for tip in tips:  # the usual marks: short of the points, just inside the widest points
                    piece.drills.append(tip + DART_DRILL_INSET * _unit(c - tip))
                for side in sides:
                    piece.drills.append(side + 0.003 * _unit(c - side))
            else:
                piece.hole_cut.append(_shrink_hole(H, spec.seam_allowance))
        for a, apex, b in darts:
            mouth = 0.5 * (panel.outline[a] + panel.outline[b])
            piece.drills.append(panel.outline[apex] + DART_DRILL_INSET * _unit(mouth - panel.outline[apex]))
        piece.symmetry_axis = _symmetry_axis(panel)
        piece.grain = _grain_line(panel)
        pieces[panel.name] = piece
        # dart mouth notches: across the bridged mouth from its two ends
        for a, _, b in darts:
            chord = panel.outline[b] - panel.outline[a]
            nrm = _unit(np.array([chord[1], -chord[0]]))
            for v in (a, b):
                piece.notches.append(_notch_at(piece, panel.outline[v], nrm, spec.notch_depth, -1, "dart", 0.0))
    for si, sp in enumerate(pattern.seams):
        if _is_dart_seam(sp):
            continue
        pa, pb = pieces[sp.a_panel], pieces[sp.b_panel]
        A = _seg_pts(pa.panel, sp.a_segment)
        B = _seg_pts(pb.panel, sp.b_segment)
        Bm = B[::-1] if sp.reverse else B  # b in the order that matches a
        La, Lb = _arc(A)[-1], _arc(Bm)[-1]
        fr = list(notch_fractions(max(La, Lb), spec.notch_spacing, spec.end_notches))
        fr += [d / La for d in spec.notch_distances if 0 < d < La]
        for f in fr:
            pa.notches.append(_notch(pa, A, f * La, spec.notch_depth, si, "a", f * La))
            s_b = (1 - f) * Lb if sp.reverse else f * Lb  # along b's own direction
            pb.notches.append(_notch(pb, B, s_b, spec.notch_depth, si, "b", f * Lb))
    out = list(pieces.values())
    if spec.group:
        out = _group(out)
    for p in out:
        p.labels = _labels(p, spec)
    return out


def _is_dart_seam(sp: SeamSpec) -> bool:
    return sp.a_segment.startswith("dart:") or sp.b_segment.startswith("dart:")


def _seg_pts(panel: Panel, name: str) -> np.ndarray:
    seg = next(s for s in panel.segments if s.name == name)
    return segment_points(panel, seg)


def _shrink_hole(H: np.ndarray, w: float) -> np.ndarray:
    """A hole's cut line: the opening less the allowance (turned in); the sew
    line itself when the hole is too small for it."""
    if w <= 0:
        return H.copy()
    from shapely import Polygon

    inner = Polygon(H).buffer(-w, join_style="mitre")
    if inner.is_empty or inner.geom_type != "Polygon":
        return H.copy()
    Q = np.asarray(inner.exterior.coords)[:-1]
    return Q[::-1] if signed_area(Q) > 0 else Q  # holes run clockwise


# ------------------------------------------------------------------ grouping and labels


def _signature(p: CutPiece, mirror: bool) -> list[np.ndarray]:
    """Point clouds of a piece, moved so its sew line's bounding box starts at 0
    (mirrored about the vertical first when asked)."""
    f = np.array([-1.0, 1.0]) if mirror else np.ones(2)
    sew = p.sew * f
    o = sew.min(0)
    clouds = [sew, p.cut * f, np.array([n.outer for n in p.notches]).reshape(-1, 2) * f]
    clouds += [h * f for h in p.panel.holes]
    clouds.append(np.array(p.drills).reshape(-1, 2) * f)
    return [c - o for c in clouds]


def _same(a: list[np.ndarray], b: list[np.ndarray], tol: float = 1e-4) -> bool:
    from scipy.spatial import cKDTree

    if len(a) != len(b):
        return False
    for x, y in zip(a, b, strict=True):
        if len(x) == 0 or len(y) == 0:
            if len(x) != len(y):
                return False
            continue
        if cKDTree(y).query(x)[0].max() > tol or cKDTree(x).query(y)[0].max() > tol:
            return False
    return True


def _group(pieces: list[CutPiece]) -> list[CutPiece]:
    out: list[CutPiece] = []
    for p in pieces:
        for q in out:
            if abs(q.panel.grain - p.panel.grain) > 1e-9:
                continue
            if _same(_signature(q, False), _signature(p, False)):
                q.quantity += 1
                q.copies.append(p.name)
                break
            if _same(_signature(q, False), _signature(p, True)):
                q.quantity += 1
                q.mirrored += 1
                q.copies.append(p.name)
                break
        else:
            out.append(p)
    return out


def _labels(p: CutPiece, spec: CutSpec) -> list[str]:
    """Lines of the piece's label, first the AAMA piece system texts."""
    cut = f"Cut {p.quantity}"
    if p.mirrored:
        cut += f" ({p.mirrored} mirrored)"
    out = [f"Piece Name: {p.name}", f"Quantity: {p.quantity}"]
    if spec.size:
        out.append(f"Size: {spec.size}")
    if spec.design_name:
        out.append(f"Style Name: {spec.design_name}")
    out.append(cut + (f" - also {', '.join(p.copies)}" if p.copies else ""))
    return out

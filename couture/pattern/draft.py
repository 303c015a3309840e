"""Drafting a design: sloper -> strokes -> DraftedPattern (panels, seams, placement).

Vertex-count invariant: every segment of a sloper is sampled with a fixed
number of points per curve, fixed from the sloper drafted at its *default*
options (target spacing ``spacing``, 1 cm by default) and the integer
(topology) options; strokes add fixed counts (dart legs ``DART_LEG_SAMPLES``
each, holes ``HOLE_SAMPLES``). So for one design (sloper kind, integer
options, stroke list) the number of polyline vertices never depends on
option or stroke *values*; only positions move, smoothly.

Body-fitted slopers (``SloperDef.body_fitted``: ``dress_waist``,
``shirt_set_in``): the body-measurement options the design does not set take
the design's body's measured values
(:func:`couture.pattern.body_measures.body_options`), its waist height among
them (``waist_height``: the rings hang there); other slopers draft from the
mannequin's measurements on any body.

Strokes (``Stroke.kind`` and ``params``):

- ``curve`` on panel P: ``{"segment": name, "points": [[s, dn], ...]}``:
  control points at fractions s (0 < s < 1, increasing) of the segment's
  curve parameter, each displaced dn [m] along the outward normal; the
  displacement along the segment is the clamped cubic spline through
  (0, 0), (s_i, dn_i), (1, 0), so segment end points (corners) stay put.
- ``dart`` on panel P, boundary: ``{"segment", "position" (fraction), "width" [m],
  "length" [m]}``: a notch cut into the segment, legs sewn together.
  Interior (diamond): ``{"anchor": segment, "position", "depth" [m] inward
  from the anchor, "width", "length"}``: a hole whose two sides are sewn.
  A stroke whose id equals a built-in sloper dart id overrides its params.
- ``hole`` on panel P: ``{"anchor", "position", "depth", "radius"}``: a round hole.
- ``seam`` (panel ''): ``{"a_panel", "a_segment", "b_panel", "b_segment"}``.
- ``symmetry`` on panel P: ``{"axis": segment}``: P is drafted (and edited) as
  a half and mirrored about the straight axis segment; edits mirror live.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from couture.pattern.drafted import DraftedPattern, Panel, SeamSpec, Segment, segment_points
from couture.pattern.errors import PatternError
from couture.pattern.geometry import Curve
from couture.pattern.options import resolve
from couture.pattern.placement import fit_ring, place
from couture.pattern.slopers import SLOPERS, SloperDraft
from couture.pattern.slopers.base import SloperDef
from schemas.design import Design, Stroke

if TYPE_CHECKING:
    from scipy.interpolate import CubicSpline

SPACING = 0.01
"""[m] target polyline spacing at default size"""
DART_LEG_SAMPLES = 8
HOLE_SAMPLES = 24
STROKE_KINDS = ("curve", "dart", "grain", "hole", "seam", "symmetry")


# ------------------------------------------------------------------ segments


class SegEval:
    """A segment as a smooth map u in [0, 1] -> R^2 over its curves, with the
    curves' parameter ranges proportional to their fixed sample counts (so
    curve junctions fall on samples), optionally displaced along its normal."""

    def __init__(self, curves: list[Curve], counts: list[int]):
        self.curves = curves
        self.counts = counts
        self.n = int(sum(counts))
        self.breaks = np.concatenate([[0.0], np.cumsum(counts) / self.n])
        self.disp: CubicSpline | None = None

    def _locate(self, u):
        u = np.clip(np.asarray(u, float), 0.0, 1.0)
        k = np.clip(np.searchsorted(self.breaks, u, side="right") - 1, 0, len(self.curves) - 1)
        span = self.breaks[k + 1] - self.breaks[k]
        return k, (u - self.breaks[k]) / span, span

    def base(self, u):
        k, t, _ = self._locate(u)
        out = np.empty((len(t), 2))
        for i, c in enumerate(self.curves):
            m = k == i
            if m.any():
                out[m] = c.eval(t[m])
        return out

    def tangent(self, u):
        k, t, span = self._locate(u)
        out = np.empty((len(t), 2))
        for i, c in enumerate(self.curves):
            m = k == i
            if m.any():
                out[m] = c.deriv(t[m]) / span[m, None]
        return out

    def normal(self, u):
        T = self.tangent(u)
        n = np.stack([T[:, 1], -T[:, 0]], axis=1)
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)

    def eval(self, u):
        u = np.atleast_1d(np.asarray(u, float))
        P = self.base(u)
        if self.disp is not None:
            P = P + self.disp(u)[:, None] * self.normal(u)
        return P

    def length(self) -> float:
        P = self.eval(np.linspace(0, 1, 4 * self.n + 1))
        return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())

    def samples(self) -> np.ndarray:
        return self.eval(np.arange(self.n) / self.n)


# ------------------------------------------------------------------ context


@dataclass
class DartSpec:
    id: str
    panel: str
    kind: str  # 'boundary' | 'interior' | 'hole'
    params: dict
    builtin: bool = False


@dataclass
class DraftContext:
    """Intermediate results kept for edit frames and validation."""

    params: dict[str, float]
    sloper: SloperDraft
    segs: dict[tuple[str, str], SegEval] = field(default_factory=dict)
    darts: dict[str, DartSpec] = field(default_factory=dict)
    seam_owner: dict[int, str] = field(default_factory=dict)
    """index into pattern.seams -> element id that created it"""


NO_SLOPER = SloperDef("none", (), lambda p: SloperDraft([]), "no sloper: a design of free-form pieces only")
"""``Sloper.kind`` 'none': no options, no panels (not in ``SLOPERS``: nothing lists it as a garment)"""


def sloper_of(design: Design):
    kind = design.sloper.kind
    if kind == NO_SLOPER.kind:
        if not design.pieces:
            raise PatternError("sloper", "sloper kind 'none' needs free-form pieces (design.pieces is empty)")
        return NO_SLOPER
    if kind not in SLOPERS:
        raise PatternError("sloper", f"unknown sloper kind {kind!r}; kinds are {sorted(SLOPERS)} or 'none'")
    return SLOPERS[kind]


def sloper_params(design: Design) -> dict[str, float]:
    """The design's option values before defaults: its own, over (for a sloper
    drafted from the body, ``SloperDef.body_fitted``) the measurements of the
    body it names (:func:`couture.pattern.body_measures.body_options`)."""
    sd = sloper_of(design)
    given = dict(design.sloper.params)
    if sd.body_fitted:
        from couture.pattern.body_measures import body_options

        names = {o.name for o in sd.options}
        given = {**{k: v for k, v in body_options(design.body.name).items() if k in names}, **given}
    return given


@lru_cache(maxsize=64)
def _counts(kind: str, topo: tuple, spacing: float) -> dict[tuple[str, str], tuple[int, ...]]:
    sd = SLOPERS[kind] if kind in SLOPERS else NO_SLOPER
    p = {o.name: o.default for o in sd.options}
    p.update(dict(topo))
    draft = sd.draft(p)
    out = {}
    for panel in draft.panels:
        for seg in panel.segments:
            out[(panel.name, seg.name)] = tuple(max(2, math.ceil(c.length() / spacing)) for c in seg.curves)
    return out


def _num(stroke_id: str, params: dict, key: str, lo=-math.inf, hi=math.inf, lo_open=False, hi_open=False) -> float:
    if key not in params:
        raise PatternError(stroke_id, f"missing parameter {key!r}")
    v = params[key]
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise PatternError(stroke_id, f"{key} = {v!r} is not a number") from None
    if not math.isfinite(v):
        raise PatternError(stroke_id, f"{key} = {v} is not finite")
    if v < lo or v > hi or (lo_open and v == lo) or (hi_open and v == hi):
        raise PatternError(
            stroke_id, f"{key} = {v:g} is outside {'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        )
    return v


def _seg(ctx: DraftContext, panel: str, name: str, element: str) -> SegEval:
    if (panel, name) not in ctx.segs:
        names = sorted(s for p, s in ctx.segs if p == panel)
        if not names:
            raise PatternError(element, f"no panel named {panel!r}")
        raise PatternError(element, f"panel {panel!r} has no segment {name!r}; segments are {names}")
    return ctx.segs[(panel, name)]


def _check_stroke(st: Stroke) -> None:
    if st.kind not in STROKE_KINDS:
        raise PatternError(st.id, f"unknown stroke kind {st.kind!r}; kinds are {list(STROKE_KINDS)}")


def interior_frame(ctx: DraftContext, panel: str, params: dict, element: str):
    """(centre, tangent t, inward axis a, anchor length) of an interior dart/hole."""
    seg = _seg(ctx, panel, params.get("anchor", ""), element)
    pos = _num(element, params, "position", 0.0, 1.0)
    depth = _num(element, params, "depth", 0.0, 10.0)
    T = seg.tangent(np.array([pos]))[0]
    t = T / np.linalg.norm(T)
    a = np.array([-t[1], t[0]])
    c = seg.eval(np.array([pos]))[0] + depth * a
    return c, t, a, seg.length()


# ------------------------------------------------------------------ drafting


def draft(design: Design, spacing: float = SPACING) -> DraftedPattern:
    """Draft a design into panels (dense CCW outlines, CW holes, named
    segments), seams (orientation from the 3D placement) and placements."""
    return draft_with_context(design, spacing)[0]


def draft_with_context(design: Design, spacing: float = SPACING) -> tuple[DraftedPattern, DraftContext]:
    from couture.pattern.limits import check_body

    check_body(design.body)  # placement reads the body's sections
    sd = sloper_of(design)
    params = resolve(sd.options, sloper_params(design))
    topo = tuple(sorted((o.name, params[o.name]) for o in sd.options if o.integer))
    sloper = sd.draft(params)
    counts = _counts(design.sloper.kind, topo, spacing)
    ctx = DraftContext(params, sloper)
    for pd in sloper.panels:
        for sg in pd.segments:
            ctx.segs[(pd.name, sg.name)] = SegEval(sg.curves, list(counts[(pd.name, sg.name)]))
    from couture.pattern.pieces import apply_piece_curves, piece_panels, piece_segments

    free = piece_panels(design)
    free_segs = {p.name: piece_segments(p) for p in free}
    for name, segs in free_segs.items():
        for sn, pseg in segs.items():
            ctx.segs[(name, sn)] = pseg  # type: ignore[assignment]  # SegEval's interface: curve strokes bend piece segments too
    panel_names = [p.name for p in sloper.panels] + [p.name for p in free]
    for name in {n for n in panel_names if panel_names.count(n) > 1}:
        raise PatternError(name, "two panels have this name (free-form pieces and sloper panels need unique names)")

    ids = set()
    for st in design.strokes:
        _check_stroke(st)
        if st.id in ids:
            raise PatternError(st.id, "duplicate stroke id")
        ids.add(st.id)

    # curve strokes: displacement splines (one per segment)
    for st in design.strokes:
        if st.kind != "curve":
            continue
        seg = _seg(ctx, st.panel, st.params.get("segment", ""), st.id)
        if seg.disp is not None:
            raise PatternError(st.id, f"segment {st.panel}:{st.params['segment']} already has a curve stroke")
        pts = st.params.get("points", [])
        if not isinstance(pts, (list, tuple)) or len(pts) == 0:
            raise PatternError(st.id, "curve stroke needs a non-empty 'points' list of [s, dn]")
        s_prev = 0.0
        ss, dn = [0.0], [0.0]
        for i, pt in enumerate(pts):
            el = f"cv:{st.panel}:{st.params['segment']}:{i}"
            if not isinstance(pt, (list, tuple)) or len(pt) != 2:
                raise PatternError(el, f"control point {pt!r} is not [s, dn]")
            s_i = _num(el, {"s": pt[0]}, "s", 0.0, 1.0, True, True)
            dn_i = _num(el, {"dn": pt[1]}, "dn", -2.0, 2.0)
            if s_i <= s_prev + 1e-6:
                raise PatternError(el, f"s = {s_i:g} must be greater than the previous control point's {s_prev:g}")
            ss.append(s_i)
            dn.append(dn_i)
            s_prev = s_i
        ss.append(1.0)
        dn.append(0.0)
        # imported here: scipy.interpolate takes 0.2-0.3 s to import, and every node imports this module
        from scipy.interpolate import CubicSpline

        seg.disp = CubicSpline(ss, dn, bc_type="clamped")
    for p in free:
        apply_piece_curves(p, free_segs[p.name])

    # darts (built-in, overridden by same-id strokes, plus stroke darts) and holes
    for st in design.strokes:
        if st.kind in ("dart", "hole") and st.panel in free_segs:
            raise PatternError(
                st.id,
                f"a {st.kind} stroke on the imported piece {st.panel!r} is not supported "
                "(a piece's darts are its own, sewn leg to leg by seam strokes)",
            )
    overrides = {st.id: st for st in design.strokes if st.kind == "dart"}
    for bd in sloper.darts:
        prm = dict(bd.params)
        if bd.id in overrides:
            prm.update(overrides[bd.id].params)
        ctx.darts[bd.id] = DartSpec(bd.id, bd.panel, bd.kind, prm, builtin=True)
    for st in design.strokes:
        if st.kind == "dart" and st.id not in ctx.darts:
            if st.panel not in panel_names:
                raise PatternError(st.id, f"no panel named {st.panel!r}")
            kind = "boundary" if "segment" in st.params else "interior" if "anchor" in st.params else None
            if kind is None:
                raise PatternError(st.id, "dart needs 'segment' (boundary dart) or 'anchor' (interior dart)")
            ctx.darts[st.id] = DartSpec(st.id, st.panel, kind, dict(st.params))
        elif st.kind == "hole":
            if st.panel not in panel_names:
                raise PatternError(st.id, f"no panel named {st.panel!r}")
            ctx.darts[st.id] = DartSpec(st.id, st.panel, "hole", dict(st.params))

    sewn: dict[tuple[str | None, str | None], list[str]] = {}
    for a_p, a_s, b_p, b_s in sloper.seams:
        sewn.setdefault((a_p, a_s), []).append("sloper seam")
        sewn.setdefault((b_p, b_s), []).append("sloper seam")
    for st in design.strokes:
        if st.kind == "seam":
            sewn.setdefault((st.params.get("a_panel"), st.params.get("a_segment")), []).append(st.id)
            sewn.setdefault((st.params.get("b_panel"), st.params.get("b_segment")), []).append(st.id)

    panels: list[Panel] = []
    dart_seams: list[tuple[SeamSpec, str]] = []
    for pd in sloper.panels:
        pts_all: list[np.ndarray] = []
        segments: list[Segment] = []
        holes: list[np.ndarray] = []
        for sg in pd.segments:
            seg = ctx.segs[(pd.name, sg.name)]
            bds = sorted(
                (
                    d
                    for d in ctx.darts.values()
                    if d.kind == "boundary" and d.panel == pd.name and d.params.get("segment") == sg.name
                ),
                key=lambda d: d.id,
            )
            start = sum(len(p) for p in pts_all)
            if not bds:
                pts_all.append(seg.samples())
            else:
                if (pd.name, sg.name) in sewn:
                    raise PatternError(
                        bds[0].id,
                        f"boundary dart on sewn segment {pd.name}:{sg.name} is not supported; use an interior dart",
                    )
                L = seg.length()
                spans = []
                for d in bds:
                    pos = _num(d.id, d.params, "position", 0.0, 1.0, True, True)
                    w = _num(d.id, d.params, "width", 0.0, 1.0, True)
                    ln = _num(d.id, d.params, "length", 0.0, 2.0, True)
                    ul, ur = pos - w / (2 * L), pos + w / (2 * L)
                    if ul <= 0.0 or ur >= 1.0:
                        raise PatternError(
                            d.id,
                            f"dart (position {pos:g}, width {w:g} m) does not fit on "
                            f"segment {pd.name}:{sg.name} ({L:.3f} m)",
                        )
                    spans.append((ul, ur, ln, d))
                # darts in the order they sit along the segment (their ids say nothing about it)
                spans.sort(key=lambda span: span[0])
                for (_, ur0, _, d0), (ul1, _, _, d1) in zip(spans, spans[1:], strict=False):
                    if ul1 <= ur0:
                        raise PatternError(d1.id, f"dart overlaps dart {d0.id!r} on {pd.name}:{sg.name}")
                npiece = max(2, math.ceil(seg.n / (len(spans) + 1)))
                u_prev = 0.0
                pieces = []
                for ul, ur, ln, d in spans:
                    pieces.append(seg.eval(np.linspace(u_prev, ul, npiece, endpoint=False)))
                    A, B = seg.eval(np.array([ul, ur]))
                    ch = B - A
                    inward = np.array([-ch[1], ch[0]]) / max(np.linalg.norm(ch), 1e-300)
                    apex = 0.5 * (A + B) + ln * inward
                    t = np.linspace(0, 1, DART_LEG_SAMPLES, endpoint=False)[:, None]
                    leg_l = A + t * (apex - A)
                    leg_r = apex + t * (B - apex)
                    i0 = start + sum(len(p) for p in pieces)
                    pieces.append(leg_l)
                    pieces.append(leg_r)
                    segments.append(Segment(f"dart:{d.id}:left", i0, i0 + DART_LEG_SAMPLES))
                    segments.append(Segment(f"dart:{d.id}:right", i0 + DART_LEG_SAMPLES, i0 + 2 * DART_LEG_SAMPLES))
                    dart_seams.append(
                        (SeamSpec(pd.name, f"dart:{d.id}:left", pd.name, f"dart:{d.id}:right", True), d.id)
                    )
                    u_prev = ur
                pieces.append(seg.eval(np.linspace(u_prev, 1.0, npiece, endpoint=False)))
                pts_all.append(np.vstack(pieces))
            segments.append(Segment(sg.name, start, start + len(pts_all[-1])))
        outline = np.vstack(pts_all)
        k = len(outline)
        for s in segments:
            s.stop %= k
        # interior darts and holes
        for d in sorted(
            (d for d in ctx.darts.values() if d.panel == pd.name and d.kind in ("interior", "hole")), key=lambda d: d.id
        ):
            c, t, a, _ = interior_frame(ctx, pd.name, d.params, d.id)
            if d.kind == "interior":
                w = _num(d.id, d.params, "width", 0.0, 1.0, True)
                ln = _num(d.id, d.params, "length", 0.0, 2.0, True)
                corners = [c + 0.5 * ln * a, c + 0.5 * w * t, c - 0.5 * ln * a, c - 0.5 * w * t]
                u = np.linspace(0, 1, DART_LEG_SAMPLES, endpoint=False)[:, None]
                hole = np.vstack([corners[i] + u * (corners[(i + 1) % 4] - corners[i]) for i in range(4)])
                hi = len(holes)
                M2 = 2 * DART_LEG_SAMPLES
                segments.append(Segment(f"dart:{d.id}:right", 0, M2, hole=hi))
                segments.append(Segment(f"dart:{d.id}:left", M2, 0, hole=hi))
                dart_seams.append((SeamSpec(pd.name, f"dart:{d.id}:right", pd.name, f"dart:{d.id}:left", True), d.id))
            else:
                r = _num(d.id, d.params, "radius", 0.0, 1.0, True)
                th = -np.linspace(0, 2 * np.pi, HOLE_SAMPLES, endpoint=False)  # clockwise
                hole = c + r * (np.cos(th)[:, None] * t + np.sin(th)[:, None] * a)
            holes.append(hole)
        panels.append(Panel(pd.name, outline, holes, segments))
    panels.extend(free)

    # symmetry: mirror half panels
    for st in design.strokes:
        if st.kind == "symmetry":
            found = next((j for j, p in enumerate(panels) if p.name == st.panel), None)
            if found is None:
                raise PatternError(st.id, f"no panel named {st.panel!r}")
            panels[found] = _mirror(panels[found], st)

    # grain: a panel cut on the bias (or any angle); the warp runs at ``angle``
    # [rad] from the panel's material +y, counter-clockwise (Panel.grain)
    grained: set[str] = set()
    for st in design.strokes:
        if st.kind != "grain":
            continue
        cut = next((p for p in panels if p.name == st.panel), None)
        if cut is None:
            raise PatternError(st.id, f"grain stroke on {st.panel!r}: no panel of that name")
        if st.panel in grained:
            raise PatternError(st.id, f"panel {st.panel!r} already has a grain stroke")
        grained.add(st.panel)
        cut.grain = _num(st.id, st.params, "angle", -math.pi, math.pi)

    # seams
    seams: list[SeamSpec] = []
    owners: list[str] = []
    by_name = {p.name: p for p in panels}
    for a_p, a_s, b_p, b_s in sloper.seams:
        if a_p in by_name and b_p in by_name and _has(by_name[a_p], a_s) and _has(by_name[b_p], b_s):
            seams.append(SeamSpec(a_p, a_s, b_p, b_s))
            owners.append(f"seam:{a_p}:{a_s}:{b_p}:{b_s}")
    for st in design.strokes:
        if st.kind == "seam":
            prm = st.params
            for key in ("a_panel", "a_segment", "b_panel", "b_segment"):
                if not isinstance(prm.get(key), str):
                    raise PatternError(st.id, f"seam needs a string {key!r}")
            seams.append(SeamSpec(prm["a_panel"], prm["a_segment"], prm["b_panel"], prm["b_segment"]))
            owners.append(st.id)
    for sp, owner in dart_seams:
        seams.append(sp)
        owners.append(owner)

    # placement, then seam orientation from the placed segments
    from couture.pattern.pieces import piece_rings

    for ring in sloper.rings + piece_rings(design, body=design.body.name):
        for name, pl in fit_ring(ring, by_name, body=design.body.name).items():
            by_name[name].placement = pl
    if any(pc.placement.ring == "neck" for pc in design.pieces):
        from couture.pattern.pieces import collar_placements

        for name, pl in collar_placements(design, by_name, seams, body=design.body.name).items():
            by_name[name].placement = pl
    if any(pc.placement.ring == "inside" for pc in design.pieces):
        from couture.pattern.pieces import inside_placements

        for name, pl in inside_placements(design, by_name, seams).items():
            by_name[name].placement = pl
    pattern = DraftedPattern(panels, seams)
    for i, (sp, owner) in enumerate(zip(seams, owners, strict=True)):
        ctx.seam_owner[i] = owner
        _orient(pattern, sp, owner)
    return pattern, ctx


def option_values(design: Design) -> dict:
    """The option values a design gives (the rest take their defaults): its
    sloper params, over its body's measured values for a body-fitted sloper
    (what an option control shows)."""
    return sloper_params(design)


def _has(panel: Panel, name: str) -> bool:
    return any(s.name == name for s in panel.segments)


def find_segment(pattern: DraftedPattern, panel: str, name: str, element: str) -> tuple[Panel, Segment]:
    try:
        p = pattern.panel(panel)
    except KeyError:
        raise PatternError(element, f"no panel named {panel!r}") from None
    for s in p.segments:
        if s.name == name:
            return p, s
    raise PatternError(element, f"panel {panel!r} has no segment {name!r}; segments are {[s.name for s in p.segments]}")


def _orient(pattern: DraftedPattern, sp: SeamSpec, owner: str) -> None:
    """Choose ``reverse`` so that sewing does not invert the cloth: b is
    traversed backwards when the two segments run opposite ways once placed
    around the body (SC §3: orientations are chosen automatically)."""
    pa, sa = find_segment(pattern, sp.a_panel, sp.a_segment, owner)
    pb, sb = find_segment(pattern, sp.b_panel, sp.b_segment, owner)
    A = place(pa, segment_points(pa, sa)[[0, -1]])
    B = place(pb, segment_points(pb, sb)[[0, -1]])
    da, db = A[1] - A[0], B[1] - B[0]
    if pa.placement is None or pb.placement is None or np.linalg.norm(da) * np.linalg.norm(db) < 1e-12:
        sp.reverse = True  # two CCW panels sewn edge to edge
        return
    sp.reverse = bool(da @ db < 0)


def _mirror(panel: Panel, st: Stroke) -> Panel:
    axis_name = st.params.get("axis")
    seg = next((s for s in panel.segments if s.name == axis_name and s.hole < 0), None)
    if seg is None:
        raise PatternError(st.id, f"panel {panel.name!r} has no outline segment {axis_name!r} to mirror about")
    P = panel.outline
    k = len(P)
    pts = segment_points(panel, seg)
    a, b = pts[0], pts[-1]
    d = b - a
    L = np.linalg.norm(d)
    if L < 1e-9:
        raise PatternError(st.id, f"axis segment {axis_name!r} has zero length")
    nrm = np.array([-d[1], d[0]]) / L
    dev = np.abs((pts - a) @ nrm).max()
    if dev > 1e-6 + 1e-4 * L:
        raise PatternError(st.id, f"axis segment {axis_name!r} is not straight (deviates {dev * 1e3:.2f} mm)")

    def refl(Q):
        return Q - 2 * ((Q - a) @ nrm)[:, None] * nrm

    # half without the axis: from the axis end b around to the axis start a
    idx = (seg.stop + np.arange((seg.start - seg.stop) % k + 1)) % k
    half = P[idx]  # b ... a
    mirrored = refl(half[::-1])[1:-1]  # a' = a ... b' = b, without the shared ends
    outline = np.vstack([half, mirrored])
    n_half = len(half)
    segments = []
    pos = {int(v): j for j, v in enumerate(idx)}
    for s in panel.segments:
        if s.hole >= 0 or s is seg:
            continue
        j0, j1 = pos[s.start], pos[s.stop]
        segments.append(Segment(s.name, j0, j1))
        # mirrored copy runs the other way: mirrored index of half j is (2 n_half - 2 - j) mod K
        K = len(outline)
        m0 = (2 * n_half - 2 - j1) % K
        m1 = (2 * n_half - 2 - j0) % K
        segments.append(Segment(s.name + "_mirror", m0, m1))
    holes = list(panel.holes) + [refl(h)[::-1] for h in panel.holes]
    nh = len(panel.holes)
    for s in panel.segments:
        if s.hole >= 0:
            segments.append(Segment(s.name, s.start, s.stop, s.hole))
            h = len(panel.holes[s.hole])
            segments.append(Segment(s.name + "_mirror", (h - s.stop) % h, (h - s.start) % h, s.hole + nh))
    return Panel(panel.name, outline, holes, segments, panel.placement, panel.grain)

"""Validation: check a design's numbers, draft it and check the pattern,
raising PatternError naming the element."""

from __future__ import annotations

import numpy as np

from couture.pattern.draft import draft_with_context, find_segment, segment_points
from couture.pattern.drafted import DraftedPattern
from couture.pattern.errors import PatternError
from couture.pattern.geometry import point_in_polygon, polyline_length, segments_cross, self_intersections, signed_area
from couture.pattern.limits import check_values
from schemas.design import Design

GATHER_RATIO_MAX = 3.0
"""longest / shortest seam segment length allowed (gathers and pleats)"""
MIN_SEGMENT_LENGTH = 1e-3  # [m]


def check_pattern(pattern: DraftedPattern, owners: dict[int, str] | None = None) -> None:
    owners = owners or {}
    for p in pattern.panels:
        for name, P in [("outline", p.outline)] + [(f"hole {i}", h) for i, h in enumerate(p.holes)]:
            if not np.all(np.isfinite(P)):
                raise PatternError(p.name, f"{name} has NaN/inf coordinates")
        if signed_area(p.outline) <= 0:
            raise PatternError(p.name, "outline is not counter-clockwise (or has no area)")
        hits = self_intersections(p.outline)
        if hits:
            i, j = hits[0]
            raise PatternError(
                f"{p.name}:{_seg_at(p, i)}",
                f"outline self-intersects (edges {i} and {j}, segments {_seg_at(p, i)!r} and {_seg_at(p, j)!r})",
            )
        for hi, h in enumerate(p.holes):
            if self_intersections(h):
                raise PatternError(f"{p.name}:{_seg_at(p, 0, hi)}", f"hole {hi} self-intersects")
            if not np.all(point_in_polygon(h, p.outline)) or segments_cross(h, p.outline):
                raise PatternError(_seg_at(p, 0, hi), f"hole/dart {hi} is not inside panel {p.name!r}")
            for hj in range(hi):
                if segments_cross(h, p.holes[hj]) or point_in_polygon(h[:1], p.holes[hj])[0]:
                    raise PatternError(_seg_at(p, 0, hi), f"hole/dart {hi} overlaps hole/dart {hj} of panel {p.name!r}")
        for s in p.segments:
            if polyline_length(segment_points(p, s)) < MIN_SEGMENT_LENGTH:
                raise PatternError(f"{p.name}:{s.name}", "segment has (nearly) zero length")
    for i, sp in enumerate(pattern.seams):
        el = owners.get(i, f"seam:{sp.a_panel}:{sp.a_segment}:{sp.b_panel}:{sp.b_segment}")
        pa, sa = find_segment(pattern, sp.a_panel, sp.a_segment, el)
        pb, sb = find_segment(pattern, sp.b_panel, sp.b_segment, el)
        if pa is pb and sa is sb:
            raise PatternError(el, f"segment {sp.a_panel}:{sp.a_segment} is sewn to itself")
        la, lb = polyline_length(segment_points(pa, sa)), polyline_length(segment_points(pb, sb))
        if max(la, lb) > GATHER_RATIO_MAX * max(min(la, lb), 1e-12):
            raise PatternError(
                el,
                f"seam lengths {la:.3f} m and {lb:.3f} m differ by more than the "
                f"gather ratio limit {GATHER_RATIO_MAX:g}x",
            )


def _seg_at(p, i, hole=-1) -> str:
    best = None
    for s in p.segments:
        if s.hole != hole:
            continue
        k = len(p.outline) if hole < 0 else len(p.holes[hole])
        n = (s.stop - s.start) % k or (k if hole >= 0 else 0)
        if (i - s.start) % k < max(n, 1):
            if best is None or n < best[0]:
                best = (n, s.name)
    return best[1] if best else p.name


def validate(design: Design) -> DraftedPattern:
    """Check the numbers (fabric, resolution, body: :mod:`couture.pattern.limits`),
    draft and check; return the pattern or raise PatternError naming the element
    (``fabric.<field>``, option, stroke id, panel:segment or seam) and the
    offending value."""
    check_values(design)
    pattern, ctx = draft_with_context(design)
    # darts' own checks: inside the panel, named after the dart
    try:
        check_pattern(pattern, ctx.seam_owner)
    except PatternError as e:
        for did in ctx.darts:
            if did in e.element:
                raise PatternError(did, str(e)) from None
        raise
    return pattern

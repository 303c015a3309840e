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
from schemas.design import Design, Piece

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


def piece_panels(design: Design) -> list[Panel]:
    """Every free-form piece of the design as a panel; a 'flat' piece gets its
    plane placement here, a ringed one from :func:`piece_rings`."""
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


def piece_rings(design: Design, body: str = "default") -> list[Ring]:
    """The torso ring of the design's ringed pieces, in ``position`` order,
    its top (material y = 0) at the first piece's ``height`` [m] (0 lies
    ``waist_y`` of the body below it if the body is not the default one: the
    height is taken relative to the default mannequin's waist)."""
    ringed = sorted((pc for pc in design.pieces if pc.placement.ring == "torso"), key=lambda pc: pc.placement.position)
    if not ringed:
        return []
    first = ringed[0].placement
    return [
        Ring(
            [pc.name for pc in ringed],
            [first.angle] + [0.0] * (len(ringed) - 1),
            np.array([0.0, first.height, M.TORSO_AXIS_Z]),
            section="torso",
            landmark="waist",
            top_rows_as_full=True,
        )
    ]

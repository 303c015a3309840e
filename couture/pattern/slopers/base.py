"""What every sloper drafts into: panels of named segments, seams, rings
(the placement about the body) and built-in darts; the sloper registry's
entry (:class:`SloperDef`); mirroring about the centre line and the ring
round the torso, which most garments use."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from couture.pattern import mannequin as M
from couture.pattern.geometry import Curve
from couture.pattern.options import Option


@dataclass
class SegDef:
    name: str
    curves: list[Curve]


@dataclass
class PanelDef:
    name: str
    segments: list[SegDef]
    """counter-clockwise, closed: each segment starts where the previous ends"""


@dataclass
class Ring:
    """Panels wrapped around one (possibly tilted, possibly conical) cylinder."""

    panels: list[str]
    angles: list[float]
    """[rad] centre angle of each panel (theta = 0 is the ref direction)"""
    origin: np.ndarray
    """[m] axis point where material y = 0"""
    axis: np.ndarray | None = None
    """unit vector of material +y; None: world up"""
    ref: np.ndarray | None = None
    """theta = 0 direction; None: world +z (front)"""
    body_radius: Callable[[np.ndarray], np.ndarray] | None = None
    """axial coordinate [m] -> body radius about the axis [m]: a circle the
    placement clears (at least), or where there is no ``section``, exactly"""
    margin: float = 0.015
    """[m] clearance from the body section"""
    min_margin: float = 0.007
    """[m] clearance a garment tighter than body + margin may go down to"""
    section: str | None = None
    """body section table about this axis (``couture.pattern.sections``); None:
    a circle of ``body_radius``"""
    gap_at: float | None = None
    """[rad] where the ring stays open (a trouser leg's half ring above the
    crotch); None: a closed ring, any shortfall shared by its seams"""
    anchor_y: float | None = None
    """material y placed at its own axial coordinate (the rows above and below
    it shorten toward it along the axis, keeping their meridian lengths); None:
    the top of the ring's panels"""
    top_rows_as_full: bool = False
    """rows above the highest one that every panel crosses at half its width or
    more keep that row's layout (free-form pieces with a curved top); False:
    every row laid out from its own widths"""
    landmark: str | None = None
    """'waist': ``origin`` lies at the default mannequin's waist height, and on
    another body the ring moves along its axis to that body's waist
    (``couture.bodies.measured``); 'neck': likewise at the neck's base
    (``couture.pattern.landmarks.neck``); None: placed where drafted on every body"""
    armpit_clear: float | None = None
    """[m] a top's ring (``landmark`` 'neck', ``top_rows_as_full``): the ring
    moves down, a row spacing at a time where it must, until no cloth from a
    little below the armholes' bottoms up (the highest row every panel
    crosses at half its width or more) lies within this distance of the
    body's surface, arms and shoulders included: a top whose shoulders' neck
    ends sit on the neck base but whose sides or straps would start in the
    arms or shoulders (a body whose neck stands higher over its armpits than
    the pattern's) starts clear of them; None: no check"""
    section_reach: float = 0.0
    """[m] each row's body radii are the largest of the section table's within
    this distance along the axis (a margin against a table row that
    undercuts the body: the default mannequin's leg table 2.4 cm at the
    thigh's front, 11 cm below the crotch); 0: the row's own"""


@dataclass
class BuiltinDart:
    """A dart that is part of the sloper (its size follows the options)."""

    id: str
    panel: str
    kind: str
    """'boundary' or 'interior'"""
    params: dict


@dataclass
class SloperDraft:
    panels: list[PanelDef]
    seams: list[tuple[str, str, str, str]] = field(default_factory=list)
    rings: list[Ring] = field(default_factory=list)
    darts: list[BuiltinDart] = field(default_factory=list)


@dataclass(frozen=True)
class SloperDef:
    kind: str
    options: tuple[Option, ...]
    draft: Callable[[dict[str, float]], SloperDraft]
    doc: str
    body_fitted: bool = False
    """the body-measurement options default to the design's body's measured
    values (:func:`couture.pattern.body_measures.body_options`), its waist
    height among them; False: the mannequin's, whatever body"""


MIRROR_X = np.array([-1.0, 1.0])
"""multiplies a material point to mirror it about x = 0"""


def mirrored(seg: SegDef, name: str | None = None) -> SegDef:
    """``seg`` mirrored about x = 0 and run backwards (so that a mirrored
    counter-clockwise outline stays counter-clockwise), named ``name`` (None:
    its own name)."""
    curves = [Curve(c.pts[::-1] * MIRROR_X) for c in reversed(seg.curves)]
    return SegDef(seg.name if name is None else name, curves)


def mirror_panel(
    name: str,
    right: list[SegDef],
    top: SegDef | list[SegDef] | None,
    bottom: SegDef | list[SegDef] | None,
) -> PanelDef:
    """A panel symmetric about x = 0 from its right half.

    ``right``: the right-side segments, bottom to top (CCW order on the right);
    ``top``/``bottom``: full-width segments crossing x = 0 (given whole; a
    list: consecutive pieces, in CCW order).
    Left segments are the mirrored right ones, renamed ``*_right -> *_left``.
    """
    segs = []
    if bottom is not None:
        segs.extend(bottom if isinstance(bottom, list) else [bottom])
    segs.extend(right)
    if top is not None:
        segs.extend(top if isinstance(top, list) else [top])
    segs.extend(mirrored(s, s.name.replace("_right", "_left")) for s in reversed(right))
    return PanelDef(name, segs)


def torso_ring(panels: list[str], y: float = M.WAIST_Y, **kw) -> Ring:
    """The panels wrapped round the torso, evenly spaced from the front
    (panel 0 centred at the front), material y = 0 at height ``y`` [m] (the
    mannequin's waist line by default); ``kw``: further :class:`Ring` fields."""
    n = len(panels)
    return Ring(
        panels, [2 * np.pi * i / n for i in range(n)], np.array([0.0, y, M.TORSO_AXIS_Z]), section="torso", **kw
    )

"""Slopers: base patterns drafted from body measurements and style options.

Each sloper is a function of its resolved options returning a
:class:`SloperDraft`: panels as chains of named segments, each segment a chain
of smooth curves (lines and cubic Béziers) whose control points are smooth
functions of the options, so drafting is differentiable in every non-integer
option. Material coordinates: metres, y up; for garments hung from the waist
y = 0 is the waist line, for sleeves y = 0 is the top of the cap.

One module per garment (``skirt``, ``dress``, ``shirt``, ``trousers``), each
ending in its :class:`SloperDef`, over ``base`` (the draft's data types,
mirroring, the torso ring) and ``parts`` (the skirt and bodice pieces, seams
and darts that several garments share). A new sloper is a module that
defines its options, its draft function and its ``SloperDef``, and one entry
in :data:`SLOPERS` below. Option tables are :data:`SLOPERS` ``[kind].options``.
"""

from __future__ import annotations

from couture.pattern.slopers.base import BuiltinDart, PanelDef, Ring, SegDef, SloperDef, SloperDraft
from couture.pattern.slopers.dress import (
    DART_MIN_WIDTH,
    DRESS,
    DRESS_OPTIONS,
    DRESS_WAIST,
    DRESS_WAIST_OPTIONS,
    draft_dress,
    draft_dress_waist,
    waist_dart_widths,
)
from couture.pattern.slopers.parts import BACK_NECK_DEPTH
from couture.pattern.slopers.shirt import (
    CAP_HEIGHT,
    COLLAR_DROP,
    NECK_Z,
    SHIRT,
    SHIRT_OPTIONS,
    SHIRT_SET_IN,
    SHIRT_SET_IN_OPTIONS,
    SLEEVE_DOWN,
    draft_shirt,
    draft_shirt_set_in,
    sleeve_cap,
)
from couture.pattern.slopers.skirt import SKIRT, SKIRT_OPTIONS, draft_skirt, skirt_panels
from couture.pattern.slopers.trousers import BAND_HEIGHT, CROTCH_EASE, TROUSERS, TROUSERS_OPTIONS, draft_trousers

SLOPERS: dict[str, SloperDef] = {s.kind: s for s in (SKIRT, DRESS, DRESS_WAIST, SHIRT, TROUSERS, SHIRT_SET_IN)}
"""sloper kind -> its option table and drafting function"""

__all__ = [
    "BACK_NECK_DEPTH",
    "BAND_HEIGHT",
    "CAP_HEIGHT",
    "COLLAR_DROP",
    "CROTCH_EASE",
    "DART_MIN_WIDTH",
    "DRESS_OPTIONS",
    "DRESS_WAIST_OPTIONS",
    "NECK_Z",
    "SHIRT_OPTIONS",
    "SHIRT_SET_IN_OPTIONS",
    "SKIRT_OPTIONS",
    "SLEEVE_DOWN",
    "SLOPERS",
    "TROUSERS_OPTIONS",
    "BuiltinDart",
    "PanelDef",
    "Ring",
    "SegDef",
    "SloperDef",
    "SloperDraft",
    "draft_dress",
    "draft_dress_waist",
    "draft_shirt",
    "draft_shirt_set_in",
    "draft_skirt",
    "draft_trousers",
    "skirt_panels",
    "sleeve_cap",
    "waist_dart_widths",
]

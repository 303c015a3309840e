"""Pattern options as data: every sloper option has a default, a min, a max and a unit.

Body measurements default to the mannequin's (:mod:`couture.pattern.mannequin`).
Options marked ``integer`` are topology options (e.g. the number of skirt
panels): changing one changes the number of panels/vertices, so they are not
differentiable and are excluded from the fixed-sample-count invariant.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from couture.pattern import mannequin as M
from couture.pattern.errors import PatternError


@dataclass(frozen=True)
class Option:
    name: str
    default: float
    min: float
    max: float
    unit: str
    """'m', 'rad', '1' (ratio) or 'count'"""
    doc: str
    integer: bool = False


def _body(name, default, lo, hi, doc):
    return Option(name, round(default, 3), lo, hi, "m", doc)


WAIST = _body("waist_girth", M.WAIST_GIRTH, 0.50, 1.30, "waist circumference (mannequin: smallest torso girth)")
HIP = _body("hip_girth", M.HIP_GIRTH, 0.70, 1.60, "hip circumference (mannequin: largest girth above the crotch)")
BUST = _body("bust_girth", M.BUST_GIRTH, 0.65, 1.50, "bust/chest circumference below the underarm")
WAIST_TO_HIP = _body("waist_to_hip", M.WAIST_Y - M.HIP_Y, 0.12, 0.34, "vertical distance waist to hip line")
WAIST_TO_UNDERARM = _body(
    "waist_to_underarm",
    M.UNDERARM_Y - M.WAIST_Y - 0.03,
    0.10,
    0.20,
    "waist to the underarm point of the side seam (2-3 cm below the armpit)",
)
WAIST_TO_SHOULDER = _body("waist_to_shoulder", M.SHOULDER_Y - M.WAIST_Y, 0.25, 0.45, "waist to shoulder tip height")
SHOULDER_WIDTH = _body("shoulder_width", 2 * M.SHOULDER_HALF_WIDTH, 0.30, 0.55, "shoulder tip to shoulder tip")
NECK_GIRTH = _body("neck_girth", M.NECK_GIRTH, 0.28, 0.50, "neck base circumference")
THIGH = _body("thigh_girth", M.THIGH_GIRTH, 0.40, 0.90, "one thigh, just below the crotch")
ANKLE = _body("ankle_girth", M.ANKLE_GIRTH, 0.17, 0.35, "one ankle")
CROTCH_DEPTH = _body("crotch_depth", M.WAIST_Y - M.CROTCH_Y, 0.20, 0.40, "waist to crotch, seated depth")
CROTCH_LENGTH = _body(
    "crotch_length", M.CROTCH_LENGTH, 0.45, 1.10, "front waist between the legs to back waist, along the body"
)
WAIST_HEIGHT = _body(
    "waist_height", M.WAIST_Y - M.FLOOR_Y, 0.80, 1.30, "waist line above the floor (places the garment on the body)"
)
ARM_GIRTH = _body("upper_arm_girth", M.UPPER_ARM_GIRTH, 0.20, 0.50, "upper arm circumference")


def opt(name, default, lo, hi, unit, doc, integer=False):
    return Option(name, default, lo, hi, unit, doc, integer)


def resolve(options: tuple[Option, ...], params: dict[str, float]) -> dict[str, float]:
    """Options' values: defaults overridden by params, each checked against its range."""
    known = {o.name: o for o in options}
    for name in params:
        if name not in known:
            raise PatternError(f"param:{name}", f"unknown option {name!r}; options are {sorted(known)}")
    out = {}
    for o in options:
        v = params.get(o.name, o.default)
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise PatternError(f"param:{o.name}", f"value {v!r} is not a number") from None
        if not np.isfinite(v):
            raise PatternError(f"param:{o.name}", f"value {v} is not finite")
        if not (o.min <= v <= o.max):
            raise PatternError(f"param:{o.name}", f"value {v:g} {o.unit} is outside [{o.min:g}, {o.max:g}] {o.unit}")
        if o.integer and v != round(v):
            raise PatternError(f"param:{o.name}", f"value {v:g} must be a whole number in [{o.min:g}, {o.max:g}]")
        out[o.name] = v
    return out

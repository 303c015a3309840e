"""Shirts: the block with a simple sleeve cap (``shirt``) and the one with
set-in sleeves and a stand collar (``shirt_set_in``), over the same bodice
pieces, sleeve and placement about the arms."""

from __future__ import annotations

import numpy as np

from couture.pattern import mannequin as M
from couture.pattern import options as O
from couture.pattern.geometry import Curve, bezier, line
from couture.pattern.options import opt
from couture.pattern.slopers.base import (
    MIRROR_X,
    PanelDef,
    Ring,
    SegDef,
    SloperDef,
    SloperDraft,
    mirror_panel,
    torso_ring,
)
from couture.pattern.slopers.parts import (
    BACK_NECK_DEPTH,
    bodice_half,
    bodice_right,
    neck_depths,
    shoulder_seams,
    side_seams,
)

# ---------------------------------------------------------------- pieces of both shirts


def _hem_line(p: dict[str, float]):
    """(bw, C, W, hem): a shirt bodice's half width at the bust, its hem corner
    C (straight down from the wider of bust and hip), the side's waist point W
    (halfway out to it) and the straight hem."""
    bw = (p["bust_girth"] + p["ease"]) / 2
    hw = (p["hip_girth"] + p["ease"]) / 2
    C = np.array([max(hw, bw) / 2, -p["length"]])
    W = np.array([bw / 2 + 0.5 * (C[0] - bw / 2), 0.0])
    return bw, C, W, SegDef("hem", [line(C * MIRROR_X, C)])


def _cap_curve(sw: float, ch: float) -> Curve:
    """Right half of a sleeve cap, underarm point (sw, -ch) to the cap top (0, 0)."""
    B = np.array([sw, -ch])
    return bezier(B, B + np.array([-0.35 * sw, 0.15 * ch]), np.array([0.45 * sw, 0.0]), np.zeros(2))


def _sleeves(cap: Curve, cw: float, sl: float) -> tuple[list[PanelDef], list[tuple[str, str, str, str]]]:
    """The left and right sleeves (cap top at (0, 0), its right half ``cap``,
    cuff ``2 cw`` wide at y = -``sl``) and their underarm seams."""
    B, Cf = cap.pts[0], np.array([cw, -sl])
    cap_r = SegDef("cap_right", [cap])
    cap_l = SegDef("cap_left", [Curve(cap.pts[::-1] * MIRROR_X)])
    under_r = SegDef("underarm_right", [line(Cf, B)])
    under_l = SegDef("underarm_left", [line(B * MIRROR_X, Cf * MIRROR_X)])
    cuff = SegDef("cuff", [line(Cf * MIRROR_X, Cf)])
    names = ("sleeve_left", "sleeve_right")
    panels = [PanelDef(name, [cuff, under_r, cap_r, cap_l, under_l]) for name in names]
    return panels, [(name, "underarm_right", name, "underarm_left") for name in names]


def _arm_frame(sign: float):
    a = M.LEFT_ARM_AXIS * np.array([sign, 1.0, 1.0])
    a = a / np.linalg.norm(a)
    v = np.array([sign, 1.0, 0.0]) / np.sqrt(2)
    f = v - (v @ a) * a
    return a, f / np.linalg.norm(f)


def _cap_radius(ym):
    """A sleeve cap's clearance about the arm axis near the shoulder, where the
    arm section table (arm vertices only) does not see the shoulder."""
    return np.where(np.asarray(ym) > -0.10, M.ARM_RADIUS, 0.0)


def _sleeve_rings(seams: list[tuple[str, str, str, str]], down: float = 0.03) -> list[Ring]:
    """One ring per sleeve about its arm's placement axis (the cap top a little
    down the arm from the shoulder); appends the cap-to-armhole seams to
    ``seams``, each cap half sewn to the armhole on the side it faces. ``down``
    [m]: the cap top's distance down the arm axis from the arm root point."""
    rings = []
    for name, sign in (("sleeve_left", 1.0), ("sleeve_right", -1.0)):
        a, f = _arm_frame(sign)
        b = np.cross(a, f)
        # sleeve material +x points along b: the cap half on that side faces front (b_z > 0) or back
        plus_front = b[2] > 0
        # the armhole on this arm's side: front/back 'armhole_left' is at world -x... material +x of
        # front is world +x (left arm); of back is world -x
        front_arm = "armhole_right" if sign > 0 else "armhole_left"
        back_arm = "armhole_left" if sign > 0 else "armhole_right"
        if plus_front:
            seams += [(name, "cap_right", "front", front_arm), (name, "cap_left", "back", back_arm)]
        else:
            seams += [(name, "cap_right", "back", back_arm), (name, "cap_left", "front", front_arm)]
        # cap top a little down the arm, clear of the shoulder
        origin = M.LEFT_ARM_SHOULDER * np.array([sign, 1.0, 1.0]) - down * a
        rings.append(
            Ring(
                [name],
                [0.0],
                origin,
                axis=a,
                ref=f,
                body_radius=_cap_radius,
                section="left_arm" if sign > 0 else "right_arm",
            )
        )
    return rings


# ---------------------------------------------------------------- shirt

# the option rows both shirts share
_LENGTH = opt("length", 0.20, 0.05, 0.45, "m", "waist to hem")
_EASE = opt("ease", 0.10, 0.02, 0.30, "m", "added to bust and hip girths")
_CUFF = opt("cuff", 0.30, 0.18, 0.50, "m", "sleeve hem circumference")
_FRONT_NECK_DEPTH = opt("front_neck_depth", 0.06, 0.01, 0.15, "m", "front neckline drop")

SHIRT_OPTIONS = (
    O.BUST,
    O.WAIST_TO_UNDERARM,
    O.WAIST_TO_SHOULDER,
    O.SHOULDER_WIDTH,
    O.NECK_GIRTH,
    O.ARM_GIRTH,
    O.HIP,
    _LENGTH,
    _EASE,
    opt("sleeve_length", 0.22, 0.18, 0.40, "m", "cap top to sleeve hem (short to below the elbow)"),
    opt("sleeve_ease", 0.06, 0.02, 0.20, "m", "added to the upper arm girth"),
    _CUFF,
    opt("cap_height", 0.10, 0.05, 0.14, "m", "sleeve cap height"),
    _FRONT_NECK_DEPTH,
)


def draft_shirt(p: dict[str, float]) -> SloperDraft:
    """Shirt block with set-in sleeves: front, back, left and right sleeves."""
    panels = []
    for name, depth in neck_depths(p):
        bw, C, W, hem = _hem_line(p)
        right, neck = bodice_right(p, 2 * W[0], bw, depth, [line(C, W)], W)
        panels.append(mirror_panel(name, right, neck, hem))
    sleeves, sleeve_seams = _sleeves(
        _cap_curve((p["upper_arm_girth"] + p["sleeve_ease"]) / 2, p["cap_height"]), p["cuff"] / 2, p["sleeve_length"]
    )
    panels += sleeves
    seams = side_seams("front", "back") + shoulder_seams("front", "back") + sleeve_seams
    rings = [torso_ring(["front", "back"])]
    rings += _sleeve_rings(seams)
    return SloperDraft(panels, seams, rings)


# ---------------------------------------------------------------- shirt with set-in sleeves and a stand collar

SHIRT_SET_IN_OPTIONS = (
    O.BUST,
    O.HIP,
    O.WAIST_TO_UNDERARM,
    O.WAIST_TO_SHOULDER,
    O.SHOULDER_WIDTH,
    O.NECK_GIRTH,
    O.ARM_GIRTH,
    O.WAIST_HEIGHT,
    _LENGTH,
    _EASE,
    opt("armhole_drop", 0.04, 0.0, 0.08, "m", "bodice underarm point below the waist_to_underarm line"),
    opt("neck_ease", 0.08, 0.0, 0.15, "m", "added to the neck girth for the neckline width"),
    _FRONT_NECK_DEPTH,
    opt("sleeve_length", 0.22, 0.15, 0.40, "m", "cap top to sleeve hem (short to below the elbow)"),
    opt("sleeve_ease", 0.04, 0.02, 0.20, "m", "added to the upper arm girth: the sleeve's width at the underarm"),
    opt("cap_ease", 0.02, 0.0, 0.05, "m", "sleeve cap seam length minus the armhole length (both halves), eased in"),
    _CUFF,
    opt("collar_height", 0.03, 0.015, 0.06, "m", "stand collar (band) height"),
)
SLEEVE_DOWN = 0.03
"""[m] a set-in sleeve's cap top this far down its arm axis from the arm root point"""
COLLAR_DROP = -0.005
"""[m] the collar's seam line starts this far below the neck points (at the neck's centre line; < 0: above)"""
NECK_Z = 0.024
"""[m] z of the neck's centre at the neckline (every shipped body shares the pose)"""


def _set_in_bodice(p, depth: float) -> tuple[list[SegDef], SegDef, SegDef]:
    """Right half (hem corner up: side, armhole, shoulder), the neck and the
    hem of a shirt bodice whose armhole is a smooth curve from the underarm
    point U (dropped ``armhole_drop`` below the underarm line) to the shoulder
    point S, meeting the side seam square (horizontal tangent at U)."""
    bw, C, W, hem = _hem_line(p)
    hu, hs = p["waist_to_underarm"] - p["armhole_drop"], p["waist_to_shoulder"]
    U = np.array([bw / 2, hu])
    S = np.array([p["shoulder_width"] / 2, hs])
    nr = (p["neck_girth"] + p["neck_ease"]) / (2 * np.pi) + 0.01
    N = np.array([nr, hs + 0.025])
    d = hs - hu
    scoop = min(0.35 * max(U[0] - S[0], 0.0) + 0.02, 0.6 * (U[0] - N[0]))
    arm = bezier(U, U + np.array([-scoop, 0.0]), S + np.array([-0.012, -0.45 * d]), S)
    right, neck = bodice_half([line(C, W)], W, U, S, N, nr, depth, arm)
    return right, neck, hem


CAP_HEIGHT = (0.04, 0.16)
"""[m] the cap heights a sleeve is drafted with; beyond them the sleeve's width gives"""


def _solve(f, lo: float, hi: float) -> float | None:
    from scipy.optimize import brentq

    if f(lo) > 0 or f(hi) < 0:
        return None
    return float(brentq(f, lo, hi, xtol=1e-12))


def sleeve_cap(sw: float, target: float, ch_max: float) -> tuple[float, float]:
    """(half width, cap height) [m] of a sleeve whose half cap (:func:`_cap_curve`)
    is ``target`` long: the height solved for the half width ``sw`` (the cap's
    length grows with both); where that height falls outside
    ``CAP_HEIGHT[0], min(CAP_HEIGHT[1], ch_max)`` it is held at that bound and
    the width is solved instead (a wider or narrower sleeve than the arm asked
    for: the armhole decides, as in drafting by hand)."""
    lo, hi = CAP_HEIGHT[0], min(CAP_HEIGHT[1], ch_max)
    ch = _solve(lambda c: _cap_curve(sw, c).length(256) - target, lo, hi)
    if ch is not None:
        return sw, ch
    ch = lo if _cap_curve(sw, lo).length(256) > target else hi
    w = _solve(lambda x: _cap_curve(x, ch).length(256) - target, 1e-3, 2.0)
    if w is None:
        raise ValueError(f"no sleeve has a half cap of {target:.3f} m")
    return w, ch


def _collar(necks: dict[str, SegDef], ht: float) -> tuple[list[PanelDef], dict[str, float]]:
    """A straight band per bodice, as long as its neckline and ``ht`` high,
    material y = 0 at the seam; with each neckline's length [m]."""
    panels = []
    neck_len = {}
    for name in ("front", "back"):
        half = 0.5 * sum(c.length(256) for c in necks[name].curves)
        neck_len[name] = 2 * half
        L0, R0 = np.array([-half, 0.0]), np.array([half, 0.0])
        L1, R1 = L0 + np.array([0.0, ht]), R0 + np.array([0.0, ht])
        panels.append(
            PanelDef(
                f"collar_{name}",
                [
                    SegDef("neck_seam", [line(L0, R0)]),
                    SegDef("end_right", [line(R0, R1)]),
                    SegDef("top", [line(R1, L1)]),
                    SegDef("end_left", [line(L1, L0)]),
                ],
            )
        )
    return panels, neck_len


def draft_shirt_set_in(p: dict[str, float]) -> SloperDraft:
    """Shirt with set-in sleeves and a stand collar, drafted from the body's
    measurements (the options default to the body a design names). Front and
    back bodices with curved armholes; sleeves whose cap (its height solved
    so the cap seam is the armhole's length plus ``cap_ease``, the sleeve's
    width solved instead where that height leaves ``CAP_HEIGHT``) is sewn
    round the armhole, underarm sleeve seams; side and shoulder seams; a two-piece stand
    collar (front and back band, sewn at the neck points) whose lower edge is
    the neckline, sewn to it."""
    from couture.pattern.errors import PatternError

    panels = []
    necks = {}
    arm_len = 0.0
    for name, depth in neck_depths(p):
        right, neck, hem = _set_in_bodice(p, depth)
        panels.append(mirror_panel(name, right, neck, hem))
        necks[name] = neck
        arm_len = sum(c.length(256) for c in right[1].curves)
    # sleeve: cap top at (0, 0), underarm at y = -ch, cuff at y = -sleeve_length
    sw = (p["upper_arm_girth"] + p["sleeve_ease"]) / 2
    sl = p["sleeve_length"]
    try:
        sw, ch = sleeve_cap(sw, arm_len + p["cap_ease"] / 2, sl - 0.05)
    except ValueError as e:
        raise PatternError("param:cap_ease", f"the sleeve cannot be set into the armhole: {e}") from None
    sleeves, sleeve_seams = _sleeves(_cap_curve(sw, ch), p["cuff"] / 2, sl)
    collars, neck_len = _collar(necks, p["collar_height"])
    panels += sleeves + collars
    seams = side_seams("front", "back") + shoulder_seams("front", "back") + sleeve_seams
    seams += [
        ("front", "neck", "collar_front", "neck_seam"),
        ("back", "neck", "collar_back", "neck_seam"),
        ("collar_front", "end_right", "collar_back", "end_left"),
        ("collar_back", "end_right", "collar_front", "end_left"),
    ]
    y_waist = M.FLOOR_Y + p["waist_height"]
    rings = [torso_ring(["front", "back"], y_waist)]
    rings += _sleeve_rings(seams, SLEEVE_DOWN)
    # the collar starts round the neck just above the neck points (the neck is
    # narrow there, below the chin; the neckline itself lies on the shoulders
    # and chest, where a band of the neckline's length would cross the body),
    # on an axis tilted forward as the neckline is (front lower than back); the
    # first solve sews it down. The neck is an ellipse: the circle it clears
    # is 1.2 times the radius of its girth.
    dip = p["front_neck_depth"] - BACK_NECK_DEPTH
    r_collar = (neck_len["front"] + neck_len["back"]) / (2 * np.pi)
    a = np.array([0.0, 2 * r_collar, dip])
    a /= np.linalg.norm(a)
    y_seam = p["waist_to_shoulder"] + 0.025 - COLLAR_DROP
    r_neck = 1.2 * p["neck_girth"] / (2 * np.pi)
    rings.append(
        Ring(
            ["collar_front", "collar_back"],
            [0.0, np.pi],
            np.array([0.0, y_waist + y_seam, NECK_Z]),
            axis=a,
            ref=np.array([0.0, 0.0, 1.0]),
            body_radius=lambda ym: np.full(np.shape(ym), r_neck),
            margin=0.008,
            min_margin=0.004,
        )
    )
    return SloperDraft(panels, seams, rings)


SHIRT = SloperDef("shirt", SHIRT_OPTIONS, draft_shirt, draft_shirt.__doc__ or "")
SHIRT_SET_IN = SloperDef(
    "shirt_set_in", SHIRT_SET_IN_OPTIONS, draft_shirt_set_in, draft_shirt_set_in.__doc__ or "", body_fitted=True
)

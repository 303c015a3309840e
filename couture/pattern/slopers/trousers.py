"""Trousers: a front and a back panel per leg and an elastic waistband."""

from __future__ import annotations

import numpy as np

from couture.pattern import mannequin as M
from couture.pattern import options as O
from couture.pattern.geometry import Curve, bezier, line
from couture.pattern.options import opt
from couture.pattern.slopers.base import PanelDef, Ring, SegDef, SloperDef, SloperDraft, mirrored, torso_ring

CROTCH_EASE = 0.10
"""[m] default crotch ease of the trousers (``draft_trousers``): the cloth keeps
the 1 cm contact offset off the body, which adds about pi x 1 cm = 3 cm round the
half turn from front waist to back waist, plus 7 cm of wearing ease (a pull-on
trouser's relaxed rise). With 8 cm the top settled up to 1.5 cm down on some
meshes of L and XS (600-800 vertices); with 10 cm at most 0.8 cm on every
shipped body at 400-1600 vertices"""
BAND_HEIGHT = 0.035
"""[m] default height of the trousers' waistband piece (``draft_trousers``)"""

TROUSERS_OPTIONS = (
    O.WAIST,
    O.HIP,
    O.WAIST_TO_HIP,
    O.CROTCH_DEPTH,
    O.CROTCH_LENGTH,
    O.THIGH,
    O.ANKLE,
    opt("length", 0.95, 0.40, 1.10, "m", "waist to hem along the side seam"),
    opt("waist_ease", 0.02, 0.0, 0.10, "m", "added to the waist girth"),
    opt(
        "waistband",
        0.75,
        0.60,
        1.00,
        "1",
        "elastic waistband: the waist edge's rest length as a fraction of waist girth + ease (1: none)",
    ),
    opt(
        "band_height",
        BAND_HEIGHT,
        0.02,
        0.08,
        "m",
        "height of the elastic waistband piece sewn to the waist edge, centred on the waist",
    ),
    opt("hip_ease", 0.05, 0.0, 0.15, "m", "added to the hip girth"),
    opt(
        "crotch_ease",
        CROTCH_EASE,
        0.0,
        0.20,
        "m",
        "added to the crotch length: the centre seam, front waist between the legs to back waist, is this much longer",
    ),
    opt("hem_ease", 0.10, 0.0, 0.40, "m", "added to the ankle girth at the hem"),
    opt("crotch_extension", 0.05, 0.02, 0.10, "m", "how far the crotch point reaches past the centre line"),
)


def _centre_seam(cd: float, ext: float) -> Curve:
    """A leg panel's centre seam, from the centre waist (0, 0) down round belly
    or seat to the crotch point (-ext, -cd)."""
    return bezier(
        np.array([0.0, 0.0]),
        np.array([0.0, -0.5 * cd]),
        np.array([-0.6 * ext, -0.75 * cd]),
        np.array([-ext, -cd]),
    )


def _rise(length: float, ext: float) -> float:
    """The drafted rise cd [m] whose centre seam (``_centre_seam``) is ``length``
    long (its length grows monotonically with cd; bisection to 0.1 mm)."""
    if length <= ext:
        raise ValueError(
            f"trousers: centre seam length {length:.3f} m is not longer than the crotch extension {ext:.3f} m"
        )
    lo, hi = 0.0, length
    while hi - lo > 1e-4:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _centre_seam(mid, ext).length() < length else (lo, mid)
    return 0.5 * (lo + hi)


def draft_trousers(p: dict[str, float]) -> SloperDraft:
    """Trousers: front and back panel per leg, and a waistband. Each leg
    panel: material x grows from the centre (crotch) edge to the side seam for
    the left leg (mirrored for the right leg so every outline stays
    counter-clockwise).

    The waistband is elastic: its rest length is ``waistband`` times the waist
    girth + ease, shorter than the body's waist, so it stays stretched around
    the waist and its hoop tension presses the garment onto the body (the way
    an elastic is cut shorter than the waist it grips). It is a piece of its
    own (``band_height`` high, centred on the waist, front and back joined at
    the sides) wrapped round the torso, so it is placed snug on the body at the
    natural waist; the leg panels' waist edges, cut to the same length, are
    sewn to its lower edge, and their sides run from there to the hip width,
    so the grip fades toward the hip. The rise is drafted from the body's
    crotch length (front waist between the legs to back waist, along the body)
    + ``crotch_ease``: the band's height below the waist plus the front and
    back panels' centre seams make up that length. A rise drafted from the
    vertical crotch depth is too short, the more so the rounder the belly and
    seat: the crotch bears up into the body's crotch and pulls the waist down
    (by 1.4 N with no ease on the default body, more than the trousers' 1.3 N
    weight; with a fixed 6 cm added to the crotch depth the centre seam was
    4.4 cm longer than the default body's crotch length but 0.8 cm on XL, whose
    band slid 2.4 cm). The elastic (0.75 of the waist) holds the band against
    what pull remains on a waist whose girth grows by less than 1 cm in the
    2-3 cm below it on every graded body: at 0.8 with the rise from the crotch length XL still slid
    1.4 cm. With no elastic (``waistband`` 1) the default 20 N/m fabric cannot
    carry the trousers' weight at the waist and they slide down toward the
    hip."""
    bh = p["band_height"]
    # the band covers the waist +- bh/2: the legs' panels start bh/2 below it
    h, L = p["waist_to_hip"] - bh / 2, p["length"] - bh / 2
    ext = p["crotch_extension"]
    # the drafted rise: band (bh / 2 below the waist) + front and back centre seams = crotch length + ease
    cd = _rise((p["crotch_length"] + p["crotch_ease"] - bh) / 2, ext)
    ww = p["waistband"] * (p["waist_girth"] + p["waist_ease"]) / 4
    wh = (p["hip_girth"] + p["hip_ease"]) / 4
    hem_w = (p["ankle_girth"] + p["hem_ease"]) / 2
    thigh_w = (p["thigh_girth"] + 0.06) / 2
    hh = min(h, 0.9 * (p["crotch_depth"] - bh / 2))  # the hip line stays above the body's crotch
    panels = []
    # left-leg front panel, centre at x = 0 edge, side seam at x = +wh
    Wc = np.array([0.0, 0.0])  # centre waist
    Ws = np.array([ww, 0.0])  # side waist
    Hs = np.array([wh, -hh])
    Cr = np.array([-ext, -cd])  # crotch point
    # leg hem centred under the knee line: x mid of thigh
    mid = 0.5 * (wh - ext)
    K_in = np.array([mid - thigh_w / 2 + 0.01, -cd - 0.05])
    Hem_in = np.array([mid - hem_w / 2, -L])
    Hem_out = np.array([mid + hem_w / 2, -L])
    segs = [
        SegDef("hem", [line(Hem_in, Hem_out)]),
        SegDef(
            "side",
            [
                bezier(Hem_out, Hem_out + np.array([0.0, 0.3 * (L - hh)]), Hs + np.array([0.0, -0.3 * (L - hh)]), Hs),
                bezier(Hs, Hs + np.array([0, hh / 3]), Ws + np.array([0, -hh / 3]), Ws),
            ],
        ),
        SegDef("waist", [line(Ws, Wc)]),
        SegDef("center", [_centre_seam(cd, ext)]),
        SegDef(
            "inseam",
            [
                bezier(Cr, K_in + np.array([-0.02, 0.03]), K_in, K_in + np.array([0.0, -0.05])),
                line(K_in + np.array([0.0, -0.05]), Hem_in),
            ],
        ),
    ]
    # the crotch extension is deeper at the back
    for name in ("front_left", "back_left", "front_right", "back_right"):
        # material +x must run with the wrap angle: outward for the left front and
        # right back, toward the centre for the other two (mirrored drafts)
        mirror = name in ("back_left", "front_right")
        s = [mirrored(sg) for sg in reversed(segs)] if mirror else segs
        panels.append(PanelDef(name, [SegDef(sg.name, list(sg.curves)) for sg in s]))
    seams = [
        ("front_left", "side", "back_left", "side"),
        ("front_left", "inseam", "back_left", "inseam"),
        ("front_right", "side", "back_right", "side"),
        ("front_right", "inseam", "back_right", "inseam"),
        ("front_left", "center", "front_right", "center"),
        ("back_left", "center", "back_right", "center"),
    ]
    rings: list[Ring] = []
    _waistband(panels, seams, rings, 2 * ww, bh)
    for leg, sign in (("left", 1.0), ("right", -1.0)):
        a = M.LEFT_LEG_AXIS * np.array([sign, 1.0, 1.0])
        a = a / np.linalg.norm(a)
        top = M.LEFT_LEG_TOP * np.array([sign, 1.0, 1.0])
        # axis point at the waist line (material y = 0)
        origin = top + a * ((M.WAIST_Y - bh / 2 - top[1]) / a[1])
        f = np.array([0.0, 0.0, 1.0]) - a[2] * a
        f /= np.linalg.norm(f)
        # one leg's front and back panels wrap its leg (with its half of the
        # pelvis above the crotch) starting from the inner side, where the ring
        # stays open: there the centre seams meet the other leg's panels.
        # Material +x runs with the wrap angle: the left leg goes inner-front ->
        # side -> back, the right leg inner-back -> side -> front.
        b = np.cross(a, f)
        inner = np.array([-sign, 0.0, 0.0])
        order = [f"front_{leg}", f"back_{leg}"] if sign > 0 else [f"back_{leg}", f"front_{leg}"]
        rings.append(
            Ring(
                order,
                [0.0, np.pi],
                origin,
                axis=a,
                ref=f,
                margin=0.02,
                section=f"{leg}_leg",
                gap_at=float(np.arctan2(inner @ b, inner @ f)),
                landmark="waist",  # the waistband sits at each body's own waist
            )
        )
    return SloperDraft(panels, seams, rings)


def _waistband(panels: list[PanelDef], seams: list, rings: list[Ring], half: float, bh: float) -> None:
    """The trousers' waistband: a front and a back piece, each ``half`` [m] long
    and ``bh`` high, joined at the side seams, wrapped round the torso at the
    waist (a closed ring: the band is placed snug on the body, its shortfall
    shared by its side seams) and sewn along its lower edge to the four leg
    panels' waist edges. Material +x runs with the wrap angle (front: toward
    the left leg, back: from the left leg to the right)."""
    x0, x1 = -half / 2, half / 2
    for name, lo_half, hi_half in (
        ("band_front", "waist_right", "waist_left"),
        ("band_back", "waist_left", "waist_right"),
    ):
        left_side = "side_left" if name == "band_front" else "side_right"
        right_side = "side_right" if name == "band_front" else "side_left"
        panels.append(
            PanelDef(
                name,
                [
                    SegDef(lo_half, [line(np.array([x0, 0.0]), np.array([0.0, 0.0]))]),
                    SegDef(hi_half, [line(np.array([0.0, 0.0]), np.array([x1, 0.0]))]),
                    SegDef(left_side, [line(np.array([x1, 0.0]), np.array([x1, bh]))]),
                    # the casing: the top edge turned down over the elastic, a hem
                    SegDef("hem", [line(np.array([x1, bh]), np.array([x0, bh]))]),
                    SegDef(right_side, [line(np.array([x0, bh]), np.array([x0, 0.0]))]),
                ],
            )
        )
    seams += [
        ("band_front", "side_left", "band_back", "side_left"),
        ("band_front", "side_right", "band_back", "side_right"),
        ("band_front", "waist_left", "front_left", "waist"),
        ("band_front", "waist_right", "front_right", "waist"),
        ("band_back", "waist_left", "back_left", "waist"),
        ("band_back", "waist_right", "back_right", "waist"),
    ]
    rings.append(torso_ring(["band_front", "band_back"], M.WAIST_Y - bh / 2, landmark="waist"))


TROUSERS = SloperDef("trousers", TROUSERS_OPTIONS, draft_trousers, draft_trousers.__doc__ or "", body_fitted=True)

"""Dresses: the one-piece sheath (``dress``) and the dress with a waist seam
(``dress_waist``), over the same bodice and skirt pieces and option rows."""

from __future__ import annotations

import numpy as np

from couture.pattern import mannequin as M
from couture.pattern import options as O
from couture.pattern.geometry import line
from couture.pattern.options import Option, opt
from couture.pattern.slopers.base import BuiltinDart, SegDef, SloperDef, SloperDraft, mirror_panel, torso_ring
from couture.pattern.slopers.parts import (
    bodice_right,
    bust_darts,
    hem,
    neck_depths,
    shoulder_seams,
    side_seams,
    skirt_side,
)


def _dress_options(
    body: tuple[Option, ...], length_doc: str, flare_doc: str, waist_ease: Option, shaping: tuple[Option, ...]
) -> tuple[Option, ...]:
    """A dress's option table: the bodice's body measurements (and ``body``),
    the skirt's length and flare, the eases, the ``shaping`` darts' options,
    the bust darts and the neckline."""
    return (
        O.BUST,
        O.WAIST,
        O.HIP,
        O.WAIST_TO_HIP,
        O.WAIST_TO_UNDERARM,
        O.WAIST_TO_SHOULDER,
        O.SHOULDER_WIDTH,
        O.NECK_GIRTH,
        *body,
        opt("length", 0.55, 0.38, 1.00, "m", length_doc),
        opt("flare", 0.06, 0.0, 0.40, "rad", flare_doc),
        opt("bust_ease", 0.06, 0.0, 0.20, "m", "added to the bust girth"),
        waist_ease,
        opt("hip_ease", 0.05, 0.0, 0.15, "m", "added to the hip girth"),
        *shaping,
        opt("bust_dart_width", 0.015, 0.0, 0.04, "m", "width of the front armhole bust darts"),
        opt("front_neck_depth", 0.07, 0.01, 0.20, "m", "front neckline drop below the neck point"),
    )


# ---------------------------------------------------------------- one-piece dress

DRESS_OPTIONS = _dress_options(
    (),
    "waist to hem",
    "side seam angle below the hip",
    opt("waist_ease", 0.04, 0.0, 0.15, "m", "added to the waist girth"),
    (opt("waist_dart_width", 0.02, 0.005, 0.04, "m", "width of each of the 4 waist (diamond) darts"),),
)


def draft_dress(p: dict[str, float]) -> SloperDraft:
    """Fitted sheath dress: front and back, each one piece from shoulder to hem,
    shaped by waist diamond darts (interior) and armhole bust darts (boundary)."""
    dw = p["waist_dart_width"]
    ww = (p["waist_girth"] + p["waist_ease"]) / 2 + 2 * dw  # side-seam waist width incl. 2 darts
    bw = (p["bust_girth"] + p["bust_ease"]) / 2
    wh = (p["hip_girth"] + p["hip_ease"]) / 2
    panels = []
    for name, depth in neck_depths(p):
        side, C, k, f = skirt_side(ww, wh, p["waist_to_hip"], p["length"], p["flare"])
        right, neck = bodice_right(p, ww, bw, depth, side, side[-1].pts[-1])
        panels.append(mirror_panel(name, right, neck, hem(C, k, f)))
    seams = side_seams("front", "back") + shoulder_seams("front", "back")
    darts = [
        BuiltinDart(
            f"{name}.waist_dart_{side_name}",
            name,
            "interior",
            {"anchor": "hem", "position": pos, "depth": p["length"] - 0.02, "width": dw, "length": 0.30, "offset": 0.0},
        )
        for name in ("front", "back")
        for side_name, pos in (("l", 0.30), ("r", 0.70))
    ]
    darts += bust_darts(p, "front")
    return SloperDraft(panels, seams, [torso_ring(["front", "back"])], darts)


# ---------------------------------------------------------------- waist-seamed dress

DRESS_WAIST_OPTIONS = _dress_options(
    (O.WAIST_HEIGHT,),
    "waist to hem (the skirt)",
    "skirt side seam angle below the hip",
    opt("waist_ease", 0.03, 0.0, 0.15, "m", "added to the waist girth (bodice and skirt waist, darts closed)"),
    (
        opt(
            "bodice_dart_share",
            0.5,
            0.1,
            0.9,
            "1",
            "share of the bodice's bust-to-waist reduction taken by its 4 waist darts (the side seams take the rest)",
        ),
        opt(
            "skirt_dart_share",
            0.4,
            0.1,
            0.9,
            "1",
            "share of the skirt's hip-to-waist reduction taken by its 4 waist darts (the side seams take the rest)",
        ),
        opt("bodice_dart_length", 0.11, 0.05, 0.16, "m", "bodice waist dart: waist to its point (below the bust)"),
        opt("skirt_dart_length", 0.10, 0.05, 0.14, "m", "skirt waist dart: waist to its point (above the hip)"),
    ),
)

DART_MIN_WIDTH = 0.005
"""[m] narrowest waist dart (a body whose waist is not smaller than its bust or hip)"""


def waist_dart_widths(p: dict[str, float]) -> tuple[float, float, float]:
    """(bodice dart width, skirt dart width, waist girth with ease) [m] of the
    waist-seamed dress: each of the 4 darts of a tier takes a quarter of its
    share of that tier's girth reduction to the waist (bust - waist for the
    bodice, hip - waist for the skirt), at least ``DART_MIN_WIDTH``."""
    w = p["waist_girth"] + p["waist_ease"]
    dwb = max(p["bodice_dart_share"] * (p["bust_girth"] + p["bust_ease"] - w) / 4, DART_MIN_WIDTH)
    dws = max(p["skirt_dart_share"] * (p["hip_girth"] + p["hip_ease"] - w) / 4, DART_MIN_WIDTH)
    return dwb, dws, w


def _waist_edge(a: float, c: float, dw: float, depth: float, ids: tuple[str, str], reverse: bool) -> list[SegDef]:
    """A panel's waist edge at y = 0 from x = -a to x = a (``reverse``: a to -a),
    as pieces ``waist_left``, ``waist_center``, ``waist_right`` with a dart of
    width ``dw`` centred at x = -c and x = c between them (``ids``: left, right
    dart), its point ``depth`` away along +y (negative: down). Each dart's legs
    are the segments ``dart:<id>:left`` (the first along the edge) and
    ``dart:<id>:right``, named as :mod:`couture.pattern.draft` names a stroke dart's."""
    xs = [-a, -c - dw / 2, -c, -c + dw / 2, c - dw / 2, c, c + dw / 2, a]
    P = [np.array([x, 0.0]) for x in xs]
    P[2] = np.array([-c, depth])
    P[5] = np.array([c, depth])
    names = [
        "waist_left",
        f"dart:{ids[0]}:left",
        f"dart:{ids[0]}:right",
        "waist_center",
        f"dart:{ids[1]}:left",
        f"dart:{ids[1]}:right",
        "waist_right",
    ]
    if reverse:
        P = P[::-1]
        names = ["waist_right", f"dart:{ids[1]}:left", f"dart:{ids[1]}:right", "waist_center"]
        names += [f"dart:{ids[0]}:left", f"dart:{ids[0]}:right", "waist_left"]
    return [SegDef(n, [line(P[i], P[i + 1])]) for i, n in enumerate(names)]


def draft_dress_waist(p: dict[str, float]) -> SloperDraft:
    """Dress with a waist seam: bodice front and back (waist darts, front
    armhole bust darts; side and shoulder seams) sewn at the waist to skirt
    front and back (waist darts; side seams). Each tier's waist darts take a
    share of its girth reduction to the waist (``bodice_dart_share``,
    ``skirt_dart_share``); the darts of bodice and skirt sit one above the
    other and the waist is sewn piece by piece (side to dart, dart to dart),
    so with the darts closed both sides of every waist seam have the same
    length and the waist measures waist girth + ease. Drafted from the body's
    measurements: the design's body's measured girths and lengths by default
    (``body_fitted``)."""
    dwb, dws, w = waist_dart_widths(p)
    # dart centres at the waist: near the bust points (about 0.105 bust girth from the centre line)
    c_b = 0.105 * p["bust_girth"]
    c_s = c_b + (dws - dwb) / 2  # skirt centre piece as long as the bodice's
    a_b, a_s = w / 4 + dwb, w / 4 + dws  # panel half-widths at the waist, darts open
    bw = (p["bust_girth"] + p["bust_ease"]) / 2
    wh = (p["hip_girth"] + p["hip_ease"]) / 2
    panels, seams = [], []
    for side_name, depth in neck_depths(p):
        bodice, skirt = f"bodice_{side_name}", f"skirt_{side_name}"
        ids_b = (f"{bodice}.waist_dart_l", f"{bodice}.waist_dart_r")
        ids_s = (f"{skirt}.waist_dart_l", f"{skirt}.waist_dart_r")
        right, neck = bodice_right(p, 2 * a_b, bw, depth, [], None)
        waist_b = _waist_edge(a_b, c_b, dwb, p["bodice_dart_length"], ids_b, reverse=False)
        panels.append(mirror_panel(bodice, right, neck, waist_b))
        side, C, k, f = skirt_side(2 * a_s, wh, p["waist_to_hip"], p["length"], p["flare"])
        waist_s = _waist_edge(a_s, c_s, dws, -p["skirt_dart_length"], ids_s, reverse=True)
        panels.append(mirror_panel(skirt, [SegDef("side_right", side)], waist_s, hem(C, k, f)))
        seams += [(bodice, piece, skirt, piece) for piece in ("waist_left", "waist_center", "waist_right")]
        seams += [
            (n, f"dart:{i}:left", n, f"dart:{i}:right") for n, ids in ((bodice, ids_b), (skirt, ids_s)) for i in ids
        ]
    for tier in ("bodice", "skirt"):
        seams += side_seams(f"{tier}_front", f"{tier}_back")
    seams += shoulder_seams("bodice_front", "bodice_back")
    # both tiers hang from the body's waist line (y = 0), so their waist edges start together
    y_waist = M.FLOOR_Y + p["waist_height"]
    rings = [torso_ring([f"{tier}_front", f"{tier}_back"], y_waist, anchor_y=0.0) for tier in ("bodice", "skirt")]
    return SloperDraft(panels, seams, rings, bust_darts(p, "bodice_front"))


DRESS = SloperDef("dress", DRESS_OPTIONS, draft_dress, draft_dress.__doc__ or "")
DRESS_WAIST = SloperDef(
    "dress_waist", DRESS_WAIST_OPTIONS, draft_dress_waist, draft_dress_waist.__doc__ or "", body_fitted=True
)

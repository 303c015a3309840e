"""Slopers: base patterns drafted from body measurements and style options.

Each sloper is a function of its resolved options returning a
:class:`SloperDraft`: panels as chains of named segments, each segment a chain
of smooth curves (lines and cubic Béziers) whose control points are smooth
functions of the options, so drafting is differentiable in every non-integer
option. Material coordinates: metres, y up; for garments hung from the waist
y = 0 is the waist line, for sleeves y = 0 is the top of the cap.

Option tables are :data:`SLOPERS` ``[kind].options``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from couture.pattern import mannequin as M
from couture.pattern import options as O
from couture.pattern.geometry import Curve, bezier, line
from couture.pattern.options import Option, opt


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
    landmark: str | None = None
    """'waist': ``origin`` lies at the default mannequin's waist height, and on
    another body the ring moves along its axis to that body's waist
    (``couture.bodies.measured``); None: placed where drafted on every body"""


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


def _mirror_panel(
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

    def mirror(seg: SegDef) -> SegDef:
        curves = [Curve(c.pts[::-1] * np.array([-1.0, 1.0])) for c in reversed(seg.curves)]
        return SegDef(seg.name.replace("_right", "_left"), curves)

    segs = []
    if bottom is not None:
        segs.extend(bottom if isinstance(bottom, list) else [bottom])
    segs.extend(right)
    if top is not None:
        segs.extend(top if isinstance(top, list) else [top])
    segs.extend(mirror(s) for s in reversed(right))
    return PanelDef(name, segs)


def _skirt_side(ww, wh, h, L, f):
    """Right side seam (hem corner -> hip -> waist) and the hem corner, hem handle."""
    a = wh / 2
    tf, t2 = np.tan(f), np.tan(f / 2)
    xh = (a + (L - h) * tf) / (1 + t2 * tf)
    yc = -L + xh * t2
    C = np.array([xh, yc])
    H = np.array([a, -h])
    W = np.array([ww / 2, 0.0])
    up = np.array([-np.sin(f), np.cos(f)])
    side = [line(C, H), bezier(H, H + up * h / 3, W + np.array([0, -h / 3]), W)]
    k = (2.0 / 3.0) * xh / np.cos(f / 2) ** 2
    return side, C, k, f


def _hem(C, k, f) -> SegDef:
    Cl = C * np.array([-1.0, 1.0])
    return SegDef(
        "hem", [bezier(Cl, Cl + k * np.array([np.cos(f), -np.sin(f)]), C - k * np.array([np.cos(f), np.sin(f)]), C)]
    )


def _torso_body_radius(y_waist: float):
    return lambda ym: M.body_radius(y_waist + np.asarray(ym))


# ---------------------------------------------------------------- skirt

SKIRT_OPTIONS = (
    O.WAIST,
    O.HIP,
    O.WAIST_TO_HIP,
    opt("length", 0.60, 0.38, 1.00, "m", "waist to hem at centre"),
    opt("flare", 0.12, 0.0, 0.60, "rad", "angle of each side seam from vertical below the hip"),
    opt("panels", 4, 2, 8, "count", "number of panels (gores); topology option", integer=True),
    opt("waist_ease", 0.01, 0.0, 0.08, "m", "added to the waist girth"),
    opt("hip_ease", 0.04, 0.0, 0.15, "m", "added to the hip girth"),
)


def skirt_panels(prefix_names: list[str], p, ww_total, wh_total, L) -> list[PanelDef]:
    n = len(prefix_names)
    side, C, k, f = _skirt_side(ww_total / n, wh_total / n, p["waist_to_hip"], L, p["flare"])
    out = []
    for name in prefix_names:
        W = side[-1].pts[-1]
        waist = SegDef("waist", [line(W, W * np.array([-1.0, 1.0]))])
        out.append(_mirror_panel(name, [SegDef("side_right", side)], waist, _hem(C, k, f)))
    return out


def draft_skirt(p: dict[str, float]) -> SloperDraft:
    """A-line skirt of n identical gores; gore 0 centred at the front."""
    n = int(round(p["panels"]))
    names = ["front", "back"] if n == 2 else [f"gore{i}" for i in range(n)]
    panels = skirt_panels(names, p, p["waist_girth"] + p["waist_ease"], p["hip_girth"] + p["hip_ease"], p["length"])
    seams = [(names[i], "side_right", names[(i + 1) % n], "side_left") for i in range(n)]
    ring = Ring(
        names, [2 * np.pi * i / n for i in range(n)], np.array([0.0, M.WAIST_Y, M.TORSO_AXIS_Z]), section="torso"
    )
    return SloperDraft(panels, seams, [ring])


# ---------------------------------------------------------------- bodice pieces


def _bodice_right(p, ww, bw, neck_depth, below: list[Curve], start):
    """Right half of a bodice above the waist: side (from ``start``), armhole,
    shoulder; plus the neck point. ``below`` are side curves below the waist."""
    hu, hs = p["waist_to_underarm"], p["waist_to_shoulder"]
    W = np.array([ww / 2, 0.0]) if start is None else start
    U = np.array([bw / 2, hu])
    S = np.array([p["shoulder_width"] / 2, hs])
    nr = p["neck_girth"] / (2 * np.pi) + 0.01
    N = np.array([nr, hs + 0.025])
    side = SegDef("side_right", below + [bezier(W, W + np.array([0, hu / 3]), U - np.array([0, hu / 3]), U)])
    inner = min(U[0], S[0]) - 0.03
    arm = SegDef(
        "armhole_right",
        [bezier(U, np.array([inner, U[1] + 0.005]), np.array([S[0] - 0.01, S[1] - 0.4 * (S[1] - U[1])]), S)],
    )
    shoulder = SegDef("shoulder_right", [line(S, N)])
    Nl = N * np.array([-1.0, 1.0])
    neck = SegDef(
        "neck",
        [
            bezier(
                N,
                N + np.array([0, -0.55 * neck_depth]),
                np.array([0.55 * nr, N[1] - neck_depth]),
                np.array([0.0, N[1] - neck_depth]),
            ),
            bezier(
                np.array([0.0, N[1] - neck_depth]),
                np.array([-0.55 * nr, N[1] - neck_depth]),
                Nl + np.array([0, -0.55 * neck_depth]),
                Nl,
            ),
        ],
    )
    return [side, arm, shoulder], neck


# ---------------------------------------------------------------- dress

DRESS_OPTIONS = (
    O.BUST,
    O.WAIST,
    O.HIP,
    O.WAIST_TO_HIP,
    O.WAIST_TO_UNDERARM,
    O.WAIST_TO_SHOULDER,
    O.SHOULDER_WIDTH,
    O.NECK_GIRTH,
    opt("length", 0.55, 0.38, 1.00, "m", "waist to hem"),
    opt("flare", 0.06, 0.0, 0.40, "rad", "side seam angle below the hip"),
    opt("bust_ease", 0.06, 0.0, 0.20, "m", "added to the bust girth"),
    opt("waist_ease", 0.04, 0.0, 0.15, "m", "added to the waist girth"),
    opt("hip_ease", 0.05, 0.0, 0.15, "m", "added to the hip girth"),
    opt("waist_dart_width", 0.02, 0.005, 0.04, "m", "width of each of the 4 waist (diamond) darts"),
    opt("bust_dart_width", 0.015, 0.0, 0.04, "m", "width of the front armhole bust darts"),
    opt("front_neck_depth", 0.07, 0.01, 0.20, "m", "front neckline drop below the neck point"),
)


def draft_dress(p: dict[str, float]) -> SloperDraft:
    """Fitted sheath dress: front and back, each one piece from shoulder to hem,
    shaped by waist diamond darts (interior) and armhole bust darts (boundary)."""
    dw = p["waist_dart_width"]
    ww = (p["waist_girth"] + p["waist_ease"]) / 2 + 2 * dw  # side-seam waist width incl. 2 darts
    bw = (p["bust_girth"] + p["bust_ease"]) / 2
    wh = (p["hip_girth"] + p["hip_ease"]) / 2
    panels = []
    for name, depth in (("front", p["front_neck_depth"]), ("back", 0.02)):
        side, C, k, f = _skirt_side(ww, wh, p["waist_to_hip"], p["length"], p["flare"])
        right, neck = _bodice_right(p, ww, bw, depth, side, side[-1].pts[-1])
        panels.append(_mirror_panel(name, right, neck, _hem(C, k, f)))
    seams = [
        ("front", "side_right", "back", "side_left"),
        ("back", "side_right", "front", "side_left"),
        ("front", "shoulder_right", "back", "shoulder_left"),
        ("back", "shoulder_right", "front", "shoulder_left"),
    ]
    darts = []
    for name in ("front", "back"):
        for side_name, pos in (("l", 0.30), ("r", 0.70)):
            darts.append(
                BuiltinDart(
                    f"{name}.waist_dart_{side_name}",
                    name,
                    "interior",
                    {
                        "anchor": "hem",
                        "position": pos,
                        "depth": p["length"] - 0.02,
                        "width": dw,
                        "length": 0.30,
                        "offset": 0.0,
                    },
                )
            )
    if p["bust_dart_width"] > 0:
        for s in ("left", "right"):
            darts.append(
                BuiltinDart(
                    f"front.bust_dart_{s}",
                    "front",
                    "boundary",
                    {
                        "segment": f"armhole_{s}",
                        "position": 0.35,
                        "width": p["bust_dart_width"],
                        "length": 0.3 * (p["waist_to_shoulder"] - p["waist_to_underarm"]),
                    },
                )
            )
    ring = Ring(["front", "back"], [0.0, np.pi], np.array([0.0, M.WAIST_Y, M.TORSO_AXIS_Z]), section="torso")
    return SloperDraft(panels, seams, [ring], darts)


# ---------------------------------------------------------------- waist-seamed dress

DRESS_WAIST_OPTIONS = (
    O.BUST,
    O.WAIST,
    O.HIP,
    O.WAIST_TO_HIP,
    O.WAIST_TO_UNDERARM,
    O.WAIST_TO_SHOULDER,
    O.SHOULDER_WIDTH,
    O.NECK_GIRTH,
    O.WAIST_HEIGHT,
    opt("length", 0.55, 0.38, 1.00, "m", "waist to hem (the skirt)"),
    opt("flare", 0.06, 0.0, 0.40, "rad", "skirt side seam angle below the hip"),
    opt("bust_ease", 0.06, 0.0, 0.20, "m", "added to the bust girth"),
    opt("waist_ease", 0.03, 0.0, 0.15, "m", "added to the waist girth (bodice and skirt waist, darts closed)"),
    opt("hip_ease", 0.05, 0.0, 0.15, "m", "added to the hip girth"),
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
    opt("bust_dart_width", 0.015, 0.0, 0.04, "m", "width of the front armhole bust darts"),
    opt("front_neck_depth", 0.07, 0.01, 0.20, "m", "front neckline drop below the neck point"),
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
    panels, darts, seams = [], [], []
    for side_name, depth in (("front", p["front_neck_depth"]), ("back", 0.02)):
        bodice, skirt = f"bodice_{side_name}", f"skirt_{side_name}"
        ids_b = (f"{bodice}.waist_dart_l", f"{bodice}.waist_dart_r")
        ids_s = (f"{skirt}.waist_dart_l", f"{skirt}.waist_dart_r")
        right, neck = _bodice_right(p, 2 * a_b, bw, depth, [], None)
        waist_b = _waist_edge(a_b, c_b, dwb, p["bodice_dart_length"], ids_b, reverse=False)
        panels.append(_mirror_panel(bodice, right, neck, waist_b))
        side, C, k, f = _skirt_side(2 * a_s, wh, p["waist_to_hip"], p["length"], p["flare"])
        waist_s = _waist_edge(a_s, c_s, dws, -p["skirt_dart_length"], ids_s, reverse=True)
        panels.append(_mirror_panel(skirt, [SegDef("side_right", side)], waist_s, _hem(C, k, f)))
        seams += [(bodice, piece, skirt, piece) for piece in ("waist_left", "waist_center", "waist_right")]
        seams += [
            (n, f"dart:{i}:left", n, f"dart:{i}:right") for n, ids in ((bodice, ids_b), (skirt, ids_s)) for i in ids
        ]
    for tier in ("bodice", "skirt"):
        seams += [
            (f"{tier}_front", "side_right", f"{tier}_back", "side_left"),
            (f"{tier}_back", "side_right", f"{tier}_front", "side_left"),
        ]
    seams += [
        ("bodice_front", "shoulder_right", "bodice_back", "shoulder_left"),
        ("bodice_back", "shoulder_right", "bodice_front", "shoulder_left"),
    ]
    if p["bust_dart_width"] > 0:
        for s in ("left", "right"):
            darts.append(
                BuiltinDart(
                    f"bodice_front.bust_dart_{s}",
                    "bodice_front",
                    "boundary",
                    {
                        "segment": f"armhole_{s}",
                        "position": 0.35,
                        "width": p["bust_dart_width"],
                        "length": 0.3 * (p["waist_to_shoulder"] - p["waist_to_underarm"]),
                    },
                )
            )
    origin = np.array([0.0, M.FLOOR_Y + p["waist_height"], M.TORSO_AXIS_Z])  # the body's waist line
    # both tiers hang from the waist line (y = 0), so their waist edges start together
    rings = [
        Ring([f"{tier}_front", f"{tier}_back"], [0.0, np.pi], origin.copy(), section="torso", anchor_y=0.0)
        for tier in ("bodice", "skirt")
    ]
    return SloperDraft(panels, seams, rings, darts)


# ---------------------------------------------------------------- shirt

SHIRT_OPTIONS = (
    O.BUST,
    O.WAIST_TO_UNDERARM,
    O.WAIST_TO_SHOULDER,
    O.SHOULDER_WIDTH,
    O.NECK_GIRTH,
    O.ARM_GIRTH,
    O.HIP,
    opt("length", 0.20, 0.05, 0.45, "m", "waist to hem"),
    opt("ease", 0.10, 0.02, 0.30, "m", "added to bust and hip girths"),
    opt("sleeve_length", 0.22, 0.18, 0.40, "m", "cap top to sleeve hem (short to below the elbow)"),
    opt("sleeve_ease", 0.06, 0.02, 0.20, "m", "added to the upper arm girth"),
    opt("cuff", 0.30, 0.18, 0.50, "m", "sleeve hem circumference"),
    opt("cap_height", 0.10, 0.05, 0.14, "m", "sleeve cap height"),
    opt("front_neck_depth", 0.06, 0.01, 0.15, "m", "front neckline drop"),
)


def _arm_frame(sign: float):
    a = M.LEFT_ARM_AXIS * np.array([sign, 1.0, 1.0])
    a = a / np.linalg.norm(a)
    v = np.array([sign, 1.0, 0.0]) / np.sqrt(2)
    f = v - (v @ a) * a
    return a, f / np.linalg.norm(f)


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


def draft_shirt(p: dict[str, float]) -> SloperDraft:
    """Shirt block with set-in sleeves: front, back, left and right sleeves."""
    bw = (p["bust_girth"] + p["ease"]) / 2
    hw = (p["hip_girth"] + p["ease"]) / 2
    L = p["length"]
    panels = []
    for name, depth in (("front", p["front_neck_depth"]), ("back", 0.02)):
        C = np.array([max(hw, bw) / 2, -L])
        W = np.array([bw / 2 + 0.5 * (C[0] - bw / 2), 0.0])
        below = [line(C, W)]
        right, neck = _bodice_right(p, 2 * W[0], bw, depth, below, W)
        hem = SegDef("hem", [line(C * np.array([-1.0, 1.0]), C)])
        panels.append(_mirror_panel(name, right, neck, hem))
    # sleeve: cap top at (0, 0), wrist at y = -sleeve_length
    sw = (p["upper_arm_girth"] + p["sleeve_ease"]) / 2
    ch, sl, cw = p["cap_height"], p["sleeve_length"], p["cuff"] / 2
    B = np.array([sw, -ch])  # underarm point (right)
    Cf = np.array([cw, -sl])
    T = np.array([0.0, 0.0])
    cap_r = SegDef("cap_right", [bezier(B, B + np.array([-0.35 * sw, 0.15 * ch]), T + np.array([0.45 * sw, 0.0]), T)])
    cap_l = SegDef(
        "cap_left",
        [
            bezier(
                T,
                T - np.array([0.45 * sw, 0.0]),
                B * np.array([-1, 1]) + np.array([0.35 * sw, 0.15 * ch]),
                B * np.array([-1.0, 1.0]),
            )
        ],
    )
    under_r = SegDef("underarm_right", [line(Cf, B)])
    under_l = SegDef("underarm_left", [line(B * np.array([-1.0, 1.0]), Cf * np.array([-1.0, 1.0]))])
    cuff = SegDef("cuff", [line(Cf * np.array([-1.0, 1.0]), Cf)])
    for name in ("sleeve_left", "sleeve_right"):
        panels.append(PanelDef(name, [cuff, under_r, cap_r, cap_l, under_l]))
    seams = [
        ("front", "side_right", "back", "side_left"),
        ("back", "side_right", "front", "side_left"),
        ("front", "shoulder_right", "back", "shoulder_left"),
        ("back", "shoulder_right", "front", "shoulder_left"),
        ("sleeve_left", "underarm_right", "sleeve_left", "underarm_left"),
        ("sleeve_right", "underarm_right", "sleeve_right", "underarm_left"),
    ]
    rings = [Ring(["front", "back"], [0.0, np.pi], np.array([0.0, M.WAIST_Y, M.TORSO_AXIS_Z]), section="torso")]
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
    opt("length", 0.20, 0.05, 0.45, "m", "waist to hem"),
    opt("ease", 0.10, 0.02, 0.30, "m", "added to bust and hip girths"),
    opt("armhole_drop", 0.04, 0.0, 0.08, "m", "bodice underarm point below the waist_to_underarm line"),
    opt("neck_ease", 0.08, 0.0, 0.15, "m", "added to the neck girth for the neckline width"),
    opt("front_neck_depth", 0.06, 0.01, 0.15, "m", "front neckline drop"),
    opt("sleeve_length", 0.22, 0.15, 0.40, "m", "cap top to sleeve hem (short to below the elbow)"),
    opt("sleeve_ease", 0.04, 0.02, 0.20, "m", "added to the upper arm girth: the sleeve's width at the underarm"),
    opt("cap_ease", 0.02, 0.0, 0.05, "m", "sleeve cap seam length minus the armhole length (both halves), eased in"),
    opt("cuff", 0.30, 0.18, 0.50, "m", "sleeve hem circumference"),
    opt("collar_height", 0.03, 0.015, 0.06, "m", "stand collar (band) height"),
)
BACK_NECK_DEPTH = 0.02
"""[m] back neckline drop below the neck point"""
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
    bw = (p["bust_girth"] + p["ease"]) / 2
    hw = (p["hip_girth"] + p["ease"]) / 2
    hu, hs = p["waist_to_underarm"] - p["armhole_drop"], p["waist_to_shoulder"]
    C = np.array([max(hw, bw) / 2, -p["length"]])
    W = np.array([bw / 2 + 0.5 * (C[0] - bw / 2), 0.0])
    U = np.array([bw / 2, hu])
    S = np.array([p["shoulder_width"] / 2, hs])
    nr = (p["neck_girth"] + p["neck_ease"]) / (2 * np.pi) + 0.01
    N = np.array([nr, hs + 0.025])
    side = SegDef("side_right", [line(C, W), bezier(W, W + np.array([0, hu / 3]), U - np.array([0, hu / 3]), U)])
    d = hs - hu
    scoop = min(0.35 * max(U[0] - S[0], 0.0) + 0.02, 0.6 * (U[0] - N[0]))
    arm = SegDef(
        "armhole_right",
        [bezier(U, U + np.array([-scoop, 0.0]), S + np.array([-0.012, -0.45 * d]), S)],
    )
    shoulder = SegDef("shoulder_right", [line(S, N)])
    Nl = N * np.array([-1.0, 1.0])
    bottom = np.array([0.0, N[1] - depth])
    neck = SegDef(
        "neck",
        [
            bezier(N, N + np.array([0, -0.55 * depth]), np.array([0.55 * nr, bottom[1]]), bottom),
            bezier(bottom, np.array([-0.55 * nr, bottom[1]]), Nl + np.array([0, -0.55 * depth]), Nl),
        ],
    )
    hem = SegDef("hem", [line(C * np.array([-1.0, 1.0]), C)])
    return [side, arm, shoulder], neck, hem


def _cap_curve(sw: float, ch: float) -> Curve:
    """Right half of a sleeve cap, underarm point (sw, -ch) to the cap top (0, 0)."""
    B = np.array([sw, -ch])
    return bezier(B, B + np.array([-0.35 * sw, 0.15 * ch]), np.array([0.45 * sw, 0.0]), np.zeros(2))


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
    for name, depth in (("front", p["front_neck_depth"]), ("back", BACK_NECK_DEPTH)):
        right, neck, hem = _set_in_bodice(p, depth)
        panels.append(_mirror_panel(name, right, neck, hem))
        necks[name] = neck
        arm_len = sum(c.length(256) for c in right[1].curves)
    # sleeve: cap top at (0, 0), underarm at y = -ch, cuff at y = -sleeve_length
    sw = (p["upper_arm_girth"] + p["sleeve_ease"]) / 2
    sl, cw = p["sleeve_length"], p["cuff"] / 2
    try:
        sw, ch = sleeve_cap(sw, arm_len + p["cap_ease"] / 2, sl - 0.05)
    except ValueError as e:
        raise PatternError("param:cap_ease", f"the sleeve cannot be set into the armhole: {e}") from None
    mx = np.array([-1.0, 1.0])
    cap = _cap_curve(sw, ch)
    B, Cf = cap.pts[0], np.array([cw, -sl])
    cap_r = SegDef("cap_right", [cap])
    cap_l = SegDef("cap_left", [Curve(cap.pts[::-1] * mx)])
    under_r = SegDef("underarm_right", [line(Cf, B)])
    under_l = SegDef("underarm_left", [line(B * mx, Cf * mx)])
    cuff = SegDef("cuff", [line(Cf * mx, Cf)])
    for name in ("sleeve_left", "sleeve_right"):
        panels.append(PanelDef(name, [cuff, under_r, cap_r, cap_l, under_l]))
    # collar: a straight band per bodice, as long as its neckline, material y = 0 at the seam
    ht = p["collar_height"]
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
    seams = [
        ("front", "side_right", "back", "side_left"),
        ("back", "side_right", "front", "side_left"),
        ("front", "shoulder_right", "back", "shoulder_left"),
        ("back", "shoulder_right", "front", "shoulder_left"),
        ("sleeve_left", "underarm_right", "sleeve_left", "underarm_left"),
        ("sleeve_right", "underarm_right", "sleeve_right", "underarm_left"),
        ("front", "neck", "collar_front", "neck_seam"),
        ("back", "neck", "collar_back", "neck_seam"),
        ("collar_front", "end_right", "collar_back", "end_left"),
        ("collar_back", "end_right", "collar_front", "end_left"),
    ]
    y_waist = M.FLOOR_Y + p["waist_height"]
    rings = [Ring(["front", "back"], [0.0, np.pi], np.array([0.0, y_waist, M.TORSO_AXIS_Z]), section="torso")]
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


# ---------------------------------------------------------------- trousers

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
        s = segs
        if mirror:  # mirror x and reverse to stay CCW
            s = [
                SegDef(sg.name, [Curve(c.pts[::-1] * np.array([-1.0, 1.0])) for c in reversed(sg.curves)])
                for sg in reversed(segs)
            ]
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
    rings.append(
        Ring(
            ["band_front", "band_back"],
            [0.0, np.pi],
            np.array([0.0, M.WAIST_Y - bh / 2, M.TORSO_AXIS_Z]),
            section="torso",
            landmark="waist",
        )
    )


def _cap_radius(ym):
    """A sleeve cap's clearance about the arm axis near the shoulder, where the
    arm section table (arm vertices only) does not see the shoulder."""
    return np.where(np.asarray(ym) > -0.10, M.ARM_RADIUS, 0.0)


def _leg_body_radius(ym):
    """Body radius about a leg axis by material height (pelvis above the crotch)."""
    y = M.WAIST_Y + np.asarray(ym)
    return np.interp(
        y,
        [M.FLOOR_Y, M.KNEE_Y, M.CROTCH_Y - 0.1, M.CROTCH_Y, M.HIP_Y + 0.1, M.WAIST_Y + 0.05],
        [0.09, 0.08, 0.095, 0.14, 0.22, 0.20],
    )


SLOPERS: dict[str, SloperDef] = {
    "skirt": SloperDef("skirt", SKIRT_OPTIONS, draft_skirt, draft_skirt.__doc__ or ""),
    "dress": SloperDef("dress", DRESS_OPTIONS, draft_dress, draft_dress.__doc__ or ""),
    "dress_waist": SloperDef(
        "dress_waist", DRESS_WAIST_OPTIONS, draft_dress_waist, draft_dress_waist.__doc__ or "", body_fitted=True
    ),
    "shirt": SloperDef("shirt", SHIRT_OPTIONS, draft_shirt, draft_shirt.__doc__ or ""),
    "trousers": SloperDef("trousers", TROUSERS_OPTIONS, draft_trousers, draft_trousers.__doc__ or "", body_fitted=True),
    "shirt_set_in": SloperDef(
        "shirt_set_in", SHIRT_SET_IN_OPTIONS, draft_shirt_set_in, draft_shirt_set_in.__doc__ or "", body_fitted=True
    ),
}
"""sloper kind -> its option table and drafting function"""

"""Pieces several slopers share: the skirt below the waist (an A-line side
seam and a curved hem), the bodice above it (side, armhole, shoulder,
neckline), the seams that join a front to a back, and the front's armhole
bust darts."""

from __future__ import annotations

import numpy as np

from couture.pattern.geometry import Curve, bezier, line
from couture.pattern.slopers.base import MIRROR_X, BuiltinDart, SegDef

# ---------------------------------------------------------------- skirt below the waist


def skirt_side(ww, wh, h, L, f):
    """Right side seam (hem corner -> hip -> waist) of a panel ``ww`` wide at
    the waist and ``wh`` at the hip, ``h`` below it, flaring at ``f`` [rad]
    below the hip to the hem ``L`` below the waist; with the hem corner C and
    the hem's handle length k and angle f (:func:`hem`)."""
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


def hem(C, k, f) -> SegDef:
    """The hem from the left corner to the right one C, square to both side seams."""
    Cl = C * MIRROR_X
    return SegDef(
        "hem", [bezier(Cl, Cl + k * np.array([np.cos(f), -np.sin(f)]), C - k * np.array([np.cos(f), np.sin(f)]), C)]
    )


# ---------------------------------------------------------------- bodice above the waist

BACK_NECK_DEPTH = 0.02
"""[m] back neckline drop below the neck point"""


def neck_depths(p: dict[str, float]) -> tuple[tuple[str, float], tuple[str, float]]:
    """(panel, neckline drop [m]) of the front and the back bodice."""
    return ("front", p["front_neck_depth"]), ("back", BACK_NECK_DEPTH)


def neckline(N, nr: float, depth: float) -> SegDef:
    """The neckline from the right neck point N to the left one, ``depth``
    below N at the centre; ``nr`` [m]: the neck's radius (the handles' reach)."""
    bottom = np.array([0.0, N[1] - depth])
    Nl = N * MIRROR_X
    return SegDef(
        "neck",
        [
            bezier(N, N + np.array([0, -0.55 * depth]), np.array([0.55 * nr, bottom[1]]), bottom),
            bezier(bottom, np.array([-0.55 * nr, bottom[1]]), Nl + np.array([0, -0.55 * depth]), Nl),
        ],
    )


def bodice_half(below: list[Curve], W, U, S, N, nr: float, depth: float, armhole: Curve) -> tuple[list[SegDef], SegDef]:
    """The right half of a bodice above the waist, bottom to top: the side seam
    (``below``, the side's curves below the waist, then from the waist point W
    up to the underarm point U), the armhole (U to the shoulder point S), the
    shoulder (S to the neck point N); and the neckline (:func:`neckline`)."""
    hu = U[1]
    side = SegDef("side_right", below + [bezier(W, W + np.array([0, hu / 3]), U - np.array([0, hu / 3]), U)])
    return [side, SegDef("armhole_right", [armhole]), SegDef("shoulder_right", [line(S, N)])], neckline(N, nr, depth)


def bodice_right(p, ww, bw, neck_depth, below: list[Curve], start):
    """Right half of a fitted bodice above the waist: side (from ``start``,
    None: the waist point at half ``ww``), armhole, shoulder; plus the
    neckline. ``bw``: the width at the underarm; ``below``: side curves below
    the waist."""
    hu, hs = p["waist_to_underarm"], p["waist_to_shoulder"]
    W = np.array([ww / 2, 0.0]) if start is None else start
    U = np.array([bw / 2, hu])
    S = np.array([p["shoulder_width"] / 2, hs])
    nr = p["neck_girth"] / (2 * np.pi) + 0.01
    N = np.array([nr, hs + 0.025])
    inner = min(U[0], S[0]) - 0.03
    arm = bezier(U, np.array([inner, U[1] + 0.005]), np.array([S[0] - 0.01, S[1] - 0.4 * (S[1] - U[1])]), S)
    return bodice_half(below, W, U, S, N, nr, neck_depth, arm)


def side_seams(front: str, back: str) -> list[tuple[str, str, str, str]]:
    """The two side seams of a front and a back panel (each mirrored about its centre line)."""
    return [(front, "side_right", back, "side_left"), (back, "side_right", front, "side_left")]


def shoulder_seams(front: str, back: str) -> list[tuple[str, str, str, str]]:
    """The two shoulder seams of a front and a back bodice."""
    return [(front, "shoulder_right", back, "shoulder_left"), (back, "shoulder_right", front, "shoulder_left")]


def bust_darts(p: dict[str, float], panel: str) -> list[BuiltinDart]:
    """The front bodice's two armhole bust darts (``bust_dart_width`` wide;
    none where it is 0)."""
    if not p["bust_dart_width"] > 0:
        return []
    return [
        BuiltinDart(
            f"{panel}.bust_dart_{s}",
            panel,
            "boundary",
            {
                "segment": f"armhole_{s}",
                "position": 0.35,
                "width": p["bust_dart_width"],
                "length": 0.3 * (p["waist_to_shoulder"] - p["waist_to_underarm"]),
            },
        )
        for s in ("left", "right")
    ]

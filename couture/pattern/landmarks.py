"""Body landmarks for placing pieces: the neck's heights and CLO-like
arrangement points, measured on each body (``couture.bodies``) from its
section tables (:mod:`couture.pattern.sections`) and measurements, so they
follow every body, graded or made.

An arrangement point is a place on the body where a piece's centre is laid
(``PiecePlacement.ring = 'point'``): the section table it lies on (the local
body axis), the angle about that axis (theta = 0 the table's front
direction), and the axial coordinate of its height. The piece is wrapped
round that axis there by arc length, its centre at the point, at a clearance
outside the body's section (:func:`couture.pattern.pieces.piece_rings`).

Bus-free: drafting and the UI both read it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

NECK_SEARCH = (0.08, 0.30)
"""[m] the neck's narrowest torso section is searched this far above the underarm"""
NECK_BASE_RATIO = 1.25
"""the neck's base: the lowest height whose torso section girth is at most
this many times the neck's narrowest girth (the shoulders' slope ends there)"""
NECK_TOP_RATIO = 1.10
"""the neck's top: the lowest height above the narrowest whose girth exceeds
this many times the narrowest (the jaw begins there)"""
UPPER_ARM_DOWN = 0.12
"""[m] the upper arm's point lies this far down the arm axis from the arm root"""
FOREARM_DOWN = 0.38
"""[m] the forearm's point lies this far down the arm axis from the arm root"""
THIGH_DOWN = 0.12
"""[m] the thigh's point lies this far below the crotch along the leg axis"""
KNEE_FRACTION = 0.5
"""the knee lies this fraction of the way from the crotch to the floor"""


@dataclass(frozen=True)
class Neck:
    """The neck of one body, on the torso section table (heights world y [m])."""

    base_y: float
    """where a collar's neck edge sits: the top of the shoulders' slope"""
    narrow_y: float
    """the narrowest torso section above the shoulders"""
    top_y: float
    """the highest height a collar may reach: below the jaw, where the section
    grows again past ``NECK_TOP_RATIO`` times the narrowest girth"""
    girth: float
    """[m] the section's perimeter at ``base_y`` (a convex hull: a tape's reading)"""


def _girths(radius: np.ndarray) -> np.ndarray:
    """Perimeters (rows,) of polar sections (rows, K) at theta_k = 2 pi k / K."""
    K = radius.shape[1]
    th = 2 * np.pi * np.arange(K) / K
    x, y = radius * np.cos(th), radius * np.sin(th)
    return np.hypot(np.roll(x, -1, axis=1) - x, np.roll(y, -1, axis=1) - y).sum(axis=1)


@lru_cache(maxsize=16)
def neck(body: str = "default") -> Neck:
    """The neck of ``body``: base, narrowest and top heights, from its torso table."""
    from couture.bodies import measured
    from couture.pattern.sections import sections

    sec = sections(body)["torso"]
    under = float(measured(body)["underarm_y"])
    y = np.arange(under + NECK_SEARCH[0], under + NECK_SEARCH[1], 0.005)
    t = y - float(sec.origin[1])
    g = _girths(sec.radii(t))
    i = int(np.argmin(g))
    limit = NECK_BASE_RATIO * g[i]
    below = np.nonzero(g[: i + 1] > limit)[0]
    j = int(below.max()) + 1 if len(below) else 0
    # interpolate the crossing between the last row above the limit and the next
    base = float(y[j]) if j == 0 else float(np.interp(limit, [g[j], g[j - 1]], [y[j], y[j - 1]]))
    above = np.nonzero(g[i:] > NECK_TOP_RATIO * g[i])[0]
    top = float(y[i + above.min()]) if len(above) else float(y[-1])
    return Neck(base_y=base, narrow_y=float(y[i]), top_y=top, girth=float(_girths(sec.radii(base - sec.origin[1]))[0]))


def landmark_y(body: str, name: str) -> float:
    """[m] world height of a ring's landmark on ``body``: 'neck' (its base,
    :func:`neck`) or a measured height ('waist', 'bust', 'hip', ...:
    ``couture.bodies.measured``'s ``<name>_y``)."""
    if name == "neck":
        return neck(body).base_y
    from couture.bodies import measured

    return float(measured(body)[f"{name}_y"])


@dataclass(frozen=True)
class ArrangementPoint:
    """A named place on the body where a piece's centre is laid."""

    name: str
    section: str
    """the section table (local body axis): 'torso', 'left_arm', 'right_leg', ..."""
    angle: float
    """[rad] about the table's axis, from its front direction (theta = 0)
    toward axis x front; on the torso: 0 front, pi/2 the body's left"""
    axial: float
    """[m] coordinate along the table's axis (from its origin) of the point's height"""
    origin: np.ndarray
    """[m] the axis point at that height, shape (3,)"""
    axis: np.ndarray
    """unit axis (up the body, the arm or the leg), shape (3,)"""
    ref: np.ndarray
    """unit theta = 0 direction, shape (3,)"""
    position: np.ndarray
    """[m] the point on the body's section there, shape (3,)"""


_TORSO_SIDES = {"front": 0.0, "left": math.pi / 2, "back": math.pi, "right": 3 * math.pi / 2}


def _points_spec(body: str) -> dict[str, tuple[str, float, float]]:
    """name -> (section, angle [rad], world height or axial distance [m])."""
    from couture.bodies import measured

    m = measured(body)
    nk = neck(body)
    out: dict[str, tuple[str, float, float]] = {}
    for level, y in (
        ("neck", nk.base_y),
        ("chest", float(m["bust_y"])),
        ("waist", float(m["waist_y"])),
        ("hip", float(m["hip_y"])),
    ):
        for side, th in _TORSO_SIDES.items():
            if level == "chest" and side in ("left", "right"):
                continue  # the arm hangs there (the torso table leaves it out)
            out[f"{side}_{level}"] = ("torso", th, y)
    crotch, floor = float(m["crotch_y"]), float(m["floor_y"])
    for lr in ("left", "right"):
        # an arm's table: theta = 0 is its top (up and out), material -axis down the arm
        out[f"{lr}_upper_arm"] = (f"{lr}_arm", 0.0, -UPPER_ARM_DOWN)
        out[f"{lr}_forearm"] = (f"{lr}_arm", 0.0, -FOREARM_DOWN)
        out[f"{lr}_thigh"] = (f"{lr}_leg", 0.0, crotch - THIGH_DOWN)
        out[f"{lr}_knee"] = (f"{lr}_leg", 0.0, crotch + KNEE_FRACTION * (floor - crotch))
    return out


def point_names() -> list[str]:
    """Every arrangement point's name (the same on every body)."""
    return sorted(_points_spec("default"))


@lru_cache(maxsize=16)
def arrangement_points(body: str = "default") -> dict[str, ArrangementPoint]:
    """Every arrangement point of ``body`` by name: torso points (front, left,
    back, right at the neck's base, the waist and the hip; front and back at
    the chest, whose sides the arms cover),
    the upper arm and forearm (on the top of the arm) and the thigh and knee
    (at the front of the leg)."""
    from couture.pattern.sections import sections

    tables = sections(body)
    out = {}
    for name, (sec_name, th, h) in _points_spec(body).items():
        sec = tables[sec_name]
        a = np.asarray(sec.axis, float)
        f = np.asarray(sec.ref, float)
        b = np.cross(a, f)
        if sec_name.endswith("_arm"):
            axial = h
        else:  # a world height: where the axis crosses it
            axial = (h - float(sec.origin[1])) / float(a[1])
        o = np.asarray(sec.origin, float) + axial * a
        K = sec.radius.shape[1]
        r = np.interp(th % (2 * np.pi), 2 * np.pi * np.arange(K + 1) / K, np.append(R := sec.radii(axial)[0], R[0]))
        pos = o + r * (math.cos(th) * f + math.sin(th) * b)
        out[name] = ArrangementPoint(name, sec_name, th, float(axial), o, a, f, pos)
    return out


def arrangement_point(body: str, name: str) -> ArrangementPoint:
    """One arrangement point; ValueError naming the known ones when there is none."""
    pts = arrangement_points(body)
    if name not in pts:
        raise ValueError(f"no arrangement point {name!r}; there are {', '.join(sorted(pts))}")
    return pts[name]

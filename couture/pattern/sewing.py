"""Imported pieces -> a design: pieces unfolded and paired, corners found,
outlines resampled, seams suggested with a confidence, pieces placed round
the body by role (``couture import``).

- Cut on the fold: the half is mirrored about its fold edge (the straight
  edge on its centre side) into one whole panel.
- Cut 2 (a mirrored pair): two panels, the piece as drawn and its mirror
  image, '<name>_left' and '<name>_right' (the body's left and right).
- Corners: outline vertices where the sew line turns more than
  ``CORNER_ANGLE`` (over a ``CORNER_REACH`` neighbourhood, so a densely
  flattened curve is no corner); segments run between consecutive corners
  and are resampled to about ``SPACING`` (corners kept exactly).
- Seams (:func:`suggest_seams`): dart legs (two consecutive segments of one
  panel of equal length meeting in a sharp V); then side seams, pairs of a
  segment on one panel's right side and one on another's left side whose
  lengths agree within ``LENGTH_TOLERANCE``, greedily by confidence. A
  confidence in [0, 1] says how sure: length agreement, equal notch counts,
  and whether the two panels are a mirrored pair or a front and a back. An
  unpaired segment is a free edge (a hem, a neckline, a waist).
- Roles from names, else from shapes (:func:`roles_by_shape`: a sleeve's
  capped symmetric outline, a front's deeper neckline).
- Trousers (:func:`crotch_side`): a leg's front and back sewn at outseam and
  inseam, the legs at their crotch curves; each leg round its own leg.
- Tops (:func:`_set_in_sleeves`): shoulders paired front to back, each
  sleeve's cap split in the armholes' proportion and set into the front and
  back armholes; each sleeve round its arm.
- Waistbands (:func:`sew_band`): the band split into the waist's pieces round
  the body from the opening, in a ring of its own above the skirt.
- Placement: the panels round the torso in the order the side seams chain
  them (a panel's right side sewn to the next one's left), starting from the
  front; where they do not chain, by role (front 0, left pi/2, back pi, right
  3 pi/2). The top at the waist (a lower garment) or the shoulder (a top).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from couture.pattern.errors import PatternError
from couture.pattern.geometry import polyline_length, signed_area
from couture.pattern.imported import ImportedPiece
from schemas.design import Body, Design, Fabric, Piece, PiecePlacement, Sloper, Stroke

SPACING = 0.01
"""[m] target spacing of the resampled sew line (the sloper drafts at the same)"""
CORNER_ANGLE = math.radians(30)
CORNER_REACH = 0.004
"""[m] a corner's turn is measured between points this far before and after it"""
LENGTH_TOLERANCE = 0.03
"""two segments pair as a seam when their lengths differ by at most this fraction (or 5 mm)"""
MIN_SEAM = 0.03
"""[m] segments shorter than this are not suggested as seams (vent corners, notches)"""
DART_ANGLE = math.radians(45)
"""two consecutive legs meeting at less than this are a dart"""
WOVEN_STRETCH_STIFFNESS = 200.0
"""[N/m] the fabric an imported design starts with: patterns from other tools are
mostly drafted for woven cloth; couture's default cotton (20 N/m) is so stretchy
that a fitted pencil skirt's waist (FreeSewing penelope) stretches over the hips
and the skirt falls to the floor (measured: 58 cm drop at 20 N/m, 5 cm at 200)"""
TUBE_ROLES = ("sleeve", "cuff", "binding")
"""pieces sewn into a tube (a loop) by their own two sides"""
ROLE_WORDS = ("waistband", "sleeve", "collar", "cuff", "yoke", "facing", "pocket", "binding", "front", "back", "side")


@dataclass
class Suggestion:
    """A suggested seam: two segments to sew, with how sure the importer is."""

    a_panel: str
    a_segment: str
    b_panel: str
    b_segment: str
    confidence: float
    """in [0, 1]"""
    reason: str
    a_length: float = 0.0
    """[m]"""
    b_length: float = 0.0
    """[m]"""


@dataclass
class _Panel:
    name: str
    outline: np.ndarray
    corners: list[int]
    holes: list[np.ndarray] = field(default_factory=list)
    notches: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    role: str = ""
    side: str = ""
    """'left' or 'right' of a mirrored pair, '' for a whole panel"""
    twin: str = ""
    """the other panel of a mirrored pair"""
    grain: float = 0.0
    source: str = ""
    leg: str = ""
    """'left' or 'right': a trouser leg's front or back panel, on that leg; '' not a leg"""
    crotch: int = -1
    """a leg panel's crotch point: the index in ``corners`` where its crotch
    curve (above) meets its inseam (below); -1 not a leg"""
    arm: str = ""
    """'left' or 'right': a sleeve set into that armhole; '' not set in"""
    band: bool = False
    """a waistband sewn to the torso ring's top edge (placed round the body above it)"""
    neck: bool = False
    """a collar sewn to the neckline (placed round the neck)"""


def role_of(name: str) -> str:
    low = re.sub(r"[^a-z]", " ", re.sub(r"([a-z])([A-Z])", r"\1 \2", name).lower())
    for w in ROLE_WORDS:
        if w in low.split() or (w in low and w in ("waistband", "sleeve", "collar")):
            return w
    return ""


def piece_role(pc: ImportedPiece) -> str:
    """The piece's role: as given (:func:`roles_by_shape`), else from its name."""
    return pc.role or role_of(pc.name)


# ------------------------------------------------------------------ geometry


def _turns(P: np.ndarray, reach: float) -> np.ndarray:
    """Turning angle [rad] at each vertex of the closed polyline, between the
    directions to the points ``reach`` [m] before and after it along the line."""
    k = len(P)
    E = np.roll(P, -1, axis=0) - P
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(E, axis=1))])
    L = s[-1]
    before = _at(P, s, (s[:k] - reach) % L)
    after = _at(P, s, (s[:k] + reach) % L)
    a, b = P - before, after - P
    na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    cos = (a * b).sum(1) / np.maximum(na * nb, 1e-300)
    return np.arccos(np.clip(cos, -1.0, 1.0))


def _at(P: np.ndarray, s: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Points at arc lengths u along the closed polyline P (cumulative lengths s)."""
    Q = np.vstack([P, P[:1]])
    j = np.clip(np.searchsorted(s, u, side="right") - 1, 0, len(P) - 1)
    t = ((u - s[j]) / np.maximum(s[j + 1] - s[j], 1e-300))[:, None]
    return (1 - t) * Q[j] + t * Q[j + 1]


def find_corners(P: np.ndarray, angle: float = CORNER_ANGLE, reach: float = CORNER_REACH) -> list[int]:
    """Indices of the outline's corners, increasing: local maxima of the turn
    (within ``reach``) above ``angle``; at least three (the polygon's
    extreme vertices when the outline has fewer corners, e.g. a circle)."""
    th = _turns(P, reach)
    E = np.roll(P, -1, axis=0) - P
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(E, axis=1))])
    L = s[-1]
    order = np.argsort(-th)
    picked: list[int] = []
    for i in order:
        if th[i] < angle:
            break
        if all(min(abs(s[i] - s[j]), L - abs(s[i] - s[j])) > 2 * reach for j in picked):
            picked.append(int(i))
    if len(picked) < 3:
        for i in (int(np.argmin(P[:, 0])), int(np.argmax(P[:, 0])), int(np.argmin(P[:, 1])), int(np.argmax(P[:, 1]))):
            if i not in picked and all(min(abs(s[i] - s[j]), L - abs(s[i] - s[j])) > 0.1 * L for j in picked):
                picked.append(i)
    return sorted(picked)


def resample(P: np.ndarray, corners: list[int], spacing: float = SPACING) -> tuple[np.ndarray, list[int]]:
    """The outline with each segment between corners resampled to about
    ``spacing`` [m] by arc length (corners kept exactly); the new corner indices."""
    out: list[np.ndarray] = []
    new_corners: list[int] = []
    k = len(P)
    for i, c in enumerate(corners):
        d = corners[(i + 1) % len(corners)]
        idx = (c + np.arange((d - c) % k + 1)) % k if d != c else (c + np.arange(k + 1)) % k
        Q = P[idx]
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))])
        n = max(2, math.ceil(s[-1] / spacing))
        u = np.linspace(0, s[-1], n + 1)[:-1]
        j = np.clip(np.searchsorted(s, u, side="right") - 1, 0, len(Q) - 2)
        t = ((u - s[j]) / np.maximum(s[j + 1] - s[j], 1e-300))[:, None]
        new_corners.append(sum(len(o) for o in out))
        out.append((1 - t) * Q[j] + t * Q[j + 1])
    return np.vstack(out), new_corners


def _straight_run(P: np.ndarray, at_min_x: bool) -> float:
    """[m] vertical extent of the longest run of outline vertices on the
    outline's min x (or max x) line, to 0.1 mm (0 when there is none)."""
    x0 = P[:, 0].min() if at_min_x else P[:, 0].max()
    on = np.abs(P[:, 0] - x0) < 1e-4
    k = len(P)
    best, i = 0.0, 0
    while i < 2 * k:
        if on[i % k]:
            j = i
            while j + 1 < i + k and on[(j + 1) % k]:
                j += 1
            ys = P[(np.arange(i, j + 1)) % k, 1]
            best = max(best, float(np.ptp(ys)))
            i = j + 1
        else:
            i += 1
    return best


def centre_at_min_x(pc: ImportedPiece) -> bool:
    """Whether the piece's centre (fold, centre front/back) edge is its left
    one: as the file says, else the side with the longer straight vertical edge."""
    if pc.center_at_min_x is not None:
        return pc.center_at_min_x
    return _straight_run(pc.sew, True) >= _straight_run(pc.sew, False)


def _unfold(P: np.ndarray, at_min_x: bool) -> np.ndarray | None:
    """A half cut on the fold, mirrored about its fold edge: the vertical
    straight run at its min x (``at_min_x``) or max x; None when there is none."""
    x0 = P[:, 0].min() if at_min_x else P[:, 0].max()
    on = np.abs(P[:, 0] - x0) < 1e-4
    k = len(P)
    if on.sum() < 2:
        return None
    # the longest cyclic run of vertices on the fold line
    best, run, start, best_start = 0, 0, 0, 0
    for i in range(2 * k):
        if on[i % k]:
            if run == 0:
                start = i
            run += 1
            if run > best:
                best, best_start = min(run, k), start
        else:
            run = 0
    if best < 2:
        return None
    ys = P[(best_start + np.arange(best)) % k, 1]
    if abs(ys[-1] - ys[0]) < 0.2 * np.ptp(P[:, 1]):
        return None
    first, last = best_start % k, (best_start + best - 1) % k
    half = P[(last + np.arange((first - last) % k + 1)) % k]  # fold end ... round the piece ... fold start
    mirrored = half[::-1].copy()
    mirrored[:, 0] = 2 * x0 - mirrored[:, 0]
    whole = np.vstack([half, mirrored[1:-1]])
    return whole if signed_area(whole) > 0 else whole[::-1].copy()


LEG_SLENDER = 1.5
"""a trouser leg panel is at least this many times as tall as it is wide"""
CROTCH_DEPTH = (0.1, 0.6)
"""a trouser leg panel's crotch point lies this fraction of its height below its top"""
CROTCH_REACH = 0.2
"""a trouser leg panel's crotch point juts out past its waist's end on that side by at least
this fraction of its width (FreeSewing titan: 0.36 front, 0.48 back; penelope's vent: 0.14)"""


def crotch_side(P: np.ndarray, role: str) -> str:
    """'min' or 'max': the side (of material x) where a trouser leg's front or
    back piece has its crotch point, a corner at the piece's widest reach,
    between ``CROTCH_DEPTH`` of its height below the top, jutting out past the
    waist by ``CROTCH_REACH`` of its width, with the inseam running on down
    from it to the hem; '' when the piece is no trouser leg
    (a skirt's hip curve has no corner there, a vent's corner is low, a
    bodice is not slender enough)."""
    if role not in ("front", "back"):
        return ""
    H, W = float(np.ptp(P[:, 1])), float(np.ptp(P[:, 0]))
    if H < LEG_SLENDER * W:
        return ""
    corners = find_corners(P)
    top, bottom = float(P[:, 1].max()), float(P[:, 1].min())
    for side, i in (("max", int(np.argmax(P[:, 0]))), ("min", int(np.argmin(P[:, 0])))):
        depth = (top - P[i, 1]) / H
        near = min(corners, key=lambda c: float(np.linalg.norm(P[c] - P[i])))
        if not (CROTCH_DEPTH[0] <= depth <= CROTCH_DEPTH[1]) or np.linalg.norm(P[near] - P[i]) > 0.01:
            continue
        # the crotch reaches well past the waist's end on that side (a skirt's vent juts out a few cm)
        upper = P[P[:, 1] >= top - 0.05 * H, 0]
        reach = P[i, 0] - upper.max() if side == "max" else upper.min() - P[i, 0]
        if reach < CROTCH_REACH * W:
            continue
        # the outline below the crotch point on its side reaches the hem: the inseam
        beyond = P[:, 0] >= P[i, 0] - 0.5 * W if side == "max" else P[:, 0] <= P[i, 0] + 0.5 * W
        if float(P[beyond, 1].min()) <= bottom + 0.05 * H:
            return side
    return ""


def _mirror(P: np.ndarray) -> np.ndarray:
    Q = P[::-1].copy()
    Q[:, 0] = -Q[:, 0]
    return Q


# ------------------------------------------------------------------ panels


def panels_of(pieces: list[ImportedPiece], spacing: float = SPACING) -> list[_Panel]:
    """Whole panels: halves unfolded, mirrored pairs doubled, corners found,
    outlines resampled, each panel's top at material y = 0 and left at x = 0."""
    out: list[_Panel] = []
    for pc in pieces:
        P = pc.sew
        crotch = "" if pc.on_fold else crotch_side(P, piece_role(pc))
        # a trouser leg's centre edge is its crotch side (its outseam may be the straighter one)
        center_min = crotch == "min" if crotch else centre_at_min_x(pc)
        if pc.on_fold:
            band = np.ptp(P[:, 1]) > 3 * np.ptp(P[:, 0]) and piece_role(pc) in ("waistband", "binding", "")
            W = None
            if band:  # a band cut on the fold: its fold is a short edge; unfold it along its length
                R = np.column_stack([-P[:, 1], P[:, 0]])  # rotated a quarter turn: the length along x
                U = _unfold(R, at_min_x=False)
                if U is None:
                    U = _unfold(R, at_min_x=True)
                W = U
            else:
                W = _unfold(P, center_min)
            if W is not None:
                P = W
        elif np.ptp(P[:, 1]) > 3 * np.ptp(P[:, 0]) and piece_role(pc) in ("waistband", "binding"):
            P = np.column_stack([-P[:, 1], P[:, 0]])  # a band lies along material x (round the body)
        copies: list[tuple[str, np.ndarray, str]] = []
        if pc.mirrored and pc.cut_count >= 2:
            a, b = P, _mirror(P)
            # a piece drawn with its centre to the left lies on the body's left at the front, its right at the back
            role = piece_role(pc)
            drawn_left = center_min == (role != "back")
            named = _pair_side(pc.name)
            if named:  # a pair exported as one piece under its first half's name: the piece drawn is that half
                drawn_left = named == "left"
            copies = [("left", a if drawn_left else b, ""), ("right", b if drawn_left else a, "")]
        else:
            copies = [("", P, "")]
        for side, Q, _ in copies:
            Q = Q - np.array([Q[:, 0].min(), Q[:, 1].max()])
            corners = find_corners(Q)
            R, rc = resample(Q, corners, spacing)
            name = f"{_pair_stem(pc.name)}_{side}" if side else pc.name
            notches = pc.notches
            out.append(
                _Panel(
                    name,
                    R,
                    rc,
                    notches=np.zeros((0, 2)) if side else notches - np.array([P[:, 0].min(), P[:, 1].max()]),
                    role=piece_role(pc),
                    side=side,
                    source=pc.name + (" (mirrored)" if side and Q is not P else ""),
                )
            )
        if len(copies) == 2:
            out[-2].twin, out[-1].twin = out[-1].name, out[-2].name
        if crotch:
            for p in out[-len(copies) :]:
                _mark_leg(p)
    return out


def _mark_leg(p: _Panel) -> None:
    """Sets a trouser leg panel's leg and crotch corner. Material x runs with
    the leg ring's angle (front, outer side, back, inner side: the left leg's
    front goes from its crotch to its outseam, the right leg's toward its
    crotch), so a front with its crotch at min x is on the left leg, a back
    with its crotch at max x too."""
    side = crotch_side(p.outline, p.role)
    if not side:
        return
    i = int(np.argmax(p.outline[:, 0]) if side == "max" else np.argmin(p.outline[:, 0]))
    k = min(range(len(p.corners)), key=lambda j: float(np.linalg.norm(p.outline[p.corners[j]] - p.outline[i])))
    p.crotch = k
    p.leg = "left" if (side == "min") == (p.role == "front") else "right"


def _leg_parts(p: _Panel) -> tuple[str, str]:
    """(crotch curve, inseam): the names of a leg panel's segments above and
    below its crotch point."""
    n = len(p.corners)
    before, after = f"e{(p.crotch - 1) % n}", f"e{p.crotch}"
    segs = {g.name: g for g in _segments(p)}
    # the inseam runs down to the hem: its far end is the lower one
    low_after = segs[after].pts[-1][1] < segs[before].pts[0][1]
    return (before, after) if low_after else (after, before)


# ------------------------------------------------------------------ seams


@dataclass
class _Seg:
    panel: str
    name: str
    pts: np.ndarray
    length: float
    facing: str
    """'left', 'right', 'top', 'bottom': where its outward normal points"""
    notches: int


def _segments(p: _Panel) -> list[_Seg]:
    out = []
    k = len(p.outline)
    for i, c in enumerate(p.corners):
        d = p.corners[(i + 1) % len(p.corners)]
        n = (d - c) % k or k
        Q = p.outline[(c + np.arange(n + 1)) % k]
        ch = Q[-1] - Q[0]
        # outward normal of a CCW outline: the chord turned clockwise; for a closed loop, the mean edge normal
        E = np.diff(Q, axis=0)
        nrm = np.array([E[:, 1].sum(), -E[:, 0].sum()]) if np.linalg.norm(ch) > 1e-9 else np.array([0.0, 1.0])
        facing = (
            ("right" if nrm[0] > 0 else "left") if abs(nrm[0]) >= abs(nrm[1]) else ("top" if nrm[1] > 0 else "bottom")
        )
        dist = np.array([np.min(np.linalg.norm(Q - q, axis=1)) for q in p.notches]) if len(p.notches) else np.zeros(0)
        out.append(_Seg(p.name, f"e{i}", Q, float(polyline_length(Q)), facing, int((dist < 0.003).sum())))
    return out


def _centre_facing(p: _Panel) -> str:
    """Which side of a mirrored pair's panel meets its twin at the body's
    centre line. Material x grows with theta (front, the body's left, back,
    its right), so the left front panel starts at the centre front (its left
    side), the left back ends at the centre back (its right side), and the
    right-hand panels the other way round."""
    if not p.side:
        return ""
    at_back = p.role == "back"
    return ("right" if at_back else "left") if p.side == "left" else ("left" if at_back else "right")


SLEEVE_EASE = 0.12
"""a sleeve cap may be this fraction longer than its armhole to be set into it"""
SLEEVE_SHORT = 0.10
"""... or this fraction shorter (the armhole eased onto it: Valentina's TShirt_test, 8 %)"""


def _shoulders(p: _Panel, S: list[_Seg]) -> dict[str, tuple[int, int]]:
    """A bodice panel's shoulder seams and the armholes below them: {'right' |
    'left': (shoulder index, armhole index) in ``S``}. A shoulder is a top
    edge sloping down to the panel's side, where the side's topmost edge (the
    armhole) meets it: on the right, the armhole runs up into it (counter-
    clockwise order), on the left down out of it."""
    out: dict[str, tuple[int, int]] = {}
    n = len(S)
    cx = 0.5 * (p.outline[:, 0].min() + p.outline[:, 0].max())
    for i, g in enumerate(S):
        if g.facing != "top" or n < 4:
            continue
        if S[i - 1].facing == "right" and g.pts[0][0] > cx and g.pts[0][1] < g.pts[-1][1]:
            out["right"] = (i, (i - 1) % n)
        if S[(i + 1) % n].facing == "left" and g.pts[-1][0] < cx and g.pts[-1][1] < g.pts[0][1]:
            out["left"] = (i, (i + 1) % n)
    return out


def _split(p: _Panel, seg: int, at: float) -> None:
    """Splits segment ``seg`` of ``p`` at arc length ``at`` [m] from its start:
    a corner (and an outline vertex) there; the later segments' names shift by one."""
    k = len(p.outline)
    c, d = p.corners[seg], p.corners[(seg + 1) % len(p.corners)]
    idx = (c + np.arange((d - c) % k + 1)) % k
    Q = p.outline[idx]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))])
    j = int(np.clip(np.searchsorted(s, at, side="right") - 1, 0, len(Q) - 2))
    t = (at - s[j]) / max(s[j + 1] - s[j], 1e-300)
    q = (1 - t) * Q[j] + t * Q[j + 1]
    after = int(idx[j]) + 1  # the new vertex's index, after outline vertex idx[j]
    p.outline = np.insert(p.outline, after, q, axis=0)
    corners = [ci + 1 if ci >= after else ci for ci in p.corners]
    p.corners = sorted(corners + [after])


def _set_in_sleeves(panels: list[_Panel], used: set[tuple[str, str]], tolerance: float) -> list[Suggestion]:
    """A top's shoulder seams (a front's right shoulder with a back's left one,
    the body's left, and the other way round) and its sleeves set into the
    armholes: each sleeve's cap (its top edge between the underarm seams) is
    split where its front part is as long as the front armhole's share of
    the whole armhole, the part on the front side of the arm
    (:func:`couture.pattern.pieces.arm_front_at_plus_x`) sewn to the front's
    armhole, the other to the back's. Marks the sleeves' ``arm``; adds the
    segments sewn to ``used``."""
    from couture.pattern.pieces import arm_front_at_plus_x

    out: list[Suggestion] = []
    body = [p for p in panels if p.role in ("front", "back") and not p.leg]
    segs = {p.name: _segments(p) for p in body}
    sh = {p.name: _shoulders(p, segs[p.name]) for p in body}
    armholes: dict[str, dict[str, _Seg]] = {}
    for pa in body:
        for pb in body:
            if pa.role == pb.role or "right" not in sh[pa.name] or "left" not in sh[pb.name]:
                continue
            a = segs[pa.name][sh[pa.name]["right"][0]]
            b = segs[pb.name][sh[pb.name]["left"][0]]
            if (a.panel, a.name) in used or (b.panel, b.name) in used:
                continue
            if abs(a.length - b.length) > max(0.005, tolerance * max(a.length, b.length)):
                continue
            conf = 0.7 + 0.3 * (1 - abs(a.length - b.length) / max(0.005, tolerance * max(a.length, b.length)))
            out.append(
                Suggestion(
                    a.panel,
                    a.name,
                    b.panel,
                    b.name,
                    round(conf, 3),
                    "shoulders of a front and a back",
                    a.length,
                    b.length,
                )
            )
            used.update({(a.panel, a.name), (b.panel, b.name)})
            # the front's right side and the back's left are the body's left (material x grows toward it)
            arm = "left" if pa.role == "front" else "right"
            armholes[arm] = {
                pa.role: segs[pa.name][sh[pa.name]["right"][1]],
                pb.role: segs[pb.name][sh[pb.name]["left"][1]],
            }
    sleeves = [p for p in panels if p.role == "sleeve"]
    free_arms: list[str] = [a for a in ("left", "right") if a in armholes]
    for sl in sorted(sleeves, key=lambda p: p.side != "left"):
        arm = sl.side if sl.side in free_arms else (free_arms[0] if free_arms and not sl.side else "")
        if not arm:
            continue
        S = _segments(sl)
        tops = [i for i, g in enumerate(S) if g.facing == "top"]
        if not tops or tops != list(range(tops[0], tops[0] + len(tops))) or len(tops) > 2:
            continue
        front, back = armholes[arm]["front"], armholes[arm]["back"]
        if any(h in used for h in ((front.panel, front.name), (back.panel, back.name))):
            continue
        cap = sum(S[i].length for i in tops)
        hole = front.length + back.length
        if not ((1 - SLEEVE_SHORT) * hole <= cap <= (1 + SLEEVE_EASE) * hole):
            continue
        plus_front = arm_front_at_plus_x(arm)
        if len(tops) == 1:  # the cap in one piece: split it in the armholes' proportion, from its +x end
            first = front if plus_front else back
            _split(sl, tops[0], cap * first.length / hole)
            S = _segments(sl)
            tops = [tops[0], tops[0] + 1]
        parts = (S[tops[0]], S[tops[1]])  # counter-clockwise: the +x part first
        pairs = ((parts[0], front), (parts[1], back)) if plus_front else ((parts[0], back), (parts[1], front))
        for c, h in pairs:
            ease = c.length / h.length - 1
            out.append(
                Suggestion(
                    c.panel,
                    c.name,
                    h.panel,
                    h.name,
                    round(float(np.clip(0.9 - 2 * abs(ease), 0.5, 0.9)), 3),
                    f"sleeve cap into the {h.panel} armhole ({ease * 100:+.0f} % ease)",
                    c.length,
                    h.length,
                )
            )
            used.update({(c.panel, c.name), (h.panel, h.name)})
        sl.arm = arm
        free_arms.remove(arm)
    for arm in free_arms:  # no sleeve set in: a sleeveless top's armholes stay free (bound or faced)
        used.update((h.panel, h.name) for h in armholes[arm].values())
    return out


EXTENSION = 0.005
"""[m] a segment of a mirrored pair's centre edge reaching this far past the
centre line (the centre edge at the waist) is a vent's or a button lap's extension"""


def _beyond_centre(p: _Panel, g: _Seg) -> bool:
    """Whether segment ``g`` of a mirrored pair's panel juts ``EXTENSION`` past
    the panel's centre line, the centre-side segment that reaches highest (a
    pencil skirt's vent extension and the step above it: a pattern maker laps
    the two extensions, sewing only the centre seam above)."""
    side = _centre_facing(p)
    lo, hi = float(p.outline[:, 0].min()), float(p.outline[:, 0].max())
    edge = hi - 0.25 * (hi - lo) if side == "right" else lo + 0.25 * (hi - lo)
    # the centre edge's segments: facing the centre and in the quarter of the panel next to it (not a dart's legs)
    segs = [
        h
        for h in _segments(p)
        if h.facing == side and (h.pts[:, 0].min() >= edge if side == "right" else h.pts[:, 0].max() <= edge)
    ]
    if not segs:
        return False
    top = max(segs, key=lambda h: float(h.pts[:, 1].max()))
    if side == "right":
        return bool(g.pts[:, 0].max() > top.pts[:, 0].max() + EXTENSION)
    return bool(g.pts[:, 0].min() < top.pts[:, 0].min() - EXTENSION)


def suggest_seams(panels: list[_Panel], tolerance: float = LENGTH_TOLERANCE) -> list[Suggestion]:
    """Seams the importer would sew (module docstring), best first."""
    used: set[tuple[str, str]] = set()
    out: list[Suggestion] = _set_in_sleeves(panels, used, tolerance)
    segs = {p.name: _segments(p) for p in panels}
    by = {p.name: p for p in panels}
    # darts: consecutive legs of equal length meeting in a sharp V that points into the panel
    for p in panels:
        S = segs[p.name]
        for i in range(len(S)):
            a, b = S[i], S[(i + 1) % len(S)]
            if (a.panel, a.name) in used or (b.panel, b.name) in used or a.length < MIN_SEAM:
                continue
            if abs(a.length - b.length) > max(0.003, 0.05 * a.length) or a.length > 0.3:
                continue
            u, v = a.pts[0] - a.pts[-1], b.pts[-1] - b.pts[0]
            ang = math.acos(np.clip(u @ v / max(np.linalg.norm(u) * np.linalg.norm(v), 1e-300), -1, 1))
            mouth = 0.5 * (a.pts[0] + b.pts[-1])
            from couture.pattern.geometry import point_in_polygon

            # beyond the apex, away from the mouth, lies cloth: the V is cut into the panel
            apex_inside = bool(point_in_polygon((a.pts[-1] + 0.1 * (a.pts[-1] - mouth))[None], p.outline)[0])
            if ang < DART_ANGLE and apex_inside:
                conf = 0.9 * (1 - abs(a.length - b.length) / max(0.003, 0.05 * a.length)) + 0.1
                out.append(
                    Suggestion(p.name, a.name, p.name, b.name, round(float(conf), 3), "dart legs", a.length, b.length)
                )
                used.update({(a.panel, a.name), (b.panel, b.name)})
    # side seams: a right-facing segment with a left-facing one of another panel (or, for a
    # sleeve, cuff or band, of the same panel: its underarm seam closes it into a tube)
    cands = []
    crotch = {p.name: _leg_parts(p)[0] for p in panels if p.leg}
    for pa in panels:
        for pb in panels:
            tube = pa.role in TUBE_ROLES
            if pa.name == pb.name and not tube:
                continue
            if pa.name != pb.name and tube and pb.role in TUBE_ROLES and by[pa.name].twin == pb.name:
                continue  # a left and a right sleeve are on opposite arms
            legs = pa.leg and pb.leg
            if legs and pa.leg != pb.leg and pa.role != pb.role:
                continue  # one leg's front and the other's back do not meet
            for a in segs[pa.name]:
                if a.facing != "right" or a.length < MIN_SEAM or (a.panel, a.name) in used:
                    continue
                for b in segs[pb.name]:
                    if b.facing != "left" or b.length < MIN_SEAM or (b.panel, b.name) in used:
                        continue
                    if legs and ((a.name == crotch[pa.name]) != (pa.leg != pb.leg)):
                        continue  # the legs meet at their crotch curves only, a leg's front and back elsewhere
                    if legs and ((b.name == crotch[pb.name]) != (pa.leg != pb.leg)):
                        continue
                    tol = max(0.005, tolerance * max(a.length, b.length))
                    rel = abs(a.length - b.length) / tol
                    if rel > 1:
                        continue
                    reasons = ["lengths agree"]
                    conf = 0.55 * (1 - rel)
                    if a.notches == b.notches:
                        conf += 0.15
                        if a.notches:
                            reasons.append(f"{a.notches} notches each")
                    if legs:
                        conf += 0.3
                        reasons.append("crotch seam" if pa.leg != pb.leg else f"front and back of the {pa.leg} leg")
                    elif by[pa.name].twin == pb.name:
                        # twins meet at their centre edges only (their other sides are across the body)
                        if a.facing != _centre_facing(by[pa.name]) or b.facing != _centre_facing(by[pb.name]):
                            continue
                        if _beyond_centre(by[pa.name], a) or _beyond_centre(by[pb.name], b):
                            continue  # a vent's or a lap's extension: lapped over its twin, not sewn to it
                        conf += 0.3
                        reasons.append("mirrored pair")
                    elif {by[pa.name].role, by[pb.name].role} == {"front", "back"}:
                        conf += 0.3
                        reasons.append("front and back")
                    elif pa.name == pb.name:
                        conf += 0.3
                        reasons.append(f"closes the {pa.role} into a tube")
                    elif by[pa.name].role and by[pa.name].role == by[pb.name].role:
                        conf += 0.1
                    cands.append((conf, a, b, ", ".join(reasons)))
    cands.sort(key=lambda c: -c[0])
    for conf, a, b, why in cands:
        if (a.panel, a.name) in used or (b.panel, b.name) in used:
            continue
        out.append(
            Suggestion(a.panel, a.name, b.panel, b.name, round(float(min(conf, 1.0)), 3), why, a.length, b.length)
        )
        used.update({(a.panel, a.name), (b.panel, b.name)})
    return out


def free_edges(panels: list[_Panel], seams: list[Suggestion]) -> list[tuple[str, str, float]]:
    """(panel, segment, length [m]) of every segment no seam uses."""
    used = {(s.a_panel, s.a_segment) for s in seams} | {(s.b_panel, s.b_segment) for s in seams}
    return [(g.panel, g.name, g.length) for p in panels for g in _segments(p) if (g.panel, g.name) not in used]


# ------------------------------------------------------------------ placement

_ROLE_ANGLE = {"front": 0.0, "back": math.pi}


def ring_order(panels: list[_Panel], seams: list[Suggestion]) -> list[str]:
    """The torso panels in theta order: from the front, following side seams
    (a panel's right side sewn to the next one's left); panels the chain
    misses are put in by role."""
    torso = [
        p
        for p in panels
        if p.role not in ("sleeve", "waistband", "collar", "cuff", "binding", "pocket", "facing")
        and not p.leg
        and not p.arm
        and (p.role or max(np.ptp(p.outline[:, 0]), np.ptp(p.outline[:, 1])) >= SMALL_PIECE)
    ]
    if not torso:
        return []
    names = {p.name for p in torso}
    nxt: dict[str, str] = {}
    segs = {p.name: {g.name: g for g in _segments(p)} for p in torso}
    for s in seams:
        if s.a_panel == s.b_panel or s.a_panel not in names or s.b_panel not in names:
            continue
        fa, fb = segs[s.a_panel][s.a_segment].facing, segs[s.b_panel][s.b_segment].facing
        if fa == "right" and fb == "left":
            nxt.setdefault(s.a_panel, s.b_panel)
        elif fa == "left" and fb == "right":
            nxt.setdefault(s.b_panel, s.a_panel)

    def angle(p: _Panel) -> float:
        a = _ROLE_ANGLE.get(p.role, math.pi / 2)
        if p.side == "left":
            a += -0.25 * math.pi if p.role == "back" else 0.25 * math.pi
        elif p.side == "right":
            a += 0.25 * math.pi if p.role == "back" else -0.25 * math.pi + 2 * math.pi
        return a % (2 * math.pi)

    start = min(torso, key=lambda p: (angle(p) if angle(p) <= math.pi else angle(p) - 2 * math.pi) ** 2)
    order = [start.name]
    while nxt.get(order[-1]) and nxt[order[-1]] not in order:
        order.append(nxt[order[-1]])
    rest = sorted((p for p in torso if p.name not in order), key=angle)
    return order + [p.name for p in rest]


BAND_SLACK = 0.10
"""a waistband's long edge may differ from the waist it is sewn to by this fraction
(longer: the rest, an overlap for the closure, stays free)"""


BAND_REACH = 0.04
"""[m] a waist edge lies within this of its panel's top"""


def sew_band(panels: list[_Panel], seams: list[Suggestion], order: list[str]) -> tuple[list[Suggestion], float]:
    """A waistband sewn to the garment's waist: the torso ring's free top
    edges (between the darts, after every other seam), panel by panel round
    the body from the opening (between a mirrored pair of backs, else of
    fronts, else at the first panel's start), each sewn to a part of the
    band's long lower edge as long as it (the band split there; an overlap
    left at its end stays free). Marks the band; returns the seams and the
    opening's angle [rad] round the ring from the ring's start."""
    bands = [p for p in panels if p.role == "waistband" and p.name not in order and not p.leg]
    if len(bands) != 1 or not order:
        return [], 0.0
    band = bands[0]
    by = {p.name: p for p in panels}
    used = {(s.a_panel, s.a_segment) for s in seams} | {(s.b_panel, s.b_segment) for s in seams}
    start = 0
    for role in ("back", "front"):
        for i, n in enumerate(order):
            prev = order[i - 1]
            if by[n].role == role and by[prev].twin == n:
                start = i
                break
        else:
            continue
        break
    ring = order[start:] + order[:start]
    waist: list[_Seg] = []
    for n in ring:
        y0 = float(by[n].outline[:, 1].max())
        # the waist line: free top edges at the panel's top (not a vent's step further down)
        top = [
            g
            for g in _segments(by[n])
            if g.facing == "top" and (n, g.name) not in used and g.pts[:, 1].min() > y0 - BAND_REACH
        ]
        waist += sorted(top, key=lambda g: float(g.pts[:, 0].mean()))  # material x runs with the angle
    W = sum(g.length for g in waist)
    S = _segments(band)
    lows = [i for i, g in enumerate(S) if g.facing == "bottom"]
    if not waist or not lows:
        return [], 0.0
    k = max(lows, key=lambda i: S[i].length)
    B = S[k].length
    if not (1 - BAND_SLACK) * W <= B <= (1 + BAND_SLACK) * W:
        return [], 0.0
    scale = min(1.0, B / W)
    for g in waist[:-1] if B <= W else waist:  # split off each waist piece's length, from the band's start
        _split(band, k, g.length * scale)
        k += 1
    S = _segments(band)
    first = k - (len(waist) - 1 if B <= W else len(waist))
    out = []
    for j, g in enumerate(waist):
        h = S[first + j]
        out.append(
            Suggestion(
                band.name,
                h.name,
                g.panel,
                g.name,
                0.8,
                f"waistband to the waist ({j + 1} of {len(waist)})",
                h.length,
                g.length,
            )
        )
    band.band = True
    w = [float(np.ptp(by[n].outline[:, 0])) for n in order]
    # the opening's angle from the first ring panel's start edge
    return out, 2 * math.pi * sum(w[:start]) / max(sum(w), 1e-9)


COLLAR_ROLES = ("collar", "binding")
"""pieces that may be sewn to the neckline"""
NECK_SLACK = 0.10
"""a collar's neck edge may differ from the neckline it is sewn to by this
fraction (a knit binding is cut about 5 % short and stretched on)"""
BINDING_EASE = 0.02
"""a binding may be at most this fraction longer than the edge it binds"""
COLLAR_SLENDER = 4.0
"""an unnamed piece at least this many times as long as it is wide is a band (a collar candidate)"""


def _turn(p: _Panel, quarter: bool) -> None:
    """Turns a panel's outline (and notches) a quarter turn (x, y) -> (-y, x) or
    a half turn, in place, its top at y = 0 and left at x = 0 again (corner
    indices and segment names unchanged)."""

    def t(Q: np.ndarray) -> np.ndarray:
        return np.column_stack([-Q[:, 1], Q[:, 0]]) if quarter else -Q

    P = t(p.outline)
    shift = np.array([P[:, 0].min(), P[:, 1].max()])
    p.outline = P - shift
    if len(p.notches):
        p.notches = t(p.notches) - shift


def sew_collar(
    panels: list[_Panel], seams: list[Suggestion], order: list[str], notes: list[str], angle0: float = 0.0
) -> tuple[list[Suggestion], float]:
    """A collar (or a neck band, a neck binding) sewn to the neckline: the
    torso ring's free top edges (after every other seam: the shoulders sewn,
    the armholes taken by sleeves or left free), panel by panel round the body
    from the opening (between a mirrored pair of fronts not sewn together,
    else of backs; none: a closed neckline, the collar's two ends sewn into a
    loop when the neckline runs round every bodice panel), each sewn to a
    part of the collar's neck edge as long as it (the collar split there, an
    overlap at the end left free). The collar: a piece
    of role collar or binding, or an unnamed band ``COLLAR_SLENDER`` times as
    long as wide, whose long edge is within ``NECK_SLACK`` of the neckline's
    length (the one nearest it; the collar is turned so that edge is its
    bottom). Removes any other seam the collar had; marks it ``neck``;
    returns the seams and the angle [rad] of the collar's centre round the
    neck (theta = 0 the front): each part as near the angle of its neckline
    piece round the torso ring (its first panel centred at ``angle0``) as
    the parts' spacing round the neck lets it be."""
    torso = [n for n in order if any(p.name == n and p.role in ("front", "back") for p in panels)]
    if not torso:
        return [], 0.0
    by = {p.name: p for p in panels}

    def candidate(p: _Panel) -> bool:
        if p.name in order or p.leg or p.arm or p.band:
            return False
        low = p.name.lower()
        if re.search(r"arm|sleeve|waist|hem|cuff|leg", low) and not re.search(r"neck|collar", low):
            return False  # named for another edge (an armhole's binding)
        if p.role in COLLAR_ROLES:
            return True
        w, h = np.ptp(p.outline, axis=0)
        return not p.role and max(w, h) >= COLLAR_SLENDER * min(w, h)

    cands = [p for p in panels if candidate(p)]
    if not cands:
        return [], 0.0
    # the neckline: free top edges of the bodice panels, after every seam but the collars'
    others = [s for s in seams if s.a_panel not in {c.name for c in cands} and s.b_panel not in {c.name for c in cands}]
    used = {(s.a_panel, s.a_segment) for s in others} | {(s.b_panel, s.b_segment) for s in others}
    start, opening = 0, ""
    for role in ("front", "back"):
        for i, n in enumerate(torso):
            prev = torso[i - 1]
            sewn = any({s.a_panel, s.b_panel} == {n, prev} for s in others)
            if by[n].role == role and by[prev].twin == n and not sewn:
                start, opening = i, role
                break
        if opening:
            break
    ring = torso[start:] + torso[:start]
    neckline: list[_Seg] = []
    for n in ring:
        top = [g for g in _segments(by[n]) if g.facing == "top" and (n, g.name) not in used]
        neckline += sorted(top, key=lambda g: float(g.pts[:, 0].mean()))  # material x runs with the angle
    W = sum(g.length for g in neckline)
    if not neckline or W <= 0:
        return [], 0.0
    best: tuple[float, _Panel] | None = None
    for c in cands:
        w, h = np.ptp(c.outline, axis=0)
        if h > w:
            _turn(c, quarter=True)  # a band lies along material x (round the neck)
        L = max((g.length for g in _segments(c) if g.facing in ("top", "bottom")), default=0.0)
        d = abs(L / W - 1)
        if c.role == "binding" and L > (1 + BINDING_EASE) * W:
            continue  # a binding is stretched onto its edge, never eased
        if d <= NECK_SLACK and (best is None or d < best[0]):
            best = (d, c)
    if best is None:
        return [], 0.0
    col = best[1]
    # its long edge nearest the neckline's length is the neck edge: turned to the bottom
    edge = min((g for g in _segments(col) if g.facing in ("top", "bottom")), key=lambda g: abs(g.length - W))
    if edge.facing == "top":
        _turn(col, quarter=False)
    seams[:] = [s for s in seams if col.name not in (s.a_panel, s.b_panel)]
    S = _segments(col)
    k = max((i for i, g in enumerate(S) if g.facing == "bottom"), key=lambda i: S[i].length)
    B = S[k].length
    scale = min(1.0, B / W)
    over = B > W + 0.005  # an overlap past the neckline's end, left free (a shorter rest is the last part's)
    for g in neckline if over else neckline[:-1]:  # split off each neckline piece's length, from the start
        _split(col, k, g.length * scale)
        k += 1
    S = _segments(col)
    first = k - (len(neckline) if over else len(neckline) - 1)
    out = [
        Suggestion(
            col.name,
            S[first + j].name,
            g.panel,
            g.name,
            0.8,
            f"collar to the neckline ({j + 1} of {len(neckline)})",
            S[first + j].length,
            g.length,
        )
        for j, g in enumerate(neckline)
    ]
    ends = [g for g in S if g.facing in ("left", "right")]
    round_all = {g.panel for g in neckline} == set(torso)
    if (
        not opening
        and round_all
        and len(ends) == 2
        and abs(ends[0].length - ends[1].length) <= max(0.005, 0.03 * ends[0].length)
    ):
        a, b = sorted(ends, key=lambda g: g.facing != "right")
        out.append(
            Suggestion(col.name, a.name, col.name, b.name, 0.8, "closes the collar into a loop", a.length, b.length)
        )
    col.neck = True
    notes.append(
        f"{col.name} sewn to the neckline in {len(neckline)} part{'s' if len(neckline) > 1 else ''} ({B * 100:.1f} cm to {W * 100:.1f} cm, "
        f"{(B / W - 1) * 100:+.0f} %), round the neck from "
        + (
            f"the centre {opening} opening"
            if opening
            else f"{neckline[0].panel}'s neckline" + (", its ends sewn" if out[-1].a_panel == out[-1].b_panel else "")
        )
        + "; one layer: a stand and its fall, or a collar's two plies, are not modelled"
    )
    # where each neckline piece lies round the torso ring (material x runs with theta) ...
    w = {n: float(np.ptp(by[n].outline[:, 0])) for n in order}
    total = max(sum(w.values()), 1e-9)
    pstart, acc = {}, angle0 - math.pi * w[order[0]] / total
    for n in order:
        pstart[n] = acc - 2 * math.pi * float(by[n].outline[:, 0].min()) / total
        acc += 2 * math.pi * w[n] / total
    # ... and where its collar part's middle lies round the neck, from the collar's start
    from couture.pattern.landmarks import neck

    G = max(B, neck().girth + 2 * math.pi * 0.01)
    lag = [
        pstart[g.panel]
        + 2 * math.pi * float(g.pts[:, 0].mean()) / total
        - 2 * math.pi * (sum(h.length for h in neckline[:j]) * scale + 0.5 * g.length * scale) / G
        for j, g in enumerate(neckline)
    ]
    wt = np.array([g.length for g in neckline])
    theta_start = math.atan2(float(wt @ np.sin(lag)), float(wt @ np.cos(lag)))
    return out, theta_start + math.pi * B / G


def is_top(panels: list[_Panel]) -> bool:
    """A garment worn from the shoulders (has a sleeve, a collar, a yoke, or 'shirt'/'top' pieces)."""
    return any(p.role in ("sleeve", "collar", "yoke") for p in panels) or any(
        re.search(r"shirt|bodice|top|blouse|dress|tee", p.source.lower()) for p in panels
    )


# ------------------------------------------------------------------ the design


def _held_by_nothing(panels: list[_Panel], seams: list[Suggestion], placed: set[str]) -> list[str]:
    """The pieces that no chain of seams joins to a piece placed on the body (a
    ring, or inside one): laid flat in front of the body, nothing holds them
    (Valentina's TShirt_test in AAMA: its front neck facing, no seam suggested)."""
    nbr: dict[str, set[str]] = {p.name: set() for p in panels}
    for s in seams:
        nbr[s.a_panel].add(s.b_panel)
        nbr[s.b_panel].add(s.a_panel)
    held = {n for n in placed if n in nbr}
    todo = list(held)
    while todo:
        for m in nbr[todo.pop()] - held:
            held.add(m)
            todo.append(m)
    return [p.name for p in panels if p.name not in held]


@dataclass
class ImportReport:
    """What ``couture import`` found and decided."""

    panels: list[str]
    seams: list[Suggestion]
    free: list[tuple[str, str, float]]
    order: list[str]
    landmark: str
    notes: list[str] = field(default_factory=list)


HALF_GIRTH = 0.6
"""torso pieces whose widths add up to less than this fraction of the body's hip
girth (and at least half of that) are halves cut on the fold that the file does
not mark (Valentina's DXF)"""
_NOT_TORSO = ("sleeve", "waistband", "collar", "cuff", "binding", "pocket", "facing")


def _halves_unfolded(pieces: list[ImportedPiece], body: str, notes: list[str]) -> list[ImportedPiece]:
    """The pieces, with the torso pieces marked 'cut on the fold' when they are
    too narrow together to go round the body (``HALF_GIRTH``) and each has a
    straight vertical edge to unfold about."""
    from dataclasses import replace

    from couture.bodies import measured

    torso = [p for p in pieces if piece_role(p) not in _NOT_TORSO and not _small(p)]
    if not torso:
        return pieces
    girth = sum(
        float(np.ptp(p.sew[:, 0])) * (2 if p.on_fold else 1) * (2 if p.mirrored and p.cut_count >= 2 else 1)
        for p in torso
    )
    hip = float(measured(body)["hip_girth"])
    if not (0.5 * HALF_GIRTH * hip <= girth < HALF_GIRTH * hip):
        return pieces  # whole garment pieces, or too little for half a garment (a collar, a test swatch)
    candidates = [p for p in torso if not p.on_fold and not p.mirrored]
    if not candidates or any(
        max(_straight_run(p.sew, True), _straight_run(p.sew, False)) < 0.5 * np.ptp(p.sew[:, 1]) for p in candidates
    ):
        return pieces
    notes.append(
        f"the torso pieces add up to {girth * 100:.0f} cm round, less than {HALF_GIRTH:g} of the body's hip "
        f"({hip * 100:.0f} cm): read as halves cut on the fold ({', '.join(p.name for p in candidates)}), "
        "each unfolded about its straight centre edge"
    )
    ids = {id(p) for p in candidates}
    return [replace(p, on_fold=True) if id(p) in ids else p for p in pieces]


SLEEVE_CAP = 0.08
"""[m] a piece whose top rises at least this high (and 0.1 of its width) above
its top corners, in the middle of a left-right symmetric outline, is a sleeve
(its cap); a whole bodice or skirt panel dips or lies flat there"""
SYMMETRY = 0.02
"""[m] how far a symmetric outline's mirror image may lie from it"""
SMALL_PIECE = 0.30
"""[m] unnamed pieces whose height and width are both under this (a facing, a
binding, a pocket) get no role from their shape"""


def _small(pc: ImportedPiece) -> bool:
    """An unnamed piece under ``SMALL_PIECE`` both ways (a facing, a binding): no bodice part."""
    return not piece_role(pc) and max(np.ptp(pc.sew[:, 0]), np.ptp(pc.sew[:, 1])) < SMALL_PIECE


def _is_sleeve_shape(P: np.ndarray) -> bool:
    """A sleeve's outline: symmetric about its vertical centre line, its
    highest point (the cap top) in the middle, ``SLEEVE_CAP`` above the ends
    of the cap (the outline's corners nearest the top left and top right)."""
    P = resample(P, find_corners(P), 0.005)[0]  # evenly spaced: a straight side has two vertices as drawn
    W = float(np.ptp(P[:, 0]))
    xc = 0.5 * (P[:, 0].min() + P[:, 0].max())
    M = P.copy()
    M[:, 0] = 2 * xc - M[:, 0]
    d = np.sqrt(((M[:, None, :] - P[None, :, :]) ** 2).sum(-1)).min(axis=1)
    if d.max() > SYMMETRY:
        return False
    top = int(np.argmax(P[:, 1]))
    if abs(P[top, 0] - xc) > 0.15 * W:
        return False
    corners = find_corners(P)
    left = [c for c in corners if P[c, 0] < xc - 0.25 * W]
    right = [c for c in corners if P[c, 0] > xc + 0.25 * W]
    if not left or not right:
        return False
    ends = min(max(P[left, 1]), max(P[right, 1]))
    return bool(P[top, 1] - ends >= max(SLEEVE_CAP, 0.1 * W))


def _neck_depth(pc: ImportedPiece) -> float:
    """[m] how far below the piece's top its outline meets its centre line
    (the fold edge of a half cut on the fold, else the middle): a front's
    neckline is the deeper one."""
    P = pc.sew
    if pc.on_fold:
        xc = P[:, 0].min() if centre_at_min_x(pc) else P[:, 0].max()
    else:
        xc = 0.5 * (P[:, 0].min() + P[:, 0].max())
    near = np.abs(P[:, 0] - xc) < 0.01
    return float(P[:, 1].max() - P[near, 1].max()) if near.any() else 0.0


def roles_by_shape(pieces: list[ImportedPiece], notes: list[str]) -> list[ImportedPiece]:
    """The pieces, those whose names say nothing ('Detail_2', 'piece1')
    given a role by their shape: a sleeve (:func:`_is_sleeve_shape`); of two
    bodice pieces left, once halves are unfolded, the one with the deeper
    neckline the front (by more than 5 cm, else nothing is said). Pieces
    smaller than ``SMALL_PIECE`` both ways get none. A sleeve given once is
    cut as a pair (a left and a right)."""
    from dataclasses import replace

    out = []
    for pc in pieces:
        small = max(np.ptp(pc.sew[:, 0]), np.ptp(pc.sew[:, 1])) < SMALL_PIECE
        if not piece_role(pc) and not small and _is_sleeve_shape(pc.sew):
            notes.append(f"{pc.name}: a sleeve by its shape (a symmetric piece with a cap on top)")
            pc = replace(pc, role="sleeve")
        if piece_role(pc) == "sleeve" and pc.cut_count < 2 and not pc.on_fold:
            notes.append(f"{pc.name}: a sleeve given once, cut as a pair (a left and a right)")
            pc = replace(pc, cut_count=2, mirrored=True)
        out.append(pc)
    return out


def fronts_by_neckline(pieces: list[ImportedPiece], notes: list[str]) -> list[ImportedPiece]:
    """Of exactly two unnamed bodice pieces (no role, not small), the one whose
    neckline is deeper by more than 5 cm becomes the front, the other the back."""
    from dataclasses import replace

    unnamed = [
        i
        for i, pc in enumerate(pieces)
        if not piece_role(pc) and max(np.ptp(pc.sew[:, 0]), np.ptp(pc.sew[:, 1])) >= SMALL_PIECE
    ]
    if len(unnamed) != 2:
        return pieces
    (i, a), (j, b) = ((k, _neck_depth(pieces[k])) for k in unnamed)
    if abs(a - b) <= 0.05:
        return pieces
    front, back = (i, j) if a > b else (j, i)
    notes.append(
        f"{pieces[front].name}: the front, {pieces[back].name}: the back (necklines {max(a, b) * 100:.0f} and "
        f"{min(a, b) * 100:.0f} cm deep at the centre)"
    )
    out = list(pieces)
    out[front], out[back] = replace(out[front], role="front"), replace(out[back], role="back")
    return out


def _pair_side(name: str) -> str:
    """'left' or 'right' when a 'Cut 2' piece's name ends '_left' or '_right'
    (a pair couture exported as one piece under its first half's name, drawn
    as that half), else ''."""
    for side in ("left", "right"):
        if name.endswith("_" + side) and len(name) > len(side) + 1:
            return side
    return ""


def _pair_stem(name: str) -> str:
    """The name a 'Cut 2' piece's left and right halves are named after: the
    piece's own, less a trailing '_left' or '_right' (:func:`_pair_side`: the
    exported pair imports back as 'back_left' and 'back_right', not as
    'back_left_left' and 'back_left_right')."""
    side = _pair_side(name)
    return name[: -len(side) - 1] if side else name


def build_design(
    pieces: list[ImportedPiece],
    *,
    body: str | Body = "default",
    landmark: str | None = None,
    exclude: tuple[str, ...] = (),
    min_confidence: float = 0.5,
    stretch_stiffness: float = WOVEN_STRETCH_STIFFNESS,
) -> tuple[Design, ImportReport]:
    """A design of the imported pieces: free-form pieces, the suggested seams
    at or above ``min_confidence`` as seam strokes, the torso ring in seam
    order with its top at the body's waist (``landmark`` 'waist') or
    shoulder ('shoulder'; default: 'shoulder' for a top, else 'waist').
    Pieces named in ``exclude`` are left out; pieces that are neither torso
    pieces nor placed lie flat in front of the body. ``body``: a body's name,
    or a Body (one with measurements: couture.bodies.use)."""
    from couture import bodies
    from couture.bodies import measured

    body_msg = body if isinstance(body, Body) else Body(name=body)
    try:
        body = bodies.use(body_msg)
    except ValueError as e:
        raise PatternError("body", str(e)) from None
    kept = [p for p in pieces if p.name not in exclude]
    if not kept:
        raise PatternError("pieces", f"no pieces left to import (all of {[p.name for p in pieces]} excluded)")
    notes: list[str] = []
    kept = roles_by_shape(kept, notes)
    kept = _halves_unfolded(kept, body, notes)
    kept = fronts_by_neckline(kept, notes)
    panels = panels_of(kept)
    seams = [s for s in suggest_seams(panels) if s.confidence >= min_confidence]
    order = ring_order(panels, seams)
    # a top: sleeves, a collar, a shirt's name, or shoulders sewn (a sleeveless top)
    shoulders = any(s.reason.startswith("shoulders") for s in seams)
    lm = landmark or ("shoulder" if is_top(panels) or shoulders else "waist")
    if lm not in ("waist", "shoulder"):
        raise PatternError("landmark", f"landmark {lm!r} is not 'waist' or 'shoulder'")
    from couture.pattern.landmarks import neck

    m0 = measured("default")
    nk = neck("default")
    # a top: its highest points (the shoulders' neck ends) at the neck's base, moved with
    # the body's neck base (and down where its armholes would not clear the armpits)
    height = float(m0["waist_y"]) + 0.02 if lm == "waist" else nk.base_y
    pos = {n: i for i, n in enumerate(order)}
    # the first panel's centre angle: the front panel centred at theta = 0, or a front pair's seam there
    by = {p.name: p for p in panels}
    angle0 = 0.0
    if order and by[order[0]].side:
        w = [np.ptp(by[n].outline[:, 0]) for n in order]
        angle0 = float(math.pi * w[0] / max(sum(w), 1e-9))
    band_seams, opening = ([], 0.0) if lm != "waist" else sew_band(panels, seams, order)
    seams += band_seams
    collar_seams, collar_angle = sew_collar(panels, seams, order, notes, angle0) if lm == "shoulder" else ([], 0.0)
    seams += collar_seams
    rings = {n: "torso" for n in pos}
    for p in panels:
        if p.leg:
            # a leg's ring runs front, outer side, back (left leg) or back, outer side, front (right leg)
            rings[p.name] = f"{p.leg}_leg"
            pos[p.name] = int((p.role == "back") == (p.leg == "left"))
        elif p.arm:
            rings[p.name], pos[p.name] = f"{p.arm}_arm", 0
        elif p.band:
            rings[p.name], pos[p.name] = "band", 0
        elif p.neck:
            rings[p.name], pos[p.name] = "neck", 0
    for kind in ("left_leg", "right_leg", "left_arm", "right_arm"):
        on = sorted((n for n, r in rings.items() if r == kind), key=lambda n: pos[n])
        if on:
            notes.append(f"placed round the {kind.replace('_', ' ')}: {' -> '.join(on)}")
    band_angle = 0.0
    if band_seams:
        # the band starts at the opening and runs round with the angle: its centre half its length on
        w = [float(np.ptp(by[n].outline[:, 0])) for n in order]
        start = angle0 - math.pi * w[0] / max(sum(w), 1e-9) + opening
        b = next(p for p in panels if p.band)
        band_angle = float(start + math.pi * np.ptp(b.outline[:, 0]) / max(sum(w), 1e-9))
        notes.append(f"{b.name} sewn to the waist in {len(band_seams)} parts, round the body from the opening")
    neck_base = nk.base_y
    for p in panels:
        if p.neck and float(np.ptp(p.outline[:, 1])) > nk.top_y - nk.base_y:
            notes.append(
                f"{p.name} stands {np.ptp(p.outline[:, 1]) * 100:.1f} cm from the neck's base, above the jaw "
                f"({(nk.top_y - nk.base_y) * 100:.1f} cm up): placed round the head's section there; a collar "
                "that folds down (its fall) is not modelled"
            )
    # a facing (or a small unnamed piece) sewn to a placed piece: laid just inside it
    placed = set(rings)
    for p in panels:
        small = not p.role and max(np.ptp(p.outline, axis=0)) < SMALL_PIECE
        if p.name in rings or not (p.role == "facing" or small):
            continue
        faced = sorted(
            {s.b_panel for s in seams if s.a_panel == p.name and s.b_panel in placed}
            | {s.a_panel for s in seams if s.b_panel == p.name and s.a_panel in placed}
        )
        if faced:
            rings[p.name], pos[p.name] = "inside", 0
            notes.append(
                f"{p.name}: a facing, laid just inside {', '.join(faced)} (the piece it is sewn to); the two "
                "layers do not collide with each other (no cloth-cloth contact): it may pass through"
            )
    unplaced = [p.name for p in panels if p.name not in rings and p.role in ("facing", "binding")]
    if unplaced:
        notes.append(
            f"{', '.join(unplaced)}: a facing or binding sewn to no placed piece; a binding folded over its "
            "edge is not modelled: left out of the design"
        )
        seams = [s for s in seams if s.a_panel not in unplaced and s.b_panel not in unplaced]
        panels = [p for p in panels if p.name not in unplaced]
    loose = _held_by_nothing(panels, seams, set(rings)) if rings else []
    if loose:
        notes.append(
            f"{', '.join(loose)}: sewn to no piece on the body (no seam at confidence >= {min_confidence:g}) "
            "and on no ring: in a drape it would fall (nothing holds it) and the drape could not converge: "
            "left out of the design (sew it by hand: a seam in the design file, or --min-confidence)"
        )
        seams = [s for s in seams if s.a_panel not in loose and s.b_panel not in loose]
        panels = [p for p in panels if p.name not in loose]
    out_pieces = []
    for p in panels:
        out_pieces.append(
            Piece(
                name=p.name,
                outline=[(float(x), float(y)) for x, y in p.outline],
                corners=list(p.corners),
                notches=[(float(x), float(y)) for x, y in p.notches],
                grain=p.grain,
                role=p.role,
                source=p.source,
                placement=PiecePlacement(
                    ring=rings.get(p.name, "flat"),  # type: ignore[arg-type]
                    position=pos.get(p.name, 0),
                    landmark="neck" if lm == "shoulder" and rings.get(p.name) == "torso" else "waist",
                    angle=angle0
                    if rings.get(p.name) == "torso"
                    else (band_angle if p.band else collar_angle if p.neck else 0.0),
                    height=height + float(np.ptp(p.outline[:, 1]))
                    if p.band
                    else neck_base + float(np.ptp(p.outline[:, 1]))
                    if p.neck
                    else height,
                ),
            )
        )
    _pair_mirrors(panels, out_pieces, notes)
    strokes = [
        Stroke(
            id=f"seam:{s.a_panel}:{s.a_segment}:{s.b_panel}:{s.b_segment}",
            kind="seam",
            params={
                "a_panel": s.a_panel,
                "a_segment": s.a_segment,
                "b_panel": s.b_panel,
                "b_segment": s.b_segment,
                "confidence": s.confidence,
                "reason": s.reason,
            },
        )
        for s in seams
    ]
    design = Design(
        sloper=Sloper(kind="none"),
        strokes=strokes,
        pieces=out_pieces,
        body=body_msg,
        fabric=Fabric(name="woven", stretch_stiffness=stretch_stiffness),
    )
    report = ImportReport(
        panels=[p.name for p in panels],
        seams=seams,
        free=free_edges(panels, seams),
        order=order,
        landmark=lm,
        notes=notes,
    )
    return design, report


MIRROR_MATCH = 1e-9
"""[m] a 'Cut 2' pair's panels are taken for mirror images within this (they
are built as such: measured 1e-15 m)"""


def _mirror_index(A: np.ndarray, B: np.ndarray, a_corners: list[int], b_corners: list[int]) -> int | None:
    """r with B[j] = (c - A[(r - j) mod k].x, A[(r - j) mod k].y) for one c,
    within ``MIRROR_MATCH``, and the corners mirrored likewise; None when there is none."""
    k = len(A)
    if len(B) != k:
        return None
    j = np.arange(k)
    for r in np.flatnonzero(np.abs(A[:, 1] - B[0, 1]) <= MIRROR_MATCH):
        M = A[(r - j) % k] * np.array([-1.0, 1.0])
        M[:, 0] += B[0, 0] - M[0, 0]
        if np.abs(M - B).max() <= MIRROR_MATCH and sorted((r - np.asarray(a_corners)) % k) == list(b_corners):
            return int(r)
    return None


def _pair_mirrors(panels: list[_Panel], pieces: list[Piece], notes: list[str]) -> None:
    """Mark each 'Cut 2' pair (a panel and its ``twin``) as mirror images of
    each other (``Piece.mirror_of``, ``mirror_index``), the second's outline set
    to the first's exact mirror, so that an edit of either applies to both."""
    from couture.pattern.pieces import mirror_outline

    by = {pc.name: pc for pc in pieces}
    for p in panels:
        a, b = by.get(p.name), by.get(p.twin)
        if a is None or b is None or a.mirror_of or pieces.index(a) > pieces.index(b):
            continue
        A, B = np.asarray(a.outline, float), np.asarray(b.outline, float)
        r = _mirror_index(A, B, list(a.corners), list(b.corners))
        if r is None:
            notes.append(f"{a.name} and {b.name} are not mirror images (after sewing): each edits alone")
            continue
        a.mirror_of, b.mirror_of = b.name, a.name
        a.mirror_index = b.mirror_index = r
        b.outline = [(float(x), float(y)) for x, y in mirror_outline(a, b)]


# ------------------------------------------------------------------ the body

_FS_GIRTHS = (("bust_girth", ("chest", "highBust")), ("waist_girth", ("waist",)), ("hip_girth", ("seat", "hips")))


def fs_measurements(meas: dict, source: str = "measurements") -> dict[str, float]:
    """ISO 8559-1 measurements [m] of a FreeSewing measurement set ({name: mm}):
    bust girth from chest (or highBust), waist girth from waist, hip girth from
    seat (or hips), height, inseam, waist height from waistToFloor; those the
    set has (PatternError when fewer
    than two of the girths and height)."""
    if not isinstance(meas, dict):
        raise PatternError(source, "a measurement set is a JSON object of {name: millimetres}")
    want: dict[str, float] = {}
    for key, fs_names in _FS_GIRTHS + (
        ("height", ("height",)),
        ("inseam", ("inseam",)),
        ("waist_height", ("waistToFloor",)),
    ):
        for n in fs_names:
            v = meas.get(n)
            if isinstance(v, (int, float)) and math.isfinite(v) and v > 0:
                want[key] = float(v) / 1000.0
                break
    if len([k for k in want if k not in ("inseam", "waist_height")]) < 2:
        raise PatternError(
            source, "needs at least two of chest, waist, seat (or hips), height [mm] (FreeSewing's names)"
        )
    return want


def _nearest(want: dict[str, float]) -> tuple[str, float]:
    from couture.bodies import measured, shipped_names

    keys = [k for k in want if k not in ("inseam", "waist_height")]
    best, best_d = "default", math.inf
    for name in shipped_names():
        m = measured(name)
        d = math.sqrt(sum((m[k] - want[k]) ** 2 for k in keys) / len(keys))
        if d < best_d:
            best, best_d = name, d
    return best, best_d


def body_for_measurements(meas: dict, source: str = "measurements") -> tuple[str, str]:
    """The shipped body (``couture bodies list``) nearest a FreeSewing
    measurement set ({name: mm}: chest, waist, seat or hips, height), by the
    root mean square difference of bust, waist and hip girths and stature;
    (its name, a line saying how near). The set's own body:
    :func:`body_of_measurements`."""
    want = fs_measurements(meas, source)
    keys = sorted(k for k in want if k not in ("inseam", "waist_height"))
    best, best_d = _nearest(want)
    return best, f"nearest shipped body {best!r} (rms difference {best_d * 100:.1f} cm over {', '.join(keys)})"


EXACT_BODY_RMS = 0.01
"""[m] a measurement set further than this (rms over its girths and stature)
from every shipped body gets a body of its own (:func:`body_of_measurements`)"""


def body_of_measurements(meas: dict, source: str = "measurements", name: str = "") -> tuple[Body, str]:
    """The body a FreeSewing measurement set's pattern was drafted for: the
    nearest shipped body when it is within ``EXACT_BODY_RMS``, else a body of
    the set's own measurements named ``name`` (the shipped one warped to them,
    couture.bodies.warp, built now and cached); (the design's Body, a line
    saying which and how near, with the measured errors)."""
    from couture import bodies

    want = fs_measurements(meas, source)
    keys = sorted(k for k in want if k not in ("inseam", "waist_height"))
    best, best_d = _nearest(want)
    if best_d <= EXACT_BODY_RMS:
        return Body(name=best), (
            f"nearest shipped body {best!r} (rms difference {best_d * 100:.1f} cm over {', '.join(keys)})"
        )
    name = re.sub(r"[^A-Za-z0-9_-]", "_", name or "measured")[:64]
    if name in bodies.shipped_names():
        name += "_set"
    body = Body(name=name, measurements={k: round(v, 4) for k, v in want.items()})
    try:
        bodies.use(body)
        got = bodies.measured(name)
        got["waist_height"] = got["waist_y"] - got["floor_y"]
        rec = bodies.custom_record(name)
    except ValueError as e:
        raise PatternError(source, f"no body for these measurements: {e}") from None
    errs = ", ".join(f"{k} {1000 * (got[k] - v):+.1f} mm" for k, v in want.items())
    return body, (
        f"the set's own body {name!r} ({rec['method']}; measured minus requested: {errs}); "
        f"the nearest shipped body {best!r} is {best_d * 100:.1f} cm rms off over {', '.join(keys)}"
    )

"""A body of given measurements by warping a shipped one (numpy and scipy only).

:mod:`couture.bodies.make` fits the Anny body model, an optional extra; this
module needs nothing beyond the core install, so any node (and CI) can build
a body for a measurement set on the spot. It deforms the shipped body nearest
the request (all share the template topology, pose and axes) in three steps:

- vertically, a piecewise-linear map of height: the floor stays, the crotch
  goes to the requested inside leg length, the waist to the requested waist
  height, the top of the head to the requested stature (each not given keeps
  the template's length above the one below);
- radially, each horizontal section of the trunk and legs about its centre
  (x = 0, the middle of its depth) by a factor s(y), a monotone cubic through
  knots at the hip, waist and bust heights (held over the shoulders, fading
  to 1 over the neck and toward the knees); the legs scale about the pair's
  centre, so thighs grow and move apart;
- the arms (the parts below the underarm cut off from the trunk) follow their
  shoulders: their displacement is the harmonic extension of the trunk's at
  the joint, nearly a rigid translation away from it.

The knot factors are corrected by a secant step per girth (girth is nearly
proportional to its factor) until every requested girth, measured by the
independent :func:`couture.bodies.measure.measure`, is within ``tol``.
The result is checked: no face turned over, and no arm or leg section reaching
further into its neighbour's hull than on the template.

A warp of the template is not a body scan: the proportions between the
landmarks (shoulders, neck, thighs, arms, head) are the template's.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from couture.bodies.measure import MEASURES, Slicer, measure

GIRTHS = ("bust_girth", "waist_girth", "hip_girth")

WARP_MEASURES = (*MEASURES, "waist_height")
"""what a warped body may be asked for [m]: MEASURES and the waist height
(ISO 8559-1: floor to the waist; FreeSewing's waistToFloor), which places the
waist between the crotch and the head and is matched to the 1 cm the waist's
section search allows, not iterated"""

PLAUSIBLE: dict[str, tuple[float, float]] = {
    "height": (1.2, 2.2),
    "bust_girth": (0.6, 1.7),
    "waist_girth": (0.45, 1.7),
    "hip_girth": (0.65, 1.8),
    "inseam": (0.5, 1.05),
    "waist_height": (0.75, 1.45),
}
"""[m] the range of each measurement a warped body accepts (adult bodies; the
warp is tested within about 0.8..1.35 of the template's girths)"""

WAIST_HEIGHT_TOL = 0.02
"""[m] how near the requested waist height the measured one must be (the
narrowest section's height moves with the girths around it)"""

MAX_FACTOR = 1.6
"""largest ratio (either way) of a requested girth to the template's that the warp attempts"""

KNEE_BELOW_CROTCH = 0.30
"""[m] the radial factor fades from the hip's at the crotch to 1 this far below it"""
SHOULDER_ABOVE_UNDERARM = 0.06
"""[m] the bust's factor holds up to this far above the underarm (the shoulders) ..."""
NECK_ABOVE_UNDERARM = 0.17
"""[m] ... and fades to 1 at this height above it (the neck; the head is not scaled)"""


def check_measurements(meas: dict, where: str = "measurements") -> dict[str, float]:
    """``meas`` as plain floats [m], or ValueError naming the field: only
    MEASURES names, finite, in PLAUSIBLE, at least one girth, waist not beyond
    1.3 x the hip, inseam under 60 % of the stature."""
    if not isinstance(meas, dict) or not meas:
        raise ValueError(f"{where}: a body's measurements are a non-empty {{name: metres}} mapping, got {meas!r}")
    out: dict[str, float] = {}
    for k, v in meas.items():
        if k not in WARP_MEASURES:
            raise ValueError(f"{where}.{k}: not a body measurement; they are {list(WARP_MEASURES)} [m]")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"{where}.{k}: {v!r} is not a finite number [m]")
        lo, hi = PLAUSIBLE[k]
        if not lo <= v <= hi:
            raise ValueError(f"{where}.{k}: {v:g} m is outside {lo:g}..{hi:g} m (an adult body, in metres)")
        out[k] = float(v)
    if not any(k in out for k in GIRTHS):
        raise ValueError(f"{where}: needs at least one of {list(GIRTHS)} [m]")
    if "waist_girth" in out and "hip_girth" in out and out["waist_girth"] > 1.3 * out["hip_girth"]:
        raise ValueError(
            f"{where}.waist_girth: {out['waist_girth']:g} m is more than 1.3 x the hip girth {out['hip_girth']:g} m"
        )
    if "inseam" in out and "height" in out and out["inseam"] > 0.6 * out["height"]:
        raise ValueError(f"{where}.inseam: {out['inseam']:g} m is more than 60 % of the height {out['height']:g} m")
    wh = out.get("waist_height")
    if wh is not None and "inseam" in out and wh < out["inseam"] + 0.15:
        raise ValueError(f"{where}.waist_height: {wh:g} m is less than 15 cm above the inseam {out['inseam']:g} m")
    if wh is not None and "height" in out and wh > out["height"] - 0.4:
        raise ValueError(f"{where}.waist_height: {wh:g} m is less than 40 cm below the height {out['height']:g} m")
    return out


@dataclass
class WarpResult:
    vertices: np.ndarray
    """(n, 3) [m]"""
    faces: np.ndarray
    """(m, 3) vertex ids, the template's"""
    measured: dict[str, float]
    """couture.bodies.measure.measure of the result [m]"""
    template: str
    factors: dict[str, float]
    """the radial factor at each girth's knot"""
    iterations: int
    seconds: float
    history: list[dict[str, float]] = field(default_factory=list)
    """per iteration: the girth errors [m]"""


def nearest_template(target: dict[str, float], candidates: dict[str, dict[str, float]]) -> str:
    """The body of ``candidates`` ({name: its measurements}) whose girths are
    nearest ``target``'s (rms over the requested girths); ties keep the first."""
    best, best_d = "default", math.inf
    for name, m in candidates.items():
        d = sum((m[k] - target[k]) ** 2 for k in GIRTHS if k in target)
        if d < best_d - 1e-12:
            best, best_d = name, d
    return best


class _Warp:
    """The template's parts and fixed geometry; :meth:`apply` for given factors."""

    def __init__(self, V: np.ndarray, F: np.ndarray, m0: dict[str, float], target: dict[str, float]):
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        self.V, self.F, self.m0 = V, F, m0
        e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
        e = np.unique(np.sort(e, axis=1), axis=0)
        self.E = e
        n = len(V)
        # the arms: pieces of the mesh below the underarm cut off from the trunk (the part with the feet)
        below = V[:, 1] < m0["underarm_y"]
        keep = below[e[:, 0]] & below[e[:, 1]]
        g = coo_matrix((np.ones(int(keep.sum())), (e[keep, 0], e[keep, 1])), shape=(n, n))
        _, lab = connected_components(g, directed=False)
        trunk_label = lab[int(np.argmin(V[:, 1]))]
        self.arm = below & (lab != trunk_label)
        if self.arm.sum() < 0.02 * n or (V[self.arm, 0] > 0).all() or (V[self.arm, 0] < 0).all():
            raise ValueError("the template's arms are not apart from the trunk below the underarm (not an A-pose?)")
        # the section centres: middle of the trunk's depth, 1 cm bins, smoothed
        body = ~self.arm
        y = V[body, 1]
        bins = np.arange(y.min(), y.max() + 0.01, 0.01)
        idx = np.clip(np.digitize(y, bins) - 1, 0, len(bins) - 1)
        zc = np.full(len(bins), np.nan)
        for i in range(len(bins)):
            z = V[body, 2][idx == i]
            if len(z):
                zc[i] = 0.5 * (z.min() + z.max())
        ok = np.isfinite(zc)
        zc = np.interp(np.arange(len(bins)), np.flatnonzero(ok), zc[ok])
        zc = np.convolve(np.pad(zc, 3, mode="edge"), np.ones(7) / 7, mode="valid")
        self.centre_z = np.interp(V[:, 1], bins + 0.005, zc)
        # the vertical map: floor fixed, crotch -> inseam, waist -> waist height, top -> height
        floor, crotch, waist, top = m0["floor_y"], m0["crotch_y"], m0["waist_y"], m0["floor_y"] + m0["height"]
        inseam = target.get("inseam", m0["inseam"])
        waist_height = target.get("waist_height", waist - floor + inseam - m0["inseam"])
        height = target.get("height", waist_height + top - waist)
        self.y_knots = np.array([floor, crotch, waist, top])
        self.y_to = np.array([floor, floor + inseam, floor + waist_height, floor + height])
        if np.any(np.diff(self.y_to) < 0.1 * np.diff(self.y_knots)):
            raise ValueError(f"measurements: inseam, waist height and height {self.y_to - floor} m are out of order")
        # the arms' Laplacian (uniform weights) for the harmonic extension
        w = np.ones(len(e))
        L = coo_matrix((np.r_[w, w], (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n)).tocsr()
        deg = np.asarray(L.sum(axis=1)).ravel()
        from scipy.sparse import diags
        from scipy.sparse.linalg import factorized

        Lap = (diags(deg) - L).tocsr()
        a = np.flatnonzero(self.arm)
        b = np.flatnonzero(~self.arm)
        self.arm_ids, self.rest_ids = a, b
        self.solve_arm = factorized(Lap[a][:, a].tocsc())
        self.arm_coupling = Lap[a][:, b].tocsr()

    def factor(self, y: np.ndarray, s: dict[str, float]) -> np.ndarray:
        """The radial factor at template heights ``y``: monotone cubic through the knots."""
        from scipy.interpolate import PchipInterpolator

        m = self.m0
        ky = [
            m["crotch_y"] - KNEE_BELOW_CROTCH,
            m["crotch_y"],
            m["hip_y"],
            m["waist_y"],
            m["bust_y"],
            m["underarm_y"] + SHOULDER_ABOVE_UNDERARM,
            m["underarm_y"] + NECK_ABOVE_UNDERARM,
        ]
        kv = [1.0, s["hip_girth"], s["hip_girth"], s["waist_girth"], s["bust_girth"], s["bust_girth"], 1.0]
        f = PchipInterpolator(ky, kv, extrapolate=False)(np.clip(y, ky[0], ky[-1]))
        return np.asarray(f)

    def apply(self, s: dict[str, float]) -> np.ndarray:
        V = self.V
        D = np.zeros_like(V)
        D[:, 1] = np.interp(V[:, 1], self.y_knots, self.y_to) - V[:, 1]
        f = self.factor(V[:, 1], s) - 1.0
        D[:, 0] = f * V[:, 0]
        D[:, 2] = f * (V[:, 2] - self.centre_z)
        # the arms: harmonic extension of the trunk's displacement at the joint
        rhs = -(self.arm_coupling @ D[self.rest_ids])
        D[self.arm_ids] = np.column_stack([self.solve_arm(rhs[:, k]) for k in range(3)])
        return V + D


def _normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)


def _overlap(V: np.ndarray, F: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Per height: the largest fraction of a loop's points inside another
    loop's convex hull (an arm inside the trunk, a leg inside the other)."""
    from matplotlib.path import Path as MplPath
    from scipy.spatial import ConvexHull

    s = Slicer(V, F)
    out = np.zeros(len(ys))
    for i, y in enumerate(ys):
        loops = [P[:, [0, 2]] for _, P in s.loops(float(y)) if len(P) >= 6]
        hulls: list[MplPath | None] = []
        for Q in loops:
            try:
                hulls.append(MplPath(Q[ConvexHull(Q).vertices]))
            except Exception:  # a degenerate loop
                hulls.append(None)
        worst = 0.0
        for a, Qa in enumerate(loops):
            for b, hb in enumerate(hulls):
                if a != b and hb is not None:
                    worst = max(worst, float(hb.contains_points(Qa).mean()))
        out[i] = worst
    return out


def check_warp(template: tuple[np.ndarray, np.ndarray], warped: np.ndarray, m0: dict, m1: dict) -> None:
    """ValueError when the warp turned a face over or pushed an arm (or a leg)
    into its neighbour further than the template has it."""
    V0, F = template
    dots = np.einsum("ij,ij->i", _normals(V0, F), _normals(warped, F))
    if dots.min() <= 0.0:
        raise ValueError(f"the warp turns {int((dots <= 0).sum())} faces over (measurements too far from the template)")
    u0 = np.linspace(0.05, 0.95, 10)
    ys0 = np.r_[m0["crotch_y"] + 0.03 + u0 * (m0["underarm_y"] - 0.02 - m0["crotch_y"] - 0.03), m0["crotch_y"] - 0.05]
    ys1 = np.r_[m1["crotch_y"] + 0.03 + u0 * (m1["underarm_y"] - 0.02 - m1["crotch_y"] - 0.03), m1["crotch_y"] - 0.05]
    before, after = _overlap(V0, F, ys0), _overlap(warped, F, ys1)
    bad = np.flatnonzero(after > before + 0.05)
    if len(bad):
        i = int(bad[0])
        raise ValueError(
            f"the warp pushes a limb into the trunk or the other leg at y = {ys1[i]:.3f} m "
            f"({after[i]:.0%} of a section inside another's hull, template {before[i]:.0%})"
        )


def warp_body(
    target: dict[str, float],
    template: str,
    mesh: tuple[np.ndarray, np.ndarray],
    template_measured: dict[str, float],
    tol: float = 0.002,
    max_iter: int = 15,
) -> WarpResult:
    """The body whose measured MEASURES are within ``tol`` [m] of ``target``'s
    (a subset of MEASURES [m]; see :func:`check_measurements`), warped from
    the shipped body ``template`` (its ``mesh`` (V, F) and measurements;
    :func:`couture.bodies.warp_to` picks the nearest and loads them).
    Deterministic. ValueError naming what cannot be reached."""
    t0 = time.perf_counter()
    target = check_measurements(target)
    V0, F = mesh
    m0 = dict(template_measured)
    for k in GIRTHS:
        if k in target and not 1 / MAX_FACTOR <= target[k] / m0[k] <= MAX_FACTOR:
            raise ValueError(
                f"measurements.{k}: {target[k]:.3f} m is more than {MAX_FACTOR:g} x away from the template "
                f"{template!r}'s {m0[k]:.3f} m"
            )
    w = _Warp(V0, F, m0, target)
    # the girths not requested keep the template's factor 1 (and so stay near its own)
    s = {k: (target[k] / m0[k] if k in target else 1.0) for k in GIRTHS}
    history: list[dict[str, float]] = []
    V, m = V0, m0
    exact = [k for k in target if k in MEASURES]
    for _ in range(max_iter):
        V = w.apply(s)
        m = measure(V, F)
        err = {k: m[k] - target[k] for k in exact}
        if "waist_height" in target:
            err["waist_height"] = m["waist_y"] - m["floor_y"] - target["waist_height"]
        history.append({k: round(v, 6) for k, v in err.items()})
        if (
            max(abs(v) for k, v in err.items() if k != "waist_height") < tol / 4
            and abs(err.get("waist_height", 0.0)) < WAIST_HEIGHT_TOL / 4
        ):
            break
        for k in GIRTHS:
            if k in target:
                s[k] *= target[k] / m[k]  # girth ~ proportional to its factor
        if "waist_height" in target:  # the narrowest section follows the waist knot, roughly
            w.y_to[2] -= float(np.clip(err["waist_height"], -0.03, 0.03))
    m["waist_height"] = m["waist_y"] - m["floor_y"]
    err = {k: m[k] - target[k] for k in exact}
    bad = [k for k, v in err.items() if abs(v) > tol]
    if "waist_height" in target and abs(m["waist_height"] - target["waist_height"]) > WAIST_HEIGHT_TOL:
        bad.append("waist_height")
    if bad:
        raise ValueError(
            "the warp cannot reach "
            + ", ".join(f"{k}={target[k]:.3f} m (got {m[k]:.3f})" for k in bad)
            + f" within {tol * 1000:g} mm from {template!r}"
        )
    check_warp((V0, F), V, m0, m)
    return WarpResult(V, F, m, template, dict(s), len(history), time.perf_counter() - t0, history)

"""Body cross-sections about the placement axes (torso, arms, legs), as polar tables.

Placement wraps each ring of panels on a surface whose cross-section at every
height is the body's own section, grown by a clearance margin and then by
whatever the garment's girth at that height needs (so the seams close), see
:mod:`couture.pattern.placement`. A circle (the old cone) cannot do this: the
waist is an ellipse of 0.67 m girth, and a circle around it clearing it by
2.5 cm has 0.85 m circumference, so a 0.68 m waistband would leave 17 cm of
seam gaps.

A section table is, for an axis frame (origin o, unit axis a, theta = 0
direction f, theta = pi/2 direction b = a x f), the polar radius
``radius[i, k]`` of the convex hull of the body part's vertices in the slab
``|t - t_i| < dt`` (t = (p - o).a, t_i = t0 + i dt), together with the axis
point itself (so the curve is star-shaped about the axis), at angle
theta_k = 2 pi k / K. Rows where the slab holds no vertex of the part are 0.

Measured once from the mannequin mesh by :func:`measure_sections` and stored
beside it (``sections.npz``, a test re-measures), so drafting never loads the
mesh.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from couture.pattern import mannequin as M

SECTIONS_PATH = Path(__file__).resolve().parents[1] / "assets" / "mannequin" / "sections.npz"
N_THETA = 64
DT = 0.02
"""[m] axial row spacing of the tables"""


@dataclass(frozen=True)
class Section:
    origin: np.ndarray
    """[m] axis point with t = 0, shape (3,)"""
    axis: np.ndarray
    """unit axis a, shape (3,)"""
    ref: np.ndarray
    """unit theta = 0 direction f (normal to a), shape (3,)"""
    t0: float
    """[m] axial coordinate of row 0"""
    dt: float
    """[m] row spacing"""
    radius: np.ndarray
    """[m] polar radius of the section, shape (rows, N_THETA); 0 where the slab is empty"""

    def radii(self, t: np.ndarray | float) -> np.ndarray:
        """Polar radii (len(t), N_THETA) [m] at axial coordinates t, linear between rows
        (the larger of the two neighbours where one is empty, so nothing is cut)."""
        t = np.atleast_1d(np.asarray(t, float))
        u = np.clip((t - self.t0) / self.dt, 0, len(self.radius) - 1)
        i = np.minimum(np.floor(u).astype(int), len(self.radius) - 2)
        w = (u - i)[:, None]
        r0, r1 = self.radius[i], self.radius[i + 1]
        lin = (1 - w) * r0 + w * r1
        return np.where((r0 == 0) | (r1 == 0), np.maximum(r0, r1), lin)


def _arm_split(y: np.ndarray) -> np.ndarray:
    """|x| beyond which a vertex belongs to an arm (measured gaps between torso
    and arm in horizontal slabs; the arms join the torso above y = 0.44)."""
    # the torso takes the arm root (y > 0.40): the bodice must go around it
    return np.interp(y, [0.18, 0.20, 0.30, 0.38, 0.40, 0.9], [0.30, 0.26, 0.21, 0.19, 0.26, 0.26])


ARM_OFFSET_BELOW_SHOULDER = 0.12
"""[m] a body's arm frame moves by the mean offset from the default of its arm's
vertices within this height below the default's shoulder point"""


def frames() -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(origin, axis, ref) of each table: torso (vertical, front ref), left/right
    arm (the sleeve placement axis), left/right leg (the leg axis)."""
    out = {"torso": (np.array([0.0, 0.0, M.TORSO_AXIS_Z]), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]))}
    for name, sign in (("left", 1.0), ("right", -1.0)):
        mir = np.array([sign, 1.0, 1.0])
        a = M.LEFT_ARM_AXIS * mir
        a = a / np.linalg.norm(a)
        v = np.array([sign, 1.0, 0.0]) / np.sqrt(2)
        f = v - (v @ a) * a
        out[f"{name}_arm"] = (M.LEFT_ARM_SHOULDER * mir, a, f / np.linalg.norm(f))
        a = M.LEFT_LEG_AXIS * mir
        a = a / np.linalg.norm(a)
        f = np.array([0.0, 0.0, 1.0]) - a[2] * a
        out[f"{name}_leg"] = (M.LEFT_LEG_TOP * mir, a, f / np.linalg.norm(f))
    return out


def _polar_hull(Q: np.ndarray, K: int) -> np.ndarray:
    """Polar radius at K angles of the convex hull of 2D points Q plus the origin."""
    from scipy.spatial import ConvexHull

    Q = np.vstack([Q, [[0.0, 0.0]]])
    if len(Q) < 4:
        return np.zeros(K)
    try:
        h = ConvexHull(Q)
    except Exception:  # degenerate (collinear) slab
        return np.zeros(K)
    P = Q[h.vertices]
    E = np.roll(P, -1, axis=0) - P
    th = 2 * np.pi * np.arange(K) / K
    d = np.column_stack([np.cos(th), np.sin(th)])
    # ray s d hits edge P + u E: solve s d - u E = P
    r = np.zeros(K)
    for k in range(K):
        det = -d[k, 0] * E[:, 1] + d[k, 1] * E[:, 0]
        ok = np.abs(det) > 1e-15
        s = np.where(ok, (-P[:, 0] * E[:, 1] + P[:, 1] * E[:, 0]) / np.where(ok, det, 1), -1)
        u = np.where(ok, (d[k, 0] * P[:, 1] - d[k, 1] * P[:, 0]) / np.where(ok, det, 1), -1)
        hit = ok & (u >= -1e-9) & (u <= 1 + 1e-9) & (s >= 0)
        r[k] = s[hit].max() if hit.any() else 0.0
    return r


def measure_sections(path: str | None = None) -> dict[str, Section]:
    """Measure every section table from the mannequin mesh (a few seconds)."""
    import trimesh

    if path is None:
        path = str(Path(__file__).resolve().parents[2] / M.MANNEQUIN_PATH)
    default = str(Path(__file__).resolve().parents[2] / M.MANNEQUIN_PATH)
    V = np.asarray(trimesh.load_mesh(path, process=False).vertices)
    V0 = V if path == default else np.asarray(trimesh.load_mesh(default, process=False).vertices)
    # a body of the default's template topology (every body of couture.bodies) is cut
    # into parts where the default is, vertex for vertex: a warped body's trunk may
    # reach past the default's arm split, and its arms sit higher
    R = V0 if V0.shape == V.shape else V
    split = _arm_split(R[:, 1])
    parts = {
        "torso": np.abs(R[:, 0]) < split,
        "left_arm": (R[:, 0] >= split) & (R[:, 1] < 0.46),
        "right_arm": (R[:, 0] <= -split) & (R[:, 1] < 0.46),
        # a leg with its half of the pelvis (the trouser panels of one leg)
        "left_leg": (R[:, 0] >= 0.0) & (np.abs(R[:, 0]) < split),
        "right_leg": (R[:, 0] <= 0.0) & (np.abs(R[:, 0]) < split),
    }
    fr = frames()
    if R is V0 and path != default:
        for arm in ("left_arm", "right_arm"):
            # the arm's frame follows the body's upper arm (where a sleeve's cap sits);
            # couture.pattern.placement moves the arm rings by the same offset
            o, a, f = fr[arm]
            near = parts[arm] & (V0[:, 1] > o[1] - ARM_OFFSET_BELOW_SHOULDER)
            fr[arm] = (o + (V[near] - V0[near]).mean(axis=0), a, f)
    out = {}
    for name, (o, a, f) in fr.items():
        b = np.cross(a, f)
        P = V[parts[name]] - o
        t = P @ a
        uv = np.column_stack([P @ f, P @ b])
        t0 = np.floor(t.min() / DT) * DT
        rows = int(np.ceil((t.max() - t0) / DT)) + 1
        R = np.zeros((rows, N_THETA))
        for i in range(rows):
            sel = np.abs(t - (t0 + i * DT)) <= DT
            if sel.sum() >= 3:
                R[i] = _polar_hull(uv[sel], N_THETA)
        out[name] = Section(o, a, f, float(t0), DT, R)
    return out


def save_sections(sections: dict[str, Section], path: Path = SECTIONS_PATH) -> None:
    arrays: dict[str, Any] = {}
    for name, s in sections.items():
        arrays[f"{name}.origin"] = s.origin
        arrays[f"{name}.axis"] = s.axis
        arrays[f"{name}.ref"] = s.ref
        arrays[f"{name}.t"] = np.array([s.t0, s.dt])
        arrays[f"{name}.radius"] = s.radius.astype(np.float32)
    np.savez_compressed(path, **arrays)


def write_body_sections(obj: Path, path: Path) -> None:
    """Measure the tables of the body mesh ``obj`` and store them at ``path`` (``couture bodies make``)."""
    save_sections(measure_sections(str(obj)), path)


@lru_cache(maxsize=16)
def sections(body: str = "default") -> dict[str, Section]:
    """The stored tables of a body ('default': regenerate with
    ``python -m couture.pattern.sections``; a graded body's are written by
    ``couture bodies make``; a body of measurements's are measured here on
    first use and cached beside it)."""
    import os

    from couture import bodies

    path = bodies.sections_path(body)
    if not path.exists():
        tmp = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npz")
        write_body_sections(bodies.obj_path(body), tmp)
        tmp.replace(path)
    with np.load(path) as z:
        names = sorted({k.split(".")[0] for k in z.files})
        return {
            n: Section(
                z[f"{n}.origin"],
                z[f"{n}.axis"],
                z[f"{n}.ref"],
                float(z[f"{n}.t"][0]),
                float(z[f"{n}.t"][1]),
                z[f"{n}.radius"].astype(np.float64),
            )
            for n in names
        }


if __name__ == "__main__":
    save_sections(measure_sections())
    print(f"wrote {SECTIONS_PATH}")

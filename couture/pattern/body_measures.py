"""A body's drafting measurements: the option defaults of a sloper drafted from
the body a design names (``SloperDef.body_fitted``).

For ``'default'`` these are the option defaults themselves (the mannequin's
constants, :mod:`couture.pattern.mannequin`). For a graded body
(:mod:`couture.bodies`) they come from the same measurements the grading
bench and ``couture bodies list`` read, ``bodies.table()``'s ``measured``
(ISO 8559-1 girths and landmark heights), plus two girths that table does not
hold, measured here from the body's mesh the way the mannequin's constants
were (:mod:`couture.pattern.mannequin`): the total crotch length
(:func:`crotch_length`), the neck girth (the smallest girth of
the largest loop straddling x = 0 at heights 0.57-0.63 m; the default's reads
0.314 m here, 0.326 m at y = 0.60 in the mannequin's constants) and the upper arm girth (the arm's horizontal section
just below the underarm, the default's at y = 0.44).

Not measured (every shipped body shares the default's pose and shoulders):
shoulder width and the shoulder height above the floor keep the default's
values (``waist_to_shoulder`` is the default's shoulder height above the body's
own waist).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from couture.pattern import mannequin as M

NECK_Y = (0.57, 0.63)
"""[m] heights searched for the neck girth (every body shares the pose)"""
ARM_BELOW_UNDERARM = 0.008
"""[m] the upper arm section's depth below the underarm (default: 0.448 -> 0.44)"""


def _hull_perimeter(Q: np.ndarray) -> float:
    from scipy.spatial import ConvexHull

    v = Q[ConvexHull(Q).vertices]
    return float(np.linalg.norm(v - np.roll(v, 1, axis=0), axis=1).sum())


def crotch_length(name: str) -> float:
    """Total crotch length [m] of body ``name`` (ISO 8559-1: from the centre
    front waist between the legs to the centre back waist): the length of the
    body's sagittal section (plane x = 0) below the waist height, front waist
    round belly, crotch and seat to back waist. The section's points below the
    waist are ordered by their angle about a point inside the pelvis (10 cm
    above the crotch, mid depth: the outline is star-shaped about it there)."""
    from couture import bodies
    from couture.bodies.measure import Slicer

    m = bodies.measured(name)
    s = Slicer(*bodies.load_mesh(name))
    loops = [P for _, P in s.loops(0.0, axis=0) if P[:, 1].min() < m["crotch_y"] + 0.01 < m["waist_y"] < P[:, 1].max()]
    if not loops:
        raise ValueError(f"body {name!r}: no sagittal section through the crotch and the waist")
    Q = max(loops, key=len)[:, [2, 1]]  # (z, y)
    Q = Q[Q[:, 1] <= m["waist_y"]]
    c = np.array([0.5 * (Q[:, 0].min() + Q[:, 0].max()), m["crotch_y"] + 0.10])
    Q = Q[np.argsort(np.arctan2(Q[:, 1] - c[1], Q[:, 0] - c[0]))]
    d = np.linalg.norm(np.diff(np.vstack([Q, Q[:1]]), axis=0), axis=1)
    return float(d.sum() - d.max())  # the longest step closes the loop across the waist


def mesh_girths(name: str, underarm_y: float) -> dict[str, float]:
    """Neck and (left) upper arm girths [m] of a body's mesh (module docstring)."""
    from couture import bodies
    from couture.bodies.measure import Slicer

    s = Slicer(*bodies.load_mesh(name))
    neck = np.inf
    for y in np.arange(NECK_Y[0], NECK_Y[1] + 1e-9, 0.005):
        # the neck is the largest loop straddling x = 0 (small ones: chin, hair)
        centred = [P[:, [0, 2]] for _, P in s.loops(float(y))]
        per = [_hull_perimeter(Q) for Q in centred if len(Q) >= 4 and Q[:, 0].min() < 0 < Q[:, 0].max()]
        if per:
            neck = min(neck, max(per))
    arm = 0.0
    for _, P in s.loops(underarm_y - ARM_BELOW_UNDERARM):
        Q = P[:, [0, 2]]
        if len(Q) >= 4 and Q[:, 0].mean() > 0.1:
            arm = max(arm, _hull_perimeter(Q))
    if not np.isfinite(neck) or arm == 0.0:
        raise ValueError(f"body {name!r}: no neck or upper arm section found")
    return {"neck_girth": neck, "upper_arm_girth": arm}


@lru_cache(maxsize=16)
def body_options(name: str) -> dict[str, float]:
    """Body-measurement option values [m] of body ``name`` (module docstring);
    {} for the default mannequin (its options' defaults are its measurements)."""
    from couture import bodies

    bodies.check_name(name)
    if name == "default":
        return {}
    m = bodies.measured(name)
    out = {
        "bust_girth": m["bust_girth"],
        "waist_girth": m["waist_girth"],
        "hip_girth": m["hip_girth"],
        "waist_height": m["waist_y"] - m["floor_y"],
        "waist_to_hip": m["waist_y"] - m["hip_y"],
        "crotch_depth": m["waist_y"] - m["crotch_y"],
        "crotch_length": crotch_length(name),
        "waist_to_underarm": m["underarm_y"] - m["waist_y"] - 0.03,
        "waist_to_shoulder": M.SHOULDER_Y - m["waist_y"],
    }
    out.update(mesh_girths(name, m["underarm_y"]))
    return {k: float(v) for k, v in out.items()}

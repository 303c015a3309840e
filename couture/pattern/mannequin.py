"""Measurements of the default mannequin (``couture/assets/mannequin/body_a_pose.obj``).

Measured once from the mesh with :func:`measure_mannequin` (a test re-measures
and compares) and stored as constants so drafting never loads the mesh.

How they were measured: horizontal sections (planes y = const) every 1-2 cm,
split into connected loops; a girth is the perimeter of the convex hull of a
loop (what a tape measure reads, it bridges concavities). Waist: the smallest
torso girth between the hip and the underarm; hip: the largest girth of the
loop that contains both legs (just above the crotch); bust: the largest torso
girth below the underarm (the arms join the torso section above it);
heights in world y (feet at -0.817). The body faces +z, y is up, metres.
"""

from __future__ import annotations

import numpy as np

MANNEQUIN_PATH = "couture/assets/mannequin/body_a_pose.obj"

WAIST_GIRTH = 0.670
"""[m] smallest torso girth, at y = WAIST_Y"""
WAIST_Y = 0.27
HIP_GIRTH = 0.978
"""[m] largest girth over both legs, at y = HIP_Y (just above the crotch)"""
HIP_Y = -0.04
BUST_GIRTH = 0.846
"""[m] largest torso girth below the underarm, at y = BUST_Y"""
BUST_Y = 0.44
UNDERARM_Y = 0.45
"""[m] highest section where the arms are separate from the torso"""
SHOULDER_Y = 0.56
"""[m] where the arms leave the neck/shoulder section"""
SHOULDER_HALF_WIDTH = 0.20
"""[m] |x| of the shoulder point (arm root at SHOULDER_Y)"""
NECK_GIRTH = 0.326
"""[m] at y = 0.60"""
CROTCH_Y = -0.05
"""[m] lowest section with one loop over both legs"""
CROTCH_LENGTH = 0.725
"""[m] total crotch length: the sagittal section (x = 0) from the front waist
between the legs to the back waist (``couture.pattern.body_measures.crotch_length``)"""
KNEE_Y = -0.42
ANKLE_Y = -0.69
FLOOR_Y = -0.817
THIGH_GIRTH = 0.571
"""[m] one leg, just below the crotch (y = -0.05)"""
KNEE_GIRTH = 0.344
ANKLE_GIRTH = 0.205
UPPER_ARM_GIRTH = 0.297
"""[m] horizontal section of the arm at y = 0.44 (oblique to the arm, so an upper bound)"""
TORSO_AXIS_Z = 0.04
"""[m] z of the vertical axis the torso/skirt placement cylinders use"""

RADIUS_PROFILE_Y0 = -0.80
RADIUS_PROFILE_DY = 0.02
RADIUS_PROFILE = np.array(
    [
        0.285,
        0.263,
        0.26,
        0.263,
        0.258,
        0.253,
        0.25,
        0.25,
        0.249,
        0.248,
        0.248,
        0.248,
        0.248,
        0.249,
        0.25,
        0.25,
        0.248,
        0.245,
        0.237,
        0.228,
        0.218,
        0.211,
        0.204,
        0.201,
        0.198,
        0.196,
        0.195,
        0.196,
        0.197,
        0.197,
        0.199,
        0.2,
        0.2,
        0.2,
        0.199,
        0.198,
        0.196,
        0.193,
        0.189,
        0.184,
        0.179,
        0.176,
        0.174,
        0.172,
        0.171,
        0.169,
        0.167,
        0.164,
        0.158,
        0.15,
        0.141,
        0.136,
        0.135,
        0.134,
        0.132,
        0.131,
        0.131,
        0.132,
        0.137,
        0.147,
        0.145,
        0.151,
        0.161,
        # above the underarm the section holds the arms too; torso-only values
        # from the shoulder strap region (|x| < 0.15), see measure_mannequin
        0.17,
        0.17,
        0.17,
        0.17,
        0.17,
        0.17,
        0.096,
        0.072,
    ]
)
"""[m] largest distance of torso/leg (not arm) section points from the vertical
axis x = 0, z = TORSO_AXIS_Z, for y = Y0 + i * DY"""

LEFT_ARM_SHOULDER = np.array([0.192, 0.48, 0.008])
"""[m] a point on the left (x > 0) upper-arm axis at the arm root"""
LEFT_UPPER_ARM_AXIS = np.array([-0.663, 0.737, -0.120])
"""unit vector up the left upper arm, through the centres of the arm's
horizontal sections at y = 0.44 and 0.36; the forearm turns forward below the
elbow (y ~ 0.34) toward the wrist at about (0.428, 0.22, 0.215)"""
LEFT_ARM_AXIS = np.array([-0.615, 0.680, -0.399])
"""sleeve placement axis (unit, pointing toward the shoulder): 0.3 upper-arm
axis + 0.7 shoulder-to-wrist chord, so one straight cylinder contains the bent
arm; the right arm mirrors x"""
ARM_RADIUS = 0.09
"""[m] radius about LEFT_ARM_AXIS that contains the arm down to the wrist
(checked: sleeves of every length start >= 1.5 cm outside the body)"""
"""[m] arm radius around LEFT_ARM_AXIS near the shoulder (upper arm, generous)"""
LEFT_LEG_TOP = np.array([0.10, -0.05, 0.02])
LEFT_LEG_AXIS = np.array([-0.177, 0.981, 0.076])
"""unit vector up the left leg (PCA of vertices x > 0.05, -0.7 < y < -0.1)"""
LEG_RADIUS = 0.095
"""[m] largest distance of leg vertices from the leg axis"""


def body_radius(y: np.ndarray | float) -> np.ndarray:
    """Body (torso/legs) radius about the torso axis at heights y [m]."""
    return np.interp(y, RADIUS_PROFILE_Y0 + RADIUS_PROFILE_DY * np.arange(len(RADIUS_PROFILE)), RADIUS_PROFILE)


def body_radius_max(y0: float, y1: float) -> float:
    """Largest body radius for heights between y0 and y1."""
    lo, hi = min(y0, y1), max(y0, y1)
    ys = np.concatenate([np.linspace(lo, hi, 64), [lo, hi]])
    return float(body_radius(ys).max())


def measure_mannequin(path: str | None = None) -> dict[str, float]:
    """Re-measure the girths from the mesh (slow-ish, ~1 s; tests use it)."""
    from pathlib import Path

    import trimesh
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import ConvexHull

    if path is None:
        path = str(Path(__file__).resolve().parents[2] / MANNEQUIN_PATH)
    mesh = trimesh.load(path, process=False)

    def loops(y):
        segs = trimesh.intersections.mesh_plane(mesh, [0, 1, 0], [0, y, 0])
        P = segs.reshape(-1, 3)[:, [0, 2]]
        u, inv = np.unique(np.round(P, 7), axis=0, return_inverse=True)
        e = inv.ravel().reshape(-1, 2)
        g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(len(u), len(u)))
        _, lab = connected_components(g, directed=False)
        out = []
        for c in range(lab.max() + 1):
            Q = u[lab == c]
            if len(Q) >= 4:
                h = ConvexHull(Q)
                v = Q[h.vertices]
                out.append((Q, float(np.linalg.norm(v - np.roll(v, 1, 0), axis=1).sum())))
        return out

    def torso(y):
        return max((per for Q, per in loops(y) if Q[:, 0].min() < 0 < Q[:, 0].max()), default=0.0)

    waist = min(torso(y) for y in np.arange(0.20, 0.40, 0.01))
    hip = max(torso(y) for y in np.arange(-0.04, 0.10, 0.01))
    bust = max(torso(y) for y in np.arange(0.36, 0.445, 0.01))
    return {
        "waist_girth": waist,
        "hip_girth": hip,
        "bust_girth": bust,
        "height": float(mesh.bounds[1, 1] - mesh.bounds[0, 1]),
    }

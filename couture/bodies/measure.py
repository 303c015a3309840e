"""Body measurements read back from a closed body mesh (y up, metres, facing +z).

ISO 8559-1 names, measured the way a tape measure reads them on a standing
body, from horizontal sections (planes y = const) of the mesh:

- ``height`` (stature): top of the head to the floor, the bounding box in y.
- ``crotch_height``: the lowest point of the body's sagittal section (plane
  x = 0); the legs are apart below it. ``inseam`` (inside leg length) is the
  crotch height above the floor.
- ``underarm_height``: the top of the lowest run of sections above the crotch
  that hold the torso and both arms apart (three or more loops).
- ``waist_girth``: the smallest torso girth between 45 % of the way from the
  crotch to the underarm and 8 cm below the underarm (the natural waist).
- ``hip_girth``: the largest girth of the section over both legs, from 1 cm
  above the crotch up to 30 % of the way to the underarm (the buttocks).
- ``bust_girth`` (chest girth): the largest torso girth in the 9 cm below the
  underarm (over the bust points; the arms join the section above).

A girth is the perimeter of the convex hull of the torso loop (the loop of the
section that straddles x = 0): a tape bridges the concavities. The sections
here are cut exactly (edge crossings, not vertex slabs), so the same girths
are differentiable in the vertex positions (:func:`girth_at_torch`, used by
the body fitting in :mod:`couture.bodies.make`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STEP = 0.005
"""[m] spacing of the sections searched for the extreme girths"""


@dataclass
class Section:
    """The torso loop of one horizontal section."""

    y: float
    edges: np.ndarray
    """(k, 2) vertex pairs of the mesh edges the hull vertices lie on, in hull order"""
    points: np.ndarray
    """(k, 2) hull vertices (x, z) [m]"""
    girth: float
    """[m] convex hull perimeter"""


class Slicer:
    """Horizontal (and sagittal) sections of one triangle mesh."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        self.V = np.asarray(vertices, np.float64)
        self.F = np.asarray(faces, np.int64)
        e = np.concatenate([self.F[:, [0, 1]], self.F[:, [1, 2]], self.F[:, [2, 0]]])
        e.sort(axis=1)
        self.E, inv = np.unique(e, axis=0, return_inverse=True)
        self.face_edges = inv.reshape(3, -1).T  # (m, 3) edge ids of each face

    def loops(self, y: float, axis: int = 1) -> list[tuple[np.ndarray, np.ndarray]]:
        """Connected loops of the section ``p[axis] = y``: per loop, the crossing
        edges (k, 2) and their crossing points (k, 3)."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        h = self.V[:, axis] - y
        h = np.where(h == 0.0, 1e-12, h)  # a vertex exactly on the plane counts as above
        cross = (h[self.E[:, 0]] > 0) != (h[self.E[:, 1]] > 0)
        idx = np.flatnonzero(cross)
        if len(idx) == 0:
            return []
        local = -np.ones(len(self.E), np.int64)
        local[idx] = np.arange(len(idx))
        fe = self.face_edges[cross[self.face_edges].sum(axis=1) == 2]
        pairs = np.array([row[cross[row]] for row in fe]) if len(fe) else np.zeros((0, 2), np.int64)
        g = coo_matrix((np.ones(len(pairs)), (local[pairs[:, 0]], local[pairs[:, 1]])), shape=(len(idx),) * 2)
        _, lab = connected_components(g, directed=False)
        a, b = self.V[self.E[idx, 0]], self.V[self.E[idx, 1]]
        t = (y - a[:, axis]) / (b[:, axis] - a[:, axis])
        P = a + t[:, None] * (b - a)
        return [(self.E[idx[lab == c]], P[lab == c]) for c in range(lab.max() + 1)]

    def torso(self, y: float) -> Section | None:
        """The largest loop straddling x = 0 at height y, as its convex hull."""
        from scipy.spatial import ConvexHull

        best = None
        for edges, P in self.loops(y):
            if len(P) < 4 or not (P[:, 0].min() < 0 < P[:, 0].max()):
                continue
            Q = P[:, [0, 2]]
            hull = ConvexHull(Q)
            v = hull.vertices  # counter-clockwise order
            per = float(np.linalg.norm(Q[v] - np.roll(Q[v], 1, axis=0), axis=1).sum())
            if best is None or per > best.girth:
                best = Section(float(y), edges[v], Q[v], per)
        return best

    def crotch(self) -> tuple[float, np.ndarray]:
        """(height of the lowest point of the sagittal section x = 0, its edge)."""
        lo = None
        for edges, P in self.loops(0.0, axis=0):
            i = int(np.argmin(P[:, 1]))
            if lo is None or P[i, 1] < lo[0]:
                lo = (float(P[i, 1]), edges[i])
        if lo is None:
            raise ValueError("the mesh has no sagittal section at x = 0")
        return lo

    def underarm(self, crotch_y: float, top_y: float) -> float:
        """Top of the lowest run of sections above the crotch that hold three or
        more loops (the torso and the two arms apart), to 1 mm."""
        y, seen = crotch_y + 0.05, False
        stop = crotch_y + 0.7 * (top_y - crotch_y)  # long trunks (warped bodies) reach 0.6
        while y < stop:
            n = len(self.loops(y))
            if n >= 3:
                seen = True
            elif seen:
                lo = y - STEP
                for yy in np.arange(lo + 0.001, y, 0.001):
                    if len(self.loops(float(yy))) < 3:
                        break
                    lo = float(yy)
                return float(lo)
            y += STEP
        raise ValueError("no section holds the torso and both arms apart (is the body in A-pose?)")


@dataclass
class Landmarks:
    floor: float
    top: float
    crotch: float
    underarm: float
    waist: Section
    hip: Section
    bust: Section


def landmarks(vertices: np.ndarray, faces: np.ndarray) -> tuple[Landmarks, Slicer, np.ndarray]:
    """The body's landmarks, its slicer and the crotch edge."""
    s = Slicer(vertices, faces)
    floor, top = float(s.V[:, 1].min()), float(s.V[:, 1].max())
    crotch, crotch_edge = s.crotch()
    ua = s.underarm(crotch, top)

    def scan(lo: float, hi: float, pick) -> Section:
        secs = [s.torso(float(y)) for y in np.arange(lo, hi + 1e-9, STEP)]
        secs = [c for c in secs if c is not None]
        coarse = pick(secs, key=lambda c: c.girth)
        # refine to 1 mm about the best coarse section
        fine = [s.torso(float(y)) for y in np.arange(coarse.y - STEP, coarse.y + STEP + 1e-9, 0.001)]
        return pick([c for c in fine if c is not None and lo <= c.y <= hi] or [coarse], key=lambda c: c.girth)

    waist = scan(crotch + 0.45 * (ua - crotch), ua - 0.08, min)
    hip = scan(crotch + 0.01, crotch + 0.30 * (ua - crotch), max)
    bust = scan(ua - 0.09, ua - 0.005, max)
    return Landmarks(floor, top, crotch, ua, waist, hip, bust), s, crotch_edge


def measure(vertices: np.ndarray, faces: np.ndarray) -> dict[str, float]:
    """ISO 8559-1 measurements [m] of a body mesh (module docstring), and the
    heights [m, world y] where they were taken."""
    lm, _, _ = landmarks(vertices, faces)
    return {
        "height": lm.top - lm.floor,
        "bust_girth": lm.bust.girth,
        "waist_girth": lm.waist.girth,
        "hip_girth": lm.hip.girth,
        "inseam": lm.crotch - lm.floor,
        "bust_y": lm.bust.y,
        "waist_y": lm.waist.y,
        "hip_y": lm.hip.y,
        "crotch_y": lm.crotch,
        "underarm_y": lm.underarm,
        "floor_y": lm.floor,
    }


MEASURES = ("height", "bust_girth", "waist_girth", "hip_girth", "inseam")
"""the measurements a body is requested by (ISO 8559-1: stature, bust girth,
waist girth, hip girth, inside leg length), all [m]"""

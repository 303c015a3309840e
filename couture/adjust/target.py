"""Target garments for direct 3D edits (Bartle et al. 2016 §3), on the source drape's mesh.

Both edits keep the mesh (vertices, triangles, panels, seams): the target is a
new position per vertex, so the pattern found for it is a new rest shape of
the same :class:`~couture.mesh.GarmentMesh`.

Hem (length) edit, :func:`hem_edit`. The hem loop slides up along the
garment by ``|dh|`` (world height, y up) and the garment below a fixed top
part is *cut*, not squashed: every vertex below ``y_fix`` slides up along
the source drape's own surface to a height that maps [y_hem, y_fix] linearly
onto [y_hem + |dh|, y_fix]. The target therefore lies on the source surface
(its fit, normals and flare are the source's: the garment cut 15 cm shorter),
only the mesh is redistributed over the part that remains. ``y_fix`` leaves
the top ``keep`` fraction of the garment's height exactly in place (the
waist and hip fit). Lengthening (dh > 0) is refused: it would need cloth
the source does not have.

Fit edit, :func:`waist_edit`. The loop at the mannequin's waist height is
offset away from the body (radially from the torso axis) by the distance
that grows its girth (convex-hull perimeter of the garment's section, what
a tape reads) by ``dg``; the offset fades smoothly (raised cosine) to zero
at ``band`` above and below, so the bust, shoulders and hem stay fixed.
A space deformation: two coincident points (a closed seam) move alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from couture.pattern.mannequin import TORSO_AXIS_Z, WAIST_Y

from .geometry import SurfaceDistance


@dataclass
class Target:
    x: np.ndarray
    """target positions [m], shape (n, 3)"""
    edit: str
    """'hem' or 'waist'"""
    amount: float
    """[m] asked: hem rise (negative: shorter) or girth change"""
    achieved: float
    """[m] measured on the target: mean rise of the hem's lowest vertices (negated) or girth change"""
    info: dict


def hem_edit(x_src: np.ndarray, tris: np.ndarray, dh: float, *, keep: float = 0.35, slide_steps: int = 12) -> Target:
    """Shorten a draped garment by ``-dh`` [m] (dh < 0), see the module docstring."""
    if not dh < 0:
        raise ValueError(f"hem edit: dh = {dh!r} m; only shortening (dh < 0) is supported")
    y = x_src[:, 1]
    y_top, y_hem = float(y.max()), float(y.min())
    length = y_top - y_hem
    if -dh >= (1.0 - keep) * length:
        raise ValueError(
            f"hem edit: shortening by {-dh:.3f} m leaves nothing below the fixed top part "
            f"({keep:.0%} of the garment's {length:.3f} m height)"
        )
    y_fix = y_top - keep * length
    below = y < y_fix
    y_new = y.copy()
    s = (y_fix - y[below]) / (y_fix - y_hem)  # 0 at y_fix, 1 at the lowest point
    y_new[below] = y_fix - s * (y_fix - y_hem + dh)
    surf = SurfaceDistance(x_src, tris)
    x = x_src.copy()
    idx = np.nonzero(below)[0]
    p = x[idx].copy()
    y0 = y[idx]
    # slide up in small steps, each projected back onto the source surface (a
    # path along the cloth, not a jump across a fold), then settle at the height
    for k in range(1, slide_steps + 6):
        yk = y0 + (y_new[idx] - y0) * min(1.0, k / slide_steps)
        q = p.copy()
        q[:, 1] += yk - p[:, 1]
        p, _, _ = surf.closest(q)
    x[idx] = p
    low = y <= y_hem + 0.02 * length
    achieved = float((x[low, 1] - y[low]).mean())
    return Target(
        x=x,
        edit="hem",
        amount=dh,
        achieved=-achieved,
        info={
            "y_top": y_top,
            "y_hem": y_hem,
            "y_fix": y_fix,
            "keep": keep,
            "hem_rise_mean": achieved,
            "height_error_max": float(np.abs(x[idx, 1] - y_new[idx]).max()),
        },
    )


def section_girth(x: np.ndarray, tris: np.ndarray, y0: float) -> float:
    """Tape-measure girth [m] of a garment at height y0: the perimeter of the
    convex hull (in x-z) of where its edges cross the plane y = y0."""
    from scipy.spatial import ConvexHull

    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    ya, yb = x[e[:, 0], 1] - y0, x[e[:, 1], 1] - y0
    cross = (ya * yb < 0) | (ya == 0)
    a, b = e[cross, 0], e[cross, 1]
    t = (ya[cross] / np.where(ya[cross] == yb[cross], 1.0, ya[cross] - yb[cross]))[:, None]
    P = (x[a] + t * (x[b] - x[a]))[:, [0, 2]]
    if len(P) < 3:
        raise ValueError(f"the garment does not go round at height y = {y0:.3f} m")
    hull = ConvexHull(P)
    loop = P[hull.vertices]
    return float(np.linalg.norm(loop - np.roll(loop, 1, axis=0), axis=1).sum())


def _radial_offset(x: np.ndarray, d: float, y0: float, band: float) -> np.ndarray:
    r = x[:, [0, 2]] - np.array([0.0, TORSO_AXIS_Z])
    rn = np.linalg.norm(r, axis=1)
    u = r / np.maximum(rn, 1e-9)[:, None]
    s = np.abs(x[:, 1] - y0) / band
    fade = np.where(s < 1.0, 0.5 * (1.0 + np.cos(np.pi * np.minimum(s, 1.0))), 0.0)
    out = x.copy()
    out[:, 0] += d * fade * u[:, 0]
    out[:, 2] += d * fade * u[:, 1]
    return out


def waist_edit(
    x_src: np.ndarray, tris: np.ndarray, dg: float, *, y_loop: float = WAIST_Y, band: float = 0.12
) -> Target:
    """Loosen (dg > 0) or tighten a draped garment's girth at ``y_loop`` by ``dg`` [m], see the module docstring."""
    g0 = section_girth(x_src, tris, y_loop)
    d = dg / (2 * np.pi)
    for _ in range(4):  # secant on the measured girth (the hull is not exactly a circle)
        g = section_girth(_radial_offset(x_src, d, y_loop, band), tris, y_loop) - g0
        if abs(g - dg) < 1e-5:
            break
        d *= dg / g if g != 0 else 1.0
    x = _radial_offset(x_src, d, y_loop, band)
    return Target(
        x=x,
        edit="waist",
        amount=dg,
        achieved=section_girth(x, tris, y_loop) - g0,
        info={"girth_source": g0, "offset": d, "y_loop": y_loop, "band": band},
    )

"""Initial 3D placement of panels around the mannequin (Meng 2010 / Volino 2005 §3.4.2).

Each panel is wrapped around a cylinder or cone (:class:`Placement` kind
'cylinder'): material x becomes arc length around the axis, material y runs
along the axis. The axis may be tilted (sleeves along the arm, trouser legs
along the leg) and the radius may grow linearly with distance down the axis
(``taper``), so a flared panel keeps its width and neighbours do not overlap.
Radii are chosen from the mannequin's measured radius profile plus a margin,
so every panel starts outside the body.
"""

from __future__ import annotations

import numpy as np

from couture.pattern.drafted import Panel, Placement

UP = np.array([0.0, 1.0, 0.0])
FRONT = np.array([0.0, 0.0, 1.0])


def frame(pl: Placement) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, f, b): axis (material +y), theta = 0 direction, theta = pi/2 direction."""
    a = UP if getattr(pl, "axis", None) is None else np.asarray(pl.axis, float)
    a = a / np.linalg.norm(a)
    f = FRONT if getattr(pl, "ref", None) is None else np.asarray(pl.ref, float)
    f = f - (f @ a) * a
    f = f / np.linalg.norm(f)
    return a, f, np.cross(a, f)


def place(panel: Panel, points2d: np.ndarray) -> np.ndarray:
    """Map material points (m, 2) of ``panel`` to world positions (m, 3) [m].

    'cylinder': r = radius + taper * (-y) (clamped >= 1 mm), theta = angle0 +
    x / r (or -x / r with ``flip``), world = origin + y / sqrt(1 + taper^2) * a
    + r (cos theta f + sin theta b), with a the axis (default world up), f the
    theta = 0 direction (default world +z, the front) and b = a x f. The
    outward normal of a counter-clockwise panel points away from the axis.
    'plane': origin + x u + y v. No placement: flat at z = 0.
    """
    P = np.asarray(points2d, float)
    pl = panel.placement
    if pl is None:
        return np.column_stack([P, np.zeros(len(P))])
    if pl.kind == "plane":
        return pl.origin + P[:, :1] * np.asarray(pl.u) + P[:, 1:2] * np.asarray(pl.v)
    if pl.kind != "cylinder":
        raise ValueError(f"placement kind {pl.kind!r} of panel {panel.name!r} is not 'cylinder' or 'plane'")
    a, f, b = frame(pl)
    taper = getattr(pl, "taper", 0.0)
    r = np.maximum(pl.radius - taper * P[:, 1], 1e-3)
    x = -P[:, 0] if pl.flip else P[:, 0]
    th = pl.angle0 + x / r
    along = P[:, 1] / np.sqrt(1.0 + taper * taper)
    return (np.asarray(pl.origin, float) + along[:, None] * a
            + r[:, None] * (np.cos(th)[:, None] * f + np.sin(th)[:, None] * b))


def fit_ring(ring, panels: dict[str, Panel]) -> dict[str, Placement]:
    """Cone radius and taper so that, at every material height, the ring clears
    the body by ``ring.margin`` and the panels' summed widths fit around it."""
    pts = [panels[n].outline for n in ring.panels]
    ys = np.concatenate([p[:, 1] for p in pts])
    y_lo, y_hi = ys.min(), ys.max()
    bins = np.linspace(y_lo, y_hi, max(2, int(np.ceil((y_hi - y_lo) / 0.02)) + 1))
    centres = 0.5 * (bins[1:] + bins[:-1])
    width = np.zeros(len(centres))
    for p in pts:
        # interpolate the outline densely so narrow bins see it
        q = np.vstack([p, p[:1]])
        t = np.linspace(0, 1, 8, endpoint=False)
        dense = (q[:-1, None, :] * (1 - t[None, :, None]) + q[1:, None, :] * t[None, :, None]).reshape(-1, 2)
        k = np.clip(np.searchsorted(bins, dense[:, 1]) - 1, 0, len(centres) - 1)
        lo = np.full(len(centres), np.inf)
        hi = np.full(len(centres), -np.inf)
        np.minimum.at(lo, k, dense[:, 0])
        np.maximum.at(hi, k, dense[:, 0])
        width += np.where(np.isfinite(lo), hi - lo, 0.0)
    need = np.maximum(ring.body_radius(centres) + ring.margin, width / (2 * np.pi) * 1.02)
    need = np.append(need, ring.body_radius(np.array([y_hi]))[0] + ring.margin)
    yc = np.append(centres, y_hi)
    drop = y_hi - yc
    # r(y) = top + taper * (y_hi - y) >= need(y), taper >= 0; pick the cone of
    # smallest mean radius among a fine grid of tapers (cheap, robust)
    tapers = np.linspace(0.0, 3.0, 601)
    tops = (need[None, :] - tapers[:, None] * drop[None, :]).max(axis=1)
    mean_r = tops + tapers * 0.5 * (y_hi - y_lo)
    best = int(np.argmin(mean_r))
    taper, top = float(tapers[best]), float(tops[best])
    radius = min(top + taper * y_hi, ring.max_radius)
    out = {}
    for name, ang in zip(ring.panels, ring.angles):
        p = panels[name].outline
        xm = 0.5 * (p[:, 0].min() + p[:, 0].max())
        r_mid = max(radius - taper * 0.5 * (p[:, 1].min() + p[:, 1].max()), 1e-3)
        out[name] = Placement("cylinder", np.asarray(ring.origin, float).copy(), radius=radius,
                              angle0=float(ang - xm / r_mid),
                              axis=None if ring.axis is None else np.asarray(ring.axis, float),
                              ref=None if ring.ref is None else np.asarray(ring.ref, float), taper=taper)
    return out

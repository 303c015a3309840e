"""Initial 3D placement of panels around the mannequin (Meng 2010 / Volino 2005 §3.4.2).

Panels of one ring (a skirt's gores, a bodice's front and back, a sleeve, a
trouser leg) are wrapped around one axis (vertical for the torso, tilted for
sleeves and trouser legs): material y runs along the axis, material x along
the ring's cross-section curve at that height, by arc length, so every
horizontal line of a panel is laid without stretch (placement kind 'wrap').

The cross-section at each height is the body's own section there (the convex
hull of the body part in a slab about the axis, :mod:`couture.pattern.sections`)
grown by the ring's clearance margin, and grown further, uniformly, until its
perimeter equals the garment's girth at that height (the summed widths of the
ring's panels): then the panels tile the curve edge to edge and the seams
between them start closed. Where the garment is smaller than the grown body
section (a waistband at the waist, whose ease is smaller than the clearance
asks for), the curve keeps its clearance and the shortfall is shared equally
by the seams (or, for a ring with ``gap_at``, left as one opening there: a
trouser leg's half ring, open where the other leg's panels join it).

The older kinds stay: 'cylinder' (a cone: radius + taper) and 'plane'.
"""

from __future__ import annotations

import numpy as np

from couture.pattern.drafted import Panel, Placement

UP = np.array([0.0, 1.0, 0.0])
FRONT = np.array([0.0, 0.0, 1.0])
ROW_SPACING = 0.01
"""[m] material-y spacing of a wrap placement's rows"""
_UPSAMPLE = 4  # polar samples per section-table angle: a smoother curve to wrap on


def frame(pl: Placement) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, f, b): axis (material +y), theta = 0 direction, theta = pi/2 direction."""
    a = UP if getattr(pl, "axis", None) is None else np.asarray(pl.axis, float)
    a = a / np.linalg.norm(a)
    f = FRONT if getattr(pl, "ref", None) is None else np.asarray(pl.ref, float)
    f = f - (f @ a) * a
    f = f / np.linalg.norm(f)
    return a, f, np.cross(a, f)


def _curve(radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed polygon (K + 1, 2) in (f, b) coordinates of polar radii (K,) at
    theta_k = 2 pi k / K, and its cumulative arc length (K + 1,)."""
    K = len(radius)
    th = 2 * np.pi * np.arange(K + 1) / K
    r = np.append(radius, radius[0])
    P = np.column_stack([r * np.cos(th), r * np.sin(th)])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    return P, s


def _upsample(radius: np.ndarray, factor: int = _UPSAMPLE) -> np.ndarray:
    """Polar radii resampled factor times finer (periodic linear interpolation)."""
    radius = np.atleast_2d(radius)
    K = radius.shape[1]
    th = np.arange(K * factor) / factor
    k0 = np.floor(th).astype(int) % K
    w = th - np.floor(th)
    return (1 - w) * radius[:, k0] + w * radius[:, (k0 + 1) % K]


def _wrap_row(pl: Placement, row: int, x: np.ndarray) -> np.ndarray:
    """World positions (m, 3) of material x (m,) on row ``row`` of a wrap placement."""
    assert pl.rows_radius is not None and pl.rows_x0 is not None and pl.rows_axial is not None, "not a wrap placement"
    a, f, b = frame(pl)
    P, s = _curve(pl.rows_radius[row])
    u = np.mod(x - pl.rows_x0[row], s[-1])
    k = np.clip(np.searchsorted(s, u, side="right") - 1, 0, len(s) - 2)
    t = ((u - s[k]) / np.maximum(s[k + 1] - s[k], 1e-300))[:, None]
    q = (1 - t) * P[k] + t * P[k + 1]
    return np.asarray(pl.origin, float) + pl.rows_axial[row] * a + q[:, :1] * f + q[:, 1:] * b


def place(panel: Panel, points2d: np.ndarray) -> np.ndarray:
    """Map material points (m, 2) of ``panel`` to world positions (m, 3) [m].

    'wrap': see the module docstring; rows are interpolated linearly in y.
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
    if pl.kind == "wrap":
        ys = pl.rows_y
        assert ys is not None, "a wrap placement has rows"
        j = np.clip(np.searchsorted(ys, P[:, 1], side="right") - 1, 0, len(ys) - 2)
        w = np.clip((P[:, 1] - ys[j]) / (ys[j + 1] - ys[j]), 0.0, 1.0)[:, None]
        out = np.empty((len(P), 3))
        for row in np.unique(j):
            m = j == row
            out[m] = (1 - w[m]) * _wrap_row(pl, row, P[m, 0]) + w[m] * _wrap_row(pl, row + 1, P[m, 0])
        return out
    if pl.kind == "grid":
        gx, gy, G = pl.grid_x, pl.grid_y, pl.grid_pos
        assert gx is not None and gy is not None and G is not None, "a grid placement has its grid"
        i = np.clip(np.searchsorted(gx, P[:, 0], side="right") - 1, 0, len(gx) - 2)
        j = np.clip(np.searchsorted(gy, P[:, 1], side="right") - 1, 0, len(gy) - 2)
        s = np.clip((P[:, 0] - gx[i]) / (gx[i + 1] - gx[i]), 0.0, 1.0)[:, None]
        t = np.clip((P[:, 1] - gy[j]) / (gy[j + 1] - gy[j]), 0.0, 1.0)[:, None]
        return (1 - t) * ((1 - s) * G[j, i] + s * G[j, i + 1]) + t * ((1 - s) * G[j + 1, i] + s * G[j + 1, i + 1])
    if pl.kind != "cylinder":
        raise ValueError(
            f"placement kind {pl.kind!r} of panel {panel.name!r} is not 'wrap', 'grid', 'cylinder' or 'plane'"
        )
    a, f, b = frame(pl)
    taper = getattr(pl, "taper", 0.0)
    r = np.maximum(pl.radius - taper * P[:, 1], 1e-3)
    x = -P[:, 0] if pl.flip else P[:, 0]
    th = pl.angle0 + x / r
    along = P[:, 1] / np.sqrt(1.0 + taper * taper)
    return (
        np.asarray(pl.origin, float)
        + along[:, None] * a
        + r[:, None] * (np.cos(th)[:, None] * f + np.sin(th)[:, None] * b)
    )


def _extents(outline: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Leftmost and rightmost material x of a closed outline on each horizontal
    line y (clamped into the outline's y range), shape (len(ys),) each."""
    q0, q1 = outline, np.roll(outline, -1, axis=0)
    lo_y, hi_y = outline[:, 1].min(), outline[:, 1].max()
    eps = 1e-6 * max(hi_y - lo_y, 1e-3)
    y = np.clip(ys, lo_y + eps, hi_y - eps)[:, None]
    ya, yb = q0[None, :, 1], q1[None, :, 1]
    cross = (np.minimum(ya, yb) <= y) & (np.maximum(ya, yb) > y)
    t = (y - ya) / np.where(yb != ya, yb - ya, 1.0)
    x = q0[None, :, 0] + t * (q1[None, :, 0] - q0[None, :, 0])
    lo = np.where(cross, x, np.inf).min(axis=1)
    hi = np.where(cross, x, -np.inf).max(axis=1)
    return lo, hi


def _grow_to(base: np.ndarray, girth: float, lo: float = 0.0) -> np.ndarray:
    """``base`` polar radii (K,) grown (or shrunk, by at most ``-lo``) uniformly
    so the curve's perimeter is as close to ``girth`` [m] as that allows (a
    few secant steps; perimeter is ~2 pi per metre of growth)."""
    p0 = _curve(base)[1][-1]
    d = (girth - p0) / (2 * np.pi)
    if d <= lo:
        return base + lo
    for _ in range(3):
        p = _curve(base + d)[1][-1]
        d += (girth - p) / (2 * np.pi)
    return base + d


def _full_row(widths: np.ndarray) -> int | None:
    """The highest row (index) that every panel crosses at half its widest or
    more, widths (panels, rows); None when no row does."""
    full = np.all(widths >= 0.5 * widths.max(axis=1, keepdims=True), axis=0)
    return int(np.nonzero(full)[0].max()) if full.any() else None


CHECK_SPACING = 0.01
"""[m] spacing of the points along a row checked against the body"""
ARMPIT_STEPS = 10
"""a top's ring moves down at most this many row spacings to clear the body"""


def _in_body(outlines, ys, rows, origin, a, f, b, R, axial, x0, body: str, clear: float) -> bool:
    """Whether any cloth of the laid-out ring on the rows ``rows`` (every
    ``CHECK_SPACING`` between its panels' outline crossings there) lies within
    ``clear`` [m] of ``body``'s surface (its distance field, arms included)."""
    from couture.cloth.body import load_mannequin_sdf

    pts = []
    for p, o in enumerate(outlines):
        q0, q1 = o, np.roll(o, -1, axis=0)
        ya, yb = q0[:, 1], q1[:, 1]
        for i in rows:
            cross = (np.minimum(ya, yb) <= ys[i]) & (np.maximum(ya, yb) > ys[i])
            if not cross.any():
                continue
            t = (ys[i] - ya[cross]) / np.where(yb[cross] != ya[cross], yb[cross] - ya[cross], 1.0)
            x = np.sort(q0[cross, 0] + t * (q1[cross, 0] - q0[cross, 0]))
            # the cloth between pairs of crossings, every CHECK_SPACING
            x = np.concatenate(
                [
                    np.linspace(x0_, x1_, max(2, int(np.ceil((x1_ - x0_) / CHECK_SPACING)) + 1))
                    for x0_, x1_ in zip(x[::2], x[1::2], strict=False)
                ]
            )
            P, s = _curve(R[i])
            u = np.mod(x - x0[p, i], s[-1])
            k = np.clip(np.searchsorted(s, u, side="right") - 1, 0, len(s) - 2)
            w = ((u - s[k]) / np.maximum(s[k + 1] - s[k], 1e-300))[:, None]
            q = (1 - w) * P[k] + w * P[k + 1]
            pts.append(origin + axial[i] * a + q[:, :1] * f + q[:, 1:] * b)
    if not pts:
        return False
    phi, _ = load_mannequin_sdf(verbose=False, name=body).phi_grad(np.ascontiguousarray(np.concatenate(pts)))
    return bool(np.any(phi < clear))


def fit_ring(ring, panels: dict[str, Panel], body: str = "default") -> dict[str, Placement]:
    """'wrap' placements of a ring's panels: the section of ``body`` (a name of
    couture.bodies) plus margin, grown to the garment's girth, with the panels
    tiling it (module docstring)."""
    from couture.pattern.sections import sections

    outlines = [np.asarray(panels[n].outline, float) for n in ring.panels]
    y_lo = min(o[:, 1].min() for o in outlines)
    y_hi = max(o[:, 1].max() for o in outlines)
    n_rows = max(2, int(np.ceil((y_hi - y_lo) / ROW_SPACING)) + 1)
    ys = np.linspace(y_lo, y_hi, n_rows)
    ext = [_extents(o, ys) for o in outlines]
    # a panel spans the rows its y range covers, to round-off: hems that are level in
    # exact arithmetic (an imported pair's, 1e-16 m apart) all reach the bottom row
    tol = 1e-9 * max(y_hi - y_lo, 1.0)
    spans = [((o[:, 1].min() <= ys + tol) & (ys - tol <= o[:, 1].max())) for o in outlines]
    widths = np.array([np.where(sp, hi - lo, 0.0) for (lo, hi), sp in zip(ext, spans, strict=True)])  # (panels, rows)
    girth = widths.sum(axis=0)

    origin = np.asarray(ring.origin, float)
    a = UP if ring.axis is None else np.asarray(ring.axis, float) / np.linalg.norm(ring.axis)
    landmark = getattr(ring, "landmark", None)
    if landmark is not None and body != "default":
        # the drafted origin is at the default body's landmark height: move it along the axis to this body's
        from couture.pattern.landmarks import landmark_y

        shift = landmark_y(body, landmark) - landmark_y("default", landmark)
        origin = origin + a * (shift / a[1])
    f = FRONT if ring.ref is None else np.asarray(ring.ref, float)
    f = f - (f @ a) * a
    f = f / np.linalg.norm(f)
    b = np.cross(a, f)
    sec = sections(body)[ring.section] if getattr(ring, "section", None) else None
    if sec is not None and ring.section.endswith("_arm"):
        # an arm's table may sit off the default's frame (a body whose arms moved:
        # couture.pattern.sections.measure_sections): the ring moves with it
        from couture.pattern.sections import frames

        origin = origin + (sec.origin - frames()[ring.section][0])
    K = 64
    if sec is not None:
        K = sec.radius.shape[1]
        # the table's theta = 0 may differ from the ring's: resample at the ring's angles
        phi = np.arctan2(sec.ref @ b, sec.ref @ f)
    i_full = _full_row(widths) if getattr(ring, "top_rows_as_full", False) else None

    def layout(origin: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(R, axial, x0) of the ring with its axis point for material y = 0 at ``origin``."""
        t_off = float((origin - sec.origin) @ sec.axis) if sec is not None else 0.0

        def base_radii(axial: np.ndarray) -> np.ndarray:
            """Body radii (rows, K) about the ring's axis at its axial coordinates:
            the section table, at least the ring's ``body_radius`` circle."""
            circle = None
            if ring.body_radius is not None:
                circle = np.repeat(np.asarray(ring.body_radius(axial), float)[:, None], K, axis=1)
            if sec is None:
                if circle is None:
                    raise ValueError("a ring needs a body section or a body_radius")
                return circle
            R = sec.radii(axial + t_off)
            reach = getattr(ring, "section_reach", 0.0)
            if reach > 0:
                for dt in (-reach, -0.5 * reach, 0.5 * reach, reach):
                    R = np.maximum(R, sec.radii(axial + t_off + dt))
            # theta_ring = theta_sec - phi
            th = (2 * np.pi * np.arange(K) / K + phi) % (2 * np.pi) / (2 * np.pi) * K
            k0 = np.floor(th).astype(int) % K
            w = th - np.floor(th)
            R = (1 - w) * R[:, k0] + w * R[:, (k0 + 1) % K]
            empty = R.max(axis=1) <= 0
            if empty.any():
                R[empty] = R[~empty].max(axis=0)
            return R if circle is None else np.maximum(R, circle)

        axial = ys.copy()
        for _ in range(2):
            # a garment tighter than body + margin (a waistband) gives up part of
            # its margin, down to min_margin, before its seams open
            base = _upsample(base_radii(axial) + ring.margin)
            lo = ring.min_margin - ring.margin if getattr(ring, "gap_at", None) is None else 0.0
            R = np.array([_grow_to(base[i], girth[i], lo) for i in range(n_rows)])
            # keep material y lengths along the meridian: the axis shortens where the radius changes
            rbar = R.mean(axis=1)
            dy = np.diff(ys)
            dh = np.sqrt(np.maximum(dy**2 - np.diff(rbar) ** 2, (0.5 * dy) ** 2))
            axial = y_hi - np.concatenate([np.cumsum(dh[::-1])[::-1], [0.0]])
            if getattr(ring, "anchor_y", None) is not None:  # that row keeps its height instead of the top
                axial = axial + ring.anchor_y - float(np.interp(ring.anchor_y, ys, axial))

        x0 = np.zeros((len(ring.panels), n_rows))
        n = len(ring.panels)
        for i in range(n_rows):
            P, s = _curve(R[i])
            perim = s[-1]
            spare = max(perim - girth[i], 0.0)

            def arc_at(theta, s=s):
                return float(np.interp(np.mod(theta, 2 * np.pi), 2 * np.pi * np.arange(len(s)) / (len(s) - 1), s))

            w_i = widths[:, i]
            if getattr(ring, "gap_at", None) is None:
                start = arc_at(ring.angles[0]) - 0.5 * w_i[0] - 0.5 * spare / n
                starts = start + np.concatenate([[0.0], np.cumsum(w_i[:-1] + spare / n)]) + 0.5 * spare / n
            else:
                start = arc_at(ring.gap_at) + 0.5 * spare
                starts = start + np.concatenate([[0.0], np.cumsum(w_i[:-1])])
            for p in range(n):
                x0[p, i] = ext[p][0][i] - starts[p]

        if i_full is not None:
            # a curved top (an imported skirt's waist, higher at the sides): above the highest row
            # that every panel crosses at half its width or more, the panels keep that row's layout,
            # not a row of slivers spread round the body with the shortfall between them
            # (on a curve no nearer the body than its margin: a top's straps over the shoulders)
            x0[:, i_full + 1 :] = x0[:, i_full : i_full + 1]
            R[i_full + 1 :] = np.maximum(R[i_full], base[i_full + 1 :])
        return R, axial, x0

    R, axial, x0 = layout(origin)
    clear = getattr(ring, "armpit_clear", None)
    if clear is not None:
        # a top: down, a row spacing at a time, until none of its cloth above the body's
        # waist (sides by the arms, straps at the shoulders) lies within ``clear`` of the body;
        # below the waist a hem tighter than the hips may start in them (the drape lifts it)
        from couture.bodies import measured

        waist = float(measured(body)["waist_y"])
        for _ in range(ARMPIT_STEPS):
            rows = np.flatnonzero(origin[1] + a[1] * axial >= waist)
            if not _in_body(outlines, ys, rows, origin, a, f, b, R, axial, x0, body, clear):
                break
            origin = origin - a * (ROW_SPACING / a[1])
            R, axial, x0 = layout(origin)
    out = {}
    for p, name in enumerate(ring.panels):
        out[name] = Placement(
            "wrap",
            origin.copy(),
            axis=None if ring.axis is None else a.copy(),
            ref=None if ring.ref is None else f.copy(),
            rows_y=ys.copy(),
            rows_axial=axial.copy(),
            rows_x0=x0[p].copy(),
            rows_radius=R.copy(),
        )
    return out

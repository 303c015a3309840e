"""``couture bench fabric``: virtual fabric tests of the library fabrics, each
a scene draped by the project's solver (Newton on a ``ClothModel``) and
compared with a reference computed independently of the cloth model.

- ``cantilever`` (ASTM D1388, Peirce): a 2.5 cm strip clamped flat over a
  platform and overhanging its edge; the overhang at which the line from
  the edge to the tip falls 41.5 degrees below horizontal (found by scaling
  the strip's weight at a fixed overhang, the same by the elastica's
  similarity, so one triangulation serves the search: ``cantilever``). Against
  the heavy elastica (an inextensible rod of rigidity G W and weight w g W
  per length, its ODE solved by ``scipy.integrate.solve_bvp``) for the same
  strip: the overhang at 41.5 degrees within 2 %; Peirce's reading
  c = (G / (w g))^(1/3), overhang 2c, beside it. Along warp, weft and bias:
  the strip's long axis is laid along that direction of the fabric's
  material plane (warp = material +y, ``Panel.grain`` 0; weft +x; bias 45
  degrees), so a model that reads the grain sees each direction's values.
- ``tensile``: a 20 cm x 2 cm strip clamped at both ends and stretched by a
  strain of 1e-3 (gravity off); force per width from the clamp's reaction,
  strain read in the middle third (an extensometer's gauge, away from the
  clamps' restrained contraction); against the fabric table along warp and
  weft, and on the bias against the orthotropic compliance
  1/E45 = 1/4 (1/E1 + 1/E2 + 1/G12 - 2 nu12/E1), within 1 %. An isotropic
  model (one that does not read the directional fields) is compared with
  its own isotropic table (E = stretch_stiffness) and says so.
- ``cusick`` (BS 5058 / ISO 9073-9): a 30 cm disc clamped on an 18 cm
  support (a rounded short cylinder, a body with a signed distance field);
  drape coefficient DC = (A_shadow - A_support) / (A_disc - A_support) from
  the projected area and the number of nodes (folds) from the rim's radius
  against angle, for every library fabric; the literature's order (chiffon
  and charmeuse below jersey below cotton below denim and canvas) checked;
  where the library gives a fabric's published drape coefficient
  (``measured_dc``) the bench's beside it; a picture of the discs side by
  side. ``--seed`` picks the discs' random start (the folds choose by it).

Writes ``fabric.json`` and ``cusick.png`` to ``--out`` (default
``bench/results/fabric/``). ``--quick``: one fabric, coarse meshes (a test).
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from bench import RESULTS_DIR, source_commit, write_results

GRAVITY = 9.81
"""[m/s²], as couture.cloth.model"""

ASTM_ANGLE = math.radians(41.5)
"""ASTM D1388 tip-line angle below horizontal"""

DIRECTIONS = {"warp": 0.0, "weft": 90.0, "bias": 45.0}
"""strip direction -> angle [deg] of its long axis from the warp (material +y), counter-clockwise"""

DISC_RADIUS = 0.15
SUPPORT_RADIUS = 0.09


# ----------------------------------------------------------------------
# references, independent of the cloth model
# ----------------------------------------------------------------------


def elastica(lam: float, n: int = 401) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heavy elastica of a clamped inextensible rod, in units of its length:
    phi'' = -lam (1 - s) cos phi, phi(0) = 0, phi'(1) = 0 (phi the slope
    below horizontal, lam = q l³ / EI), solved by ``solve_bvp`` with
    continuation in lam. Returns s, x(s), y(s) (y downward positive)."""
    from scipy.integrate import cumulative_trapezoid, solve_bvp

    s = np.linspace(0.0, 1.0, n)
    y = np.zeros((2, n))
    sol = None
    for lam_k in np.linspace(0.0, lam, max(2, int(math.ceil(lam / 2.0)) + 1))[1:]:

        def rhs(t, u, lam_k=lam_k):
            return np.vstack([u[1], -lam_k * (1.0 - t) * np.cos(u[0])])

        def bc(ua, ub):
            return np.array([ua[0], ub[1]])

        sol = solve_bvp(rhs, bc, s, y, tol=1e-10, max_nodes=100_000)
        if not sol.success:
            raise RuntimeError(f"elastica: solve_bvp failed at lam = {lam_k}: {sol.message}")
        y = sol.sol(s)
    phi = y[0]
    x = cumulative_trapezoid(np.cos(phi), s, initial=0.0)
    yy = cumulative_trapezoid(np.sin(phi), s, initial=0.0)
    return s, x, yy


def elastica_tip_angle(lam: float) -> float:
    """[rad] angle below horizontal of the line from the clamp to the tip."""
    _, x, y = elastica(lam)
    return float(math.atan2(y[-1], x[-1]))


def elastica_lambda(angle: float = ASTM_ANGLE) -> float:
    """q l³ / EI at which the tip line falls ``angle`` below horizontal."""
    from scipy.optimize import brentq

    return float(brentq(lambda lam: elastica_tip_angle(lam) - angle, 1.0, 40.0, xtol=1e-10))


def peirce_overhang_ratio(angle: float = ASTM_ANGLE) -> float:
    """Peirce's l / c at the tip-line angle: c = l (cos(θ/2) / (8 tan θ))^(1/3)
    (2.0 at 41.5 degrees, the ASTM D1388 reading l = 2c)."""
    return float((math.cos(angle / 2) / (8 * math.tan(angle))) ** (-1.0 / 3.0))


def bias_stiffness(e1: float, e2: float, g12: float, nu12: float) -> float:
    """[N/m] tensile stiffness at 45 degrees of an orthotropic sheet:
    1/E45 = 1/4 (1/E1 + 1/E2 + 1/G12 - 2 nu12/E1)."""
    return 1.0 / (0.25 * (1.0 / e1 + 1.0 / e2 + 1.0 / g12 - 2.0 * nu12 / e1))


def rim_profile(points: np.ndarray, center: np.ndarray, bins: int = 720) -> tuple[np.ndarray, np.ndarray]:
    """The shadow's outline seen from above: per angle bin the largest
    horizontal radius of ``points`` (n, 3; y up) about ``center`` (3,);
    an empty bin takes its neighbours' (periodic interpolation).
    Returns bin-centre angles (bins,) [rad] and radii (bins,) [m]."""
    d = points[:, [0, 2]] - center[[0, 2]]
    ang = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2 * np.pi)
    rad = np.hypot(d[:, 0], d[:, 1])
    k = np.minimum((ang / (2 * np.pi) * bins).astype(int), bins - 1)
    r = np.full(bins, np.nan)
    np.fmax.at(r, k, rad)
    theta = (np.arange(bins) + 0.5) * 2 * np.pi / bins
    ok = np.isfinite(r)
    if not ok.all():
        r = np.interp(theta, theta[ok], r[ok], period=2 * np.pi)
    return theta, r


def shadow_area(theta: np.ndarray, r: np.ndarray) -> float:
    """[m²] area inside the star-shaped outline r(theta): ½ ∮ r² dθ."""
    return float(0.5 * np.sum(r**2) * (2 * np.pi / len(theta)))


def polygon_area(p: np.ndarray) -> float:
    """[m²] area of the closed polygon p (k, 2) (shoelace; either orientation)."""
    x, y = p[:, 0], p[:, 1]
    return float(0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def drape_coefficient(shadow: float, disc_radius: float = DISC_RADIUS, support_radius: float = SUPPORT_RADIUS) -> float:
    """DC = (A_shadow - A_support) / (A_disc - A_support) (BS 5058), A_shadow [m²]."""
    a_s = math.pi * support_radius**2
    return (shadow - a_s) / (math.pi * disc_radius**2 - a_s)


def count_nodes(r: np.ndarray, prominence: float = 0.005, smooth: int = 3) -> int:
    """Folds (nodes) of a drape: the peaks of the periodic radius r (k,) [m]
    of the disc's rim (its vertices in order round the rim), smoothed over
    ``smooth`` samples, that stand ``prominence`` [m] above the troughs
    either side (scipy.signal.find_peaks on the signal wrapped once so a
    peak at angle 0 counts once)."""
    from scipy.signal import find_peaks

    n = len(r)
    if smooth > 1:
        kern = np.ones(smooth) / smooth
        r = np.convolve(np.concatenate([r[-smooth:], r, r[:smooth]]), kern, mode="same")[smooth:-smooth]
    ext = np.concatenate([r, r, r])
    peaks, _ = find_peaks(ext, prominence=prominence)
    return int(np.sum((peaks >= n) & (peaks < 2 * n)))


# ----------------------------------------------------------------------
# scenes
# ----------------------------------------------------------------------


def _strip_mesh(length: float, width: float, h: float, direction_deg: float, clamp: float = 0.0):
    """A quality-triangulated strip (``triangle``, min angle 30 degrees, spacing
    about h), long axis u in [-clamp, length], v in [0, width], with a row of
    mesh edges exactly on u = 0 (the platform's edge: the clamp ends there, not
    up to a triangle short of it), laid in the material plane with its long
    axis ``direction_deg`` from the warp (material +y) counter-clockwise.
    Returns the mesh and its (u, v)."""
    import triangle as tr

    from couture.mesh import GarmentMesh

    def pts(a: float, b: float) -> np.ndarray:
        return np.linspace(a, b, max(2, int(round(abs(b - a) / h)) + 1))

    us = np.concatenate([pts(-clamp, 0.0)[:-1], pts(0.0, length)]) if clamp > 0 else pts(0.0, length)
    vs = pts(0.0, width)
    boundary = np.concatenate(
        [
            np.column_stack([us[:-1], np.zeros(len(us) - 1)]),
            np.column_stack([np.full(len(vs) - 1, length), vs[:-1]]),
            np.column_stack([us[::-1][:-1], np.full(len(us) - 1, width)]),
            np.column_stack([np.full(len(vs) - 1, us[0]), vs[::-1][:-1]]),
        ]
    )
    k = len(boundary)
    segs = [np.column_stack([np.arange(k), (np.arange(k) + 1) % k])]
    verts = [boundary]
    if clamp > 0:
        # the clamp line u = 0 as a chain of segments between the two long edges
        i0 = int(np.argmin(np.hypot(boundary[:, 0], boundary[:, 1])))
        i1 = int(np.argmin(np.hypot(boundary[:, 0], boundary[:, 1] - width)))
        inner = np.column_stack([np.zeros(len(vs) - 2), vs[1:-1]])
        ids = np.concatenate([[i0], k + np.arange(len(inner)), [i1]])
        verts.append(inner)
        segs.append(np.column_stack([ids[:-1], ids[1:]]))
    area = 0.5 * h * h * math.sqrt(3) / 2 * 1.2
    out = tr.triangulate({"vertices": np.concatenate(verts), "segments": np.concatenate(segs)}, f"pq30a{area:.12f}Q")
    P = out["vertices"].astype(np.float64)
    tris = out["triangles"].astype(np.int32)
    e1 = P[tris[:, 1]] - P[tris[:, 0]]
    e2 = P[tris[:, 2]] - P[tris[:, 0]]
    flip = (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) < 0
    tris[flip] = tris[flip][:, [0, 2, 1]]
    u, v = P[:, 0], P[:, 1]
    b = math.radians(direction_deg)
    t = np.array([-math.sin(b), math.cos(b)])  # the strip's axis in the material plane
    nrm = np.array([math.cos(b), math.sin(b)])
    X = u[:, None] * t + v[:, None] * nrm
    x0 = np.column_stack([u, np.zeros_like(u), v])  # world: u along +x, y up, v along +z
    # the rotation keeps the triangles counter-clockwise in X
    return GarmentMesh(X=X, tris=tris, x0=x0), u, v


def _newton(model, x0, tol: float, max_seconds: float = 120.0):
    from couture.solvers import get_solver

    res = get_solver("newton").solve(model, x0, tol=tol, max_iters=500, max_seconds=max_seconds)
    return res


def _orthotropic(model) -> bool:
    """Whether the model built a directional (orthotropic) membrane or bending path."""
    return any("ortho" in t or "aniso" in t for t in model.terms) or bool(getattr(model, "orthotropic", False))


def _model_is_orthotropic(fabric) -> bool:
    """Whether a ClothModel built from ``fabric`` reads its directional fields (a tiny model is built to ask)."""
    from couture.cloth import ClothModel, Scene
    from couture.mesh import grid_sheet

    return _orthotropic(ClothModel(grid_sheet(0.1, 0.1, 3, 3), fabric, Scene(gravity=False)))


def _direction_table(fabric, direction: str) -> tuple[float, float]:
    """(tensile stiffness [N/m], bending rigidity [N m]) the fabric table gives a strip cut along ``direction``."""
    f = fabric
    e1 = f.warp_stiffness or f.stretch_stiffness
    e2 = f.weft_stiffness or f.stretch_stiffness
    nu = f.poisson_ratio
    g12 = f.shear_stiffness or f.stretch_stiffness / (2 * (1 + nu))
    b1 = f.bend_warp if f.bend_warp is not None else f.bend_stiffness
    b2 = f.bend_weft if f.bend_weft is not None else f.bend_stiffness
    if direction == "warp":
        return e1, b1
    if direction == "weft":
        return e2, b2
    bb = f.bend_bias if f.bend_bias is not None else 0.5 * (b1 + b2)
    return bias_stiffness(e1, e2, g12, nu), bb


def _isotropic(fabric):
    """The fabric as a model that reads only the isotropic fields sees it."""
    return msgspec.structs.replace(
        fabric,
        warp_stiffness=None,
        weft_stiffness=None,
        shear_stiffness=None,
        bend_warp=None,
        bend_weft=None,
        bend_bias=None,
    )


def cantilever_angle(
    fabric,
    direction: str,
    overhang: float,
    h: float,
    width: float = 0.025,
    mesh_overhang: float | None = None,
    weight: float = 1.0,
) -> dict[str, Any]:
    """Drape the strip with ``overhang`` [m] beyond the platform edge (clamped
    flat 1 cm back from it), its area density ``weight`` times the fabric's;
    the tip line's angle below horizontal. The mesh is made for
    ``mesh_overhang`` (default: the overhang) and its overhanging part
    stretched to ``overhang`` in the rest shape."""
    from couture.cloth import ClothModel, Scene

    if weight != 1.0:
        fabric = msgspec.structs.replace(fabric, area_density=fabric.area_density * weight)

    clamp = max(2 * h, 0.01)
    base = overhang if mesh_overhang is None else mesh_overhang
    mesh, u, v = _strip_mesh(base, width, h, DIRECTIONS[direction], clamp=clamp)
    if base != overhang:
        u = np.where(u > 0, u * (overhang / base), u)
        b = math.radians(DIRECTIONS[direction])
        t = np.array([-math.sin(b), math.cos(b)])
        nrm = np.array([math.cos(b), math.sin(b)])
        mesh.X = np.ascontiguousarray(u[:, None] * t + v[:, None] * nrm)
        mesh.x0 = np.ascontiguousarray(np.column_stack([u, np.zeros_like(u), v]))
    mesh.pinned = np.nonzero(u <= 1e-12)[0].astype(np.int32)
    model = ClothModel(mesh, fabric, Scene())
    res = _newton(model, mesh.x0, tol=1e-8)
    tip = np.isclose(u, overhang)
    xt = res.x[tip].mean(axis=0)
    return {
        "angle_deg": math.degrees(math.atan2(-xt[1], xt[0])),
        "converged": bool(res.converged),
        "residual": float(res.residual),
        "iterations": int(res.iterations),
        "seconds": float(res.wall_time),
        "vertices": int(model.n),
        "orthotropic_model": _orthotropic(model),
    }


STRIP_ROWS = 32
"""the cantilever strip's mesh has at least this many rows over its overhang"""

STRIP_MESHES = (0.0, -0.004, 0.004)
"""the cantilever's triangulations: the 25 mm specimen's width changed by these
shares (the rigidity is per width; the meshes differ)"""


def cantilever(
    fabric,
    direction: str,
    h: float = 0.00125,
    width: float = 0.025,
    rows: int = STRIP_ROWS,
    meshes: tuple[float, ...] = STRIP_MESHES,
) -> dict[str, Any]:
    """ASTM D1388 on the cloth model: the overhang at which the tip line is at
    41.5 degrees, against the elastica's and Peirce's overhang for the
    strip's rigidity along ``direction``.

    The strip is meshed once, for the elastica's overhang l_e, and the
    search runs on its weight, not its length: secant steps on the weight
    factor s (each a fresh Newton drape) until the tip line is at 41.5
    degrees. The elastica depends on w and l only through λ = w g l³ / G,
    so the overhang at the fabric's own weight is l_e s^(1/3). (Stretching
    one triangulation to each trial overhang, as before, compressed its
    triangles along the strip by up to 10 % and read the overhang up to 2 %
    shorter: cotton shirting's weft at 2.5 mm -6.7 % against -4.7 %; a fresh
    triangulation per trial adds mesh noise of about 1 % to the search.)

    The mesh spacing is ``h`` or finer, so that the overhang has ``rows``
    rows (0: ``h`` as given): a fixed 1.25 mm gave chiffon's 1.8 cm weft
    overhang 14 rows and read it 1.6 to 3.3 % short on four triangulations
    of one strip, 0.6 to 1.7 % at 0.625 mm (cotton's and denim's 4-6 cm, 32-44
    rows at 1.25 mm). One triangulation's error scatters by about 1 %, so the
    test runs on several (``meshes``: the specimen's width changed by those
    shares) and reads the overhang as their mean; each one's is kept."""
    ortho = _model_is_orthotropic(fabric)
    _, rigidity = _direction_table(fabric if ortho else _isotropic(fabric), direction)
    w = fabric.area_density
    c = (rigidity / (w * GRAVITY)) ** (1.0 / 3.0)
    lam_star = elastica_lambda()
    l_ref = c * lam_star ** (1.0 / 3.0)
    t0 = time.perf_counter()
    h_mesh = min(h, l_ref / rows) if rows else h
    per_mesh = [_overhang_search(fabric, direction, l_ref, h_mesh, width * (1.0 + d)) for d in meshes]
    l_sim = float(np.mean([m["overhang_m"] for m in per_mesh]))
    return {
        "fabric": fabric.name,
        "direction": direction,
        "rigidity_Nm": rigidity,
        "peirce_c_m": c,
        "h_m": h_mesh,
        "overhang_m": l_sim,
        "elastica_overhang_m": l_ref,
        "peirce_overhang_m": 2.0 * c,
        "error_vs_elastica": l_sim / l_ref - 1.0,
        "mesh_errors_vs_elastica": [m["overhang_m"] / l_ref - 1.0 for m in per_mesh],
        "mesh_widths_m": [width * (1.0 + d) for d in meshes],
        "peirce_vs_elastica": 2.0 * c / l_ref - 1.0,
        "orthotropic_model": ortho,
        "all_converged": all(t["converged"] for m in per_mesh for t in m["tries"]),
        "tries": [t for m in per_mesh for t in m["tries"]],
        "seconds": time.perf_counter() - t0,
    }


def _overhang_search(fabric, direction: str, l_ref: float, h: float, width: float) -> dict[str, Any]:
    """The overhang [m] at which one triangulation's tip line is at 41.5
    degrees, by secant steps on the weight (``cantilever``)."""
    lam_star = elastica_lambda()
    tries = []
    ss = [1.0]
    angs: list[float] = []
    for _ in range(6):
        r = cantilever_angle(fabric, direction, l_ref, h, width, weight=ss[-1])
        r["weight_scale"] = ss[-1]
        r["overhang"] = l_ref * ss[-1] ** (1.0 / 3.0)
        tries.append(r)
        angs.append(math.radians(r["angle_deg"]))
        if abs(angs[-1] - ASTM_ANGLE) < math.radians(0.02):
            break
        if len(ss) == 1:
            # the elastica's local slope: angle(s) ≈ angle_e(s λ*), a scale step
            ss.append(ss[-1] * lam_star / elastica_lambda(angs[-1]))
        else:
            s0, s1, a0, a1 = ss[-2], ss[-1], angs[-2], angs[-1]
            ss.append(s1 + (ASTM_ANGLE - a1) * (s1 - s0) / (a1 - a0))
    # the last two tries bracket or straddle 41.5 degrees: interpolate the weight there
    if len(angs) >= 2 and angs[-1] != angs[-2]:
        s0, s1 = tries[-2]["weight_scale"], tries[-1]["weight_scale"]
        s_sim = s1 + (ASTM_ANGLE - angs[-1]) * (s1 - s0) / (angs[-1] - angs[-2])
    else:
        s_sim = tries[-1]["weight_scale"]
    return {"overhang_m": l_ref * s_sim ** (1.0 / 3.0), "tries": tries}


def tensile(fabric, direction: str, strain: float = 1e-3, h: float = 0.004) -> dict[str, Any]:
    """Uniaxial tensile test along ``direction`` (see the module docstring)."""
    from couture.cloth import ClothModel, Scene

    length, width = 0.20, 0.02
    mesh, u, v = _strip_mesh(length, width, h, DIRECTIONS[direction])
    left = np.isclose(u, 0.0)
    right = np.isclose(u, length)
    mesh.pinned = np.nonzero(left | right)[0].astype(np.int32)
    x0 = mesh.x0.copy()
    x0[:, 0] *= 1.0 + strain  # the clamps moved apart; a uniform start
    mesh.x0 = x0
    model = ClothModel(mesh, fabric, Scene(gravity=False))
    res = _newton(model, x0, tol=1e-10)
    f_int = model.forces(res.x, [t for t in model.terms if t.startswith("membrane")])
    force = -float(f_int[right, 0].sum())  # what the right clamp pulls with [N]
    mid = (u > length / 3) & (u < 2 * length / 3)
    # gauge strain: the slope of x against u over the middle third
    eps = float(np.polyfit(u[mid], res.x[mid, 0], 1)[0] - 1.0)
    measured = force / width / eps
    ortho = _orthotropic(model)
    table, _ = _direction_table(fabric if ortho else _isotropic(fabric), direction)
    directional, _ = _direction_table(fabric, direction)
    return {
        "fabric": fabric.name,
        "direction": direction,
        "strain": eps,
        "force_per_width_N_per_m": force / width,
        "stiffness_N_per_m": measured,
        "table_N_per_m": table,
        "directional_table_N_per_m": directional,
        "error": measured / table - 1.0,
        "orthotropic_model": ortho,
        "converged": bool(res.converged),
        "residual": float(res.residual),
        "seconds": float(res.wall_time),
    }


@dataclass
class SupportDisc:
    """A short cylinder (centre of its top face at ``top``, radius R, height H)
    with its top edge rounded by ``rad``: the Cusick drape tester's support,
    as a signed distance field (positive outside; y up)."""

    top: np.ndarray
    radius: float
    height: float = 0.05
    rad: float = 0.003

    def phi_grad(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = np.asarray(points, float)
        c = self.top - np.array([0.0, self.height / 2, 0.0])
        dx, dy, dz = (p - c).T
        q = np.hypot(dx, dz)
        a = q - (self.radius - self.rad)
        b = np.abs(dy) - (self.height / 2 - self.rad)
        ua, ub = np.maximum(a, 0.0), np.maximum(b, 0.0)
        outer = np.hypot(ua, ub)
        inside = (a <= 0) & (b <= 0)
        phi = np.where(inside, np.maximum(a, b), outer) - self.rad
        # gradient in (radial, vertical), then to 3D
        ga = np.where(inside, (a >= b).astype(float), np.divide(ua, outer, out=np.zeros_like(ua), where=outer > 0))
        gb = np.where(inside, (b > a).astype(float), np.divide(ub, outer, out=np.zeros_like(ub), where=outer > 0))
        qs = np.where(q > 0, q, 1.0)
        g = np.column_stack([ga * dx / qs, gb * np.sign(dy + (dy == 0)), ga * dz / qs])
        return phi, g


def _disc_mesh(h: float):
    """A 30 cm disc, quality-triangulated with spacing about h [m], in the xz plane."""
    import triangle as tr

    from couture.mesh import GarmentMesh

    n_rim = int(round(2 * math.pi * DISC_RADIUS / h))
    t = np.linspace(0, 2 * math.pi, n_rim, endpoint=False)
    rim = DISC_RADIUS * np.column_stack([np.cos(t), np.sin(t)])
    segs = np.column_stack([np.arange(n_rim), (np.arange(n_rim) + 1) % n_rim])
    area = 0.5 * h * h * math.sqrt(3) / 2 * 1.2
    out = tr.triangulate({"vertices": rim, "segments": segs}, f"pq30a{area:.12f}Q")
    X = out["vertices"].astype(np.float64)
    tris = out["triangles"].astype(np.int32)
    e1 = X[tris[:, 1]] - X[tris[:, 0]]
    e2 = X[tris[:, 2]] - X[tris[:, 0]]
    flip = (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) < 0
    tris[flip] = tris[flip][:, [0, 2, 1]]
    # material (u, v) -> world (x, z); y up
    return GarmentMesh(X=X, tris=tris, x0=np.column_stack([X[:, 0], np.zeros(len(X)), X[:, 1]]))


CUSICK_H = 0.005
"""[m] the Cusick disc's mesh spacing: at 8 mm the light wovens' drape
coefficients moved by 10 points with the random start alone (chiffon 29-40 %,
charmeuse 31-42 % over five seeds), at 5 mm by about one (docs/fabrics.md,
"The light end")"""


def cusick(fabric, h: float = CUSICK_H, seed: int = 0, max_seconds: float = 300.0) -> dict[str, Any]:
    """The Cusick drape test of ``fabric`` (see the module docstring): the disc
    clamped flat within 8 cm of the centre (the tester's clamping discs), the
    support's rounded rim under the rest; started flat with a small random
    out-of-plane perturbation (seeded) so the folds can choose their number."""
    from couture.cloth import ClothModel, Scene

    mesh = _disc_mesh(h)
    r0 = np.hypot(mesh.X[:, 0], mesh.X[:, 1])
    offset = 0.001
    mesh.pinned = np.nonzero(r0 <= 0.08)[0].astype(np.int32)
    rng = np.random.default_rng(seed)
    x0 = mesh.x0.copy()
    over = np.clip((r0 - SUPPORT_RADIUS) / (DISC_RADIUS - SUPPORT_RADIUS), 0.0, None)
    # a smooth random start: modes 3..10 of the rim angle, random phases, 1 cm at the rim
    ang = np.arctan2(mesh.X[:, 1], mesh.X[:, 0])
    wave = sum(np.cos(m * ang + rng.uniform(0, 2 * np.pi)) for m in range(3, 11)) / math.sqrt(8)
    x0[:, 1] += offset + 0.01 * over**2 * wave
    mesh.x0 = x0
    support = SupportDisc(top=np.zeros(3), radius=SUPPORT_RADIUS)
    scene = Scene(body=support, contact_offset=offset, contact_smoothing=0.0005)
    model = ClothModel(mesh, fabric, scene)
    res = _newton(model, x0, tol=1e-4, max_seconds=max_seconds)
    theta, r = rim_profile(res.x, np.zeros(3), bins=90)
    rim = np.nonzero(r0 > DISC_RADIUS - 1e-9)[0]
    rim = rim[np.argsort(np.arctan2(mesh.X[rim, 1], mesh.X[rim, 0]))]
    r_rim = np.hypot(res.x[rim, 0], res.x[rim, 2])
    return {
        "fabric": fabric.name,
        # the shadow: the rim's outline seen from above (the rim hangs outermost on a Cusick drape)
        "drape_coefficient": drape_coefficient(polygon_area(res.x[rim][:, [0, 2]])),
        "drape_coefficient_binned": drape_coefficient(shadow_area(theta, np.maximum(r, SUPPORT_RADIUS))),
        "nodes": count_nodes(r_rim),
        "converged": bool(res.converged),
        "residual": float(res.residual),
        "iterations": int(res.iterations),
        "seconds": float(res.wall_time),
        "vertices": int(model.n),
        "diagnosis": res.diagnosis,
        "_x": res.x,
        "_tris": mesh.tris,
        "_theta": theta,
        "_r": r,
    }


def against_measured(row: dict[str, Any], entry) -> dict[str, Any]:
    """The library's published drape coefficient of ``entry``'s fabric beside
    the bench's (``row`` a :func:`cusick` result): {} when the library has none;
    the difference only when it was measured on the bench's 30 cm specimen
    (ISO 9073-9's 24 and 36 cm discs give other coefficients)."""
    if entry.measured_dc is None:
        return {}
    out: dict[str, Any] = {
        "measured_dc": entry.measured_dc,
        "measured_dc_diameter_m": entry.measured_dc_diameter,
        "measured_dc_source": entry.sources["measured_dc"],
    }
    if abs(entry.measured_dc_diameter - 2 * DISC_RADIUS) < 1e-6:
        out["dc_minus_measured"] = row["drape_coefficient"] - entry.measured_dc
    return out


LITERATURE_ORDER = (("chiffon", "silk_charmeuse"), ("jersey",), ("cotton_shirting",), ("denim", "canvas"))
"""Cusick DC from low to high as the literature orders them (groups: any order within)"""


def order_holds(dc: dict[str, float]) -> bool | None:
    """Whether the measured DCs keep LITERATURE_ORDER (None: a group's fabric was not run)."""
    groups = [[dc[n] for n in g if n in dc] for g in LITERATURE_ORDER]
    if any(not g for g in groups):
        return None
    return all(max(a) < min(b) for a, b in zip(groups, groups[1:], strict=False))


def plot_discs(rows: list[dict[str, Any]], path: Path) -> None:
    """Top views of every draped disc side by side, height as colour."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(rows)
    cols = min(n, 4)
    nr = int(math.ceil(n / cols))
    fig, axes = plt.subplots(nr, cols, figsize=(3.2 * cols, 3.4 * nr), squeeze=False)
    for ax in axes.ravel():
        ax.set_axis_off()
    for ax, row in zip(axes.ravel(), rows, strict=False):
        x = row["_x"]
        ax.tripcolor(x[:, 0], x[:, 2], row["_tris"], x[:, 1], shading="gouraud", cmap="viridis", vmin=-0.07, vmax=0.0)
        ax.add_patch(plt.Circle((0, 0), SUPPORT_RADIUS, fill=False, ls="--", lw=0.6, color="w"))
        ax.add_patch(plt.Circle((0, 0), DISC_RADIUS, fill=False, ls=":", lw=0.6, color="k"))
        ax.set_xlim(-0.16, 0.16)
        ax.set_ylim(-0.16, 0.16)
        ax.set_aspect("equal")
        ax.set_title(f"{row['fabric']}\nDC {100 * row['drape_coefficient']:.0f} %, {row['nodes']} nodes", fontsize=9)
    fig.suptitle("Cusick drape test (top view, colour: height, 0 to -7 cm)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _warmup() -> float:
    """[s] numba compilation (or cache load) of the kernels the tests use, on tiny scenes."""
    from couture import fabrics

    t = time.perf_counter()
    f = fabrics.get("cotton_shirting")
    cantilever_angle(f, "warp", 0.03, 0.01)
    cusick(f, h=0.04, max_seconds=10)
    return time.perf_counter() - t


def main(argv: list[str] | None = None) -> int:
    from couture import fabrics

    ap = argparse.ArgumentParser(prog="couture bench fabric", description=__doc__.split("\n\n")[0])
    ap.add_argument("--fabrics", nargs="*", default=None, help="library names (default: every fabric)")
    ap.add_argument(
        "--tests", nargs="*", default=["cantilever", "tensile", "cusick"], choices=["cantilever", "tensile", "cusick"]
    )
    ap.add_argument(
        "--cantilever-fabrics",
        nargs="*",
        default=["chiffon", "cotton_shirting", "denim"],
        help="fabrics of the cantilever and tensile tests (default: three)",
    )
    ap.add_argument(
        "--h-strip",
        type=float,
        default=0.00125,
        help=f"[m] strip mesh spacing at most (default 1.25 mm; finer where the overhang has fewer than {STRIP_ROWS} "
        "rows; also run at twice it)",
    )
    ap.add_argument(
        "--h-disc",
        type=float,
        default=CUSICK_H,
        help="[m] Cusick disc mesh spacing (default 5 mm; 8 mm leaves the light wovens' folds to chance)",
    )
    ap.add_argument(
        "--seed", type=int, default=0, help="seed of the Cusick discs' random start (default 0; the folds choose by it)"
    )
    ap.add_argument(
        "--max-seconds",
        type=float,
        default=300.0,
        help="[s] Newton's wall-clock limit per Cusick disc (default 300; finer discs need more)",
    )
    ap.add_argument(
        "--isotropic",
        action="store_true",
        help="cantilever: also each fabric taken isotropic (its bend_stiffness; a warp strip), as docs/fabrics.md's "
        "last column",
    )
    ap.add_argument("--quick", action="store_true", help="one fabric, coarse meshes, warp and bias only (a test)")
    ap.add_argument(
        "--library",
        type=Path,
        default=None,
        metavar="TOML",
        help="a fabric library file in the shipped one's format (default: the shipped library), "
        "e.g. published fabrics to try before they enter it",
    )
    ap.add_argument(
        "--out", type=Path, default=RESULTS_DIR / "fabric", metavar="DIR", help="results folder (default: %(default)s)"
    )
    a = ap.parse_args(argv)
    library = fabrics.load(a.library) if a.library is not None else {n: fabrics.entry(n) for n in fabrics.names()}

    def entry(name: str) -> fabrics.FabricEntry:
        if name not in library:
            raise SystemExit(f"unknown fabric {name!r}; the library has {sorted(library)}")
        return library[name]

    def get(name: str):
        return msgspec.structs.replace(entry(name).fabric)

    names = a.fabrics if a.fabrics is not None else list(library)
    strip_names = a.cantilever_fabrics
    directions = list(DIRECTIONS)
    h_strip, h_disc = a.h_strip, a.h_disc
    if a.quick:
        names = names[:1] if a.fabrics is not None else ["cotton_shirting"]
        strip_names = names
        directions = ["warp", "bias"]  # the cantilever along the warp only (below)
        h_strip, h_disc = max(h_strip, 0.004), max(h_disc, 0.015)
    strip_tests = {"cantilever", "tensile"} & set(a.tests)
    for n in set(names) | (set(strip_names) if strip_tests else set()):
        entry(n)  # an unknown name fails before any work
    compile_s = _warmup()
    print(f"compile/warm-up {compile_s:.1f} s", flush=True)
    t_all = time.perf_counter()
    lam_star = elastica_lambda()
    results: dict[str, Any] = {
        "bench": "fabric",
        "commit": source_commit(),
        "compile_s": compile_s,
        "elastica_overhang_per_c": lam_star ** (1.0 / 3.0),
        "peirce_overhang_per_c": peirce_overhang_ratio(),
        "h_strip_m": h_strip,
        "h_disc_m": h_disc,
        "library": str(a.library) if a.library is not None else "shipped",
        "seed": a.seed,
        "cusick_max_seconds": a.max_seconds,
    }
    if "cantilever" in a.tests:
        rows = []
        runs = [(n, d, False) for n in strip_names for d in (directions[:1] if a.quick else directions)]
        if a.isotropic:
            runs += [(n, "warp", True) for n in strip_names]
        for n, d, iso in runs:
            fab = _isotropic(get(n)) if iso else get(n)
            r = cantilever(fab, d, h=h_strip, meshes=STRIP_MESHES[:1] if a.quick else STRIP_MESHES)
            r["model"] = "isotropic" if iso else "fabric"
            if not a.quick:
                # the same test on meshes twice as coarse: how the error falls with h
                r["coarse_h_m"] = 2 * r["h_m"]
                r["coarse_error_vs_elastica"] = cantilever(fab, d, h=2 * r["h_m"], rows=0)["error_vs_elastica"]
            rows.append(r)
            print(
                f"cantilever {n + (' (isotropic)' if iso else ''):28s} {d:5s} overhang {100 * r['overhang_m']:6.2f} cm, elastica "
                f"{100 * r['elastica_overhang_m']:6.2f} cm ({100 * r['error_vs_elastica']:+.2f} %; h = "
                f"{1000 * r['h_m']:.2f} mm, meshes "
                + ", ".join(f"{100 * e:+.2f}" for e in r["mesh_errors_vs_elastica"])
                + " %), Peirce 2c "
                f"{100 * r['peirce_overhang_m']:6.2f} cm; "
                + (
                    f"at h = {1000 * r['coarse_h_m']:.1f} mm {100 * r['coarse_error_vs_elastica']:+.2f} %; "
                    if "coarse_h_m" in r
                    else ""
                )
                + f"{len(r['tries'])} drapes, {r['seconds']:.1f} s",
                flush=True,
            )
        results["cantilever"] = rows
        results["cantilever_worst_error"] = max(abs(r["error_vs_elastica"]) for r in rows)
    if "tensile" in a.tests:
        rows = []
        for n in strip_names:
            for d in directions:
                r = tensile(get(n), d, h=max(h_strip, 0.004))
                rows.append(r)
                print(
                    f"tensile    {n:16s} {d:5s} {r['stiffness_N_per_m']:8.1f} N/m vs table {r['table_N_per_m']:8.1f} "
                    f"({100 * r['error']:+.3f} %){'' if r['orthotropic_model'] else ' [isotropic model; directional table ' + format(r['directional_table_N_per_m'], '.1f') + ']'}",
                    flush=True,
                )
        results["tensile"] = rows
        results["tensile_worst_error"] = max(abs(r["error"]) for r in rows)
    if "cusick" in a.tests:
        rows = []
        for k, n in enumerate(names, 1):
            r = cusick(get(n), h=h_disc, seed=a.seed, max_seconds=a.max_seconds)
            r.update(against_measured(r, entry(n)))
            rows.append(r)
            print(
                f"cusick [{k}/{len(names)}] {n:16s} DC {100 * r['drape_coefficient']:5.1f} %  nodes {r['nodes']:2d}  "
                f"{'converged' if r['converged'] else 'NOT converged ' + r['diagnosis']} (res {r['residual']:.1e}, "
                f"{r['iterations']} its, {r['seconds']:.1f} s, {r['vertices']} vertices)",
                flush=True,
            )
            if "measured_dc" in r:
                print(
                    f"       measured {100 * r['measured_dc']:5.1f} % on a {100 * r['measured_dc_diameter_m']:.0f} cm "
                    + (
                        f"specimen: bench {100 * r['dc_minus_measured']:+.1f} points"
                        if "dc_minus_measured" in r
                        else "specimen (the bench's is 30 cm: not compared)"
                    )
                    + f" ({r['measured_dc_source']})",
                    flush=True,
                )
        a.out.mkdir(parents=True, exist_ok=True)
        png = a.out / "cusick.png"
        plot_discs(rows, png)
        dc = {r["fabric"]: r["drape_coefficient"] for r in rows}
        results["cusick"] = [{k: v for k, v in r.items() if not k.startswith("_")} for r in rows]
        results["cusick_order_holds"] = order_holds(dc)
        results["cusick_png"] = png.name
        print(
            f"literature order (chiffon, charmeuse < jersey < cotton < denim, canvas): {results['cusick_order_holds']}"
        )
    results["total_s"] = time.perf_counter() - t_all
    path = write_results(a.out, "fabric", results)
    print(f"wrote {path} ({results['total_s']:.0f} s after a {compile_s:.0f} s warm-up)")
    return 0

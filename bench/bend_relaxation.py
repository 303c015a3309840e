"""``couture bench bend_relaxation``: how much of an imposed cylindrical bend's
bending energy a sheet keeps in equilibrium, per mesh kind (the measurement
``BEND_CONSTANT`` is calibrated on; ``couture.cloth.model``, docs/fabrics.md).

A flat sheet is bent onto a cylinder of radius R along a direction d (every
vertex on it: the imposed bend), then held there on a border band
(``--band`` mean edge lengths wide: position and slope, so the continuum's
equilibrium is the cylinder itself) and its interior relaxed by Newton (``couture.cloth.testing.newton``, gravity off,
the fabric's own membrane): the relaxed bend. Both energies against the
continuum (k/2) A / R², A the area the hinges cover (Σ (A0 + A1) / 3), over
every hinge and over the interior window (hinges at least ``--window`` of
the sheet's half-size from its border, clear of the held border's boundary
layer), and relaxed over imposed. Mesh kinds: triangle-library quality
sheets (``grid_sheet``, the tests' and benches' meshes) at several spacings,
the cantilever bench's strip mesh generator (``bench.fabric._strip_mesh``) on
a square, a rectangle panel meshed by the remesher (``mesh_pattern``, as a
garment's panels are) at several spacings, the default skirt's largest gore
at the fine and coarse levels, and for reference a structured right-triangle grid and an
equilateral lattice (never used for garments).

Energies are reported at c = ``BEND_IMPOSED_FIT`` (0.29), whatever
``BEND_CONSTANT`` is: the window's relaxed over continuum, averaged over the
mesh kinds garments and benches use, is ``BEND_RELAXED_RESPONSE``.

Writes ``bend_relaxation.json`` to ``--out`` (default ``bench/results/``).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from bench import add_out_arg, source_commit, write_results

RADII = (0.02, 0.1, 0.6)
"""[m] cylinder radii"""
ANGLES_DEG = (0.0, 30.0, 45.0, 90.0)
"""bend directions [deg] from the sheet's x axis"""
CALIBRATION_MESHES = {
    "grid_sheet": ("h5mm", "h2.5mm", "h1.25mm"),
    "strip_mesh": ("h2.5mm", "h1.25mm"),
    "remesher_panel": ("h8mm", "h5mm", "h3mm"),
    "skirt_gore": ("fine",),
}
"""the meshes ``BEND_RELAXED_RESPONSE`` averages (per kind, then over kinds):
the tests' and benches' sheets and strips, the remesher's panels at garment
sizes and a garment's fine level (its coarse gore at 22 mm leaves only a
few edges free between the held bands: not a measurement of the mesh)"""


def cylinder_map(X: np.ndarray, R: float, angle: float, center: np.ndarray) -> np.ndarray:
    """The flat sheet X (n, 2) [m] wrapped isometrically onto a cylinder of
    radius R [m] whose generators are perpendicular to the direction at
    ``angle`` [rad]; (n, 3) [m]."""
    d = np.array([math.cos(angle), math.sin(angle)])
    a = np.array([-math.sin(angle), math.cos(angle)])
    s = (X - center) @ d
    t = (X - center) @ a
    x = np.zeros((len(X), 3))
    x[:, :2] = np.outer(R * np.sin(s / R), d) + np.outer(t, a)
    x[:, 2] = R * (1.0 - np.cos(s / R))
    return x


def border_vertices(tris: np.ndarray) -> np.ndarray:
    """Vertices on edges that belong to one triangle only, sorted."""
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    uniq, cnt = np.unique(e, axis=0, return_counts=True)
    return np.unique(uniq[cnt == 1].ravel())


def hinge_energies(model, x: np.ndarray) -> np.ndarray:
    """(e,) [J] each hinge's (k_b/2) c 3/(A0+A1) |K x|² at c = ``BEND_IMPOSED_FIT``
    (no clamp factor: the window used is clear of any clamp line)."""
    from couture.cloth.model import BEND_IMPOSED_FIT, bending_weights

    Kw, fac = bending_weights(model.X, model.bend_stencils)
    kx = np.einsum("ej,ejk->ek", Kw, x[model.bend_stencils])
    return 0.5 * model.bend_stiffness * BEND_IMPOSED_FIT * fac * np.sum(kx * kx, axis=1)


def measure(mesh, fabric, R: float, angle: float, window: float, band: float) -> dict[str, Any]:
    """One sheet, one bend: imposed and relaxed energies against the continuum;
    held: the vertices within ``band`` [m] of the border (0: the border alone)."""
    from scipy.spatial import cKDTree

    from couture.cloth import ClothModel, Scene
    from couture.cloth.model import bending_weights
    from couture.cloth.testing import newton

    X = mesh.X
    center = 0.5 * (X.min(axis=0) + X.max(axis=0))
    border = border_vertices(mesh.tris)
    near = cKDTree(X[border]).query(X)[0] <= band
    mesh.pinned = np.nonzero(near)[0].astype(np.int32)
    model = ClothModel(mesh, fabric, Scene(gravity=False, seams=False))
    x_imp = cylinder_map(X, R, angle, center)
    t0 = time.perf_counter()
    x_rel, hist = newton(model, x_imp, tol=1e-9, max_iters=60)
    seconds = time.perf_counter() - t0
    _, fac = bending_weights(model.X, model.bend_stencils)
    area = 1.0 / fac  # Σ (A0 + A1) / 3 per hinge
    mid = 0.5 * (X[model.bend_stencils[:, 0]] + X[model.bend_stencils[:, 1]])
    dist = cKDTree(X[border]).query(mid)[0]
    half = 0.5 * float(min(np.ptp(X[:, 0]), np.ptp(X[:, 1])))
    inner = dist >= window * half
    k = model.bend_stiffness
    e_imp, e_rel = hinge_energies(model, x_imp), hinge_energies(model, x_rel)
    cont = 0.5 * k * area / R**2
    return {
        "R_m": R,
        "angle_deg": math.degrees(angle),
        "imposed_over_continuum": float(e_imp.sum() / cont.sum()),
        "relaxed_over_continuum": float(e_rel.sum() / cont.sum()),
        "relaxed_over_imposed": float(e_rel.sum() / e_imp.sum()),
        "window_imposed_over_continuum": float(e_imp[inner].sum() / cont[inner].sum()),
        "window_relaxed_over_continuum": float(e_rel[inner].sum() / cont[inner].sum()),
        "window_relaxed_over_imposed": float(e_rel[inner].sum() / e_imp[inner].sum()),
        "window_hinges": int(inner.sum()),
        "held_vertices": int(near.sum()),
        "residual": float(hist[-1]),
        "newton_its": len(hist) - 1,
        "max_move_m": float(np.abs(x_rel - x_imp).max()),
        "seconds": seconds,
    }


def edge_length(mesh) -> float:
    """[m] mean edge length."""
    t = mesh.tris
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    return float(np.linalg.norm(mesh.X[e[:, 0]] - mesh.X[e[:, 1]], axis=1).mean())


def structured_grid(size: float, n: int, equilateral: bool):
    """Reference lattices over a square of side ``size`` [m]: right triangles
    (one diagonal per cell) or equilateral triangles (rows offset by half a cell)."""
    from couture.mesh import GarmentMesh

    if equilateral:
        h = size / (n - 1)
        rows = int(round(size / (h * math.sqrt(3) / 2))) + 1
        pts: list[tuple[float, float]] = []
        ids = np.full((rows, n), -1)
        for r in range(rows):
            for c in range(n):
                ids[r, c] = len(pts)
                pts.append((c * h + (0.5 * h if r % 2 else 0.0), r * h * math.sqrt(3) / 2))
        tris = []
        for r in range(rows - 1):
            for c in range(n - 1):
                a, b, cc, d = ids[r, c], ids[r, c + 1], ids[r + 1, c], ids[r + 1, c + 1]
                if r % 2 == 0:
                    tris += [(a, b, cc), (b, d, cc)]
                else:
                    tris += [(a, d, cc), (a, b, d)]
        return GarmentMesh(X=np.array(pts, np.float64), tris=np.array(tris, np.int32))
    g = np.linspace(0.0, size, n)
    X = np.array([(x, y) for y in g for x in g], np.float64)
    tris = []
    for r in range(n - 1):
        for c in range(n - 1):
            a, b, cc, d = r * n + c, r * n + c + 1, (r + 1) * n + c, (r + 1) * n + c + 1
            tris += [(a, b, d), (a, d, cc)]
    return GarmentMesh(X=X, tris=np.array(tris, np.int32))


def remesher_panel(size: float, h: float):
    """A ``size`` x ``size`` [m] rectangle panel meshed by ``mesh_pattern`` at spacing about h [m]."""
    from couture.pattern.drafted import DraftedPattern
    from couture.remesh import mesh_pattern
    from couture.remesh.fixtures import rectangle_panel
    from couture.remesh.meshing import target_spacing

    drafted = DraftedPattern(panels=[rectangle_panel("square", size, size, per_edge=8)], seams=[])
    # target_spacing(A, N) = h  <=>  N = 2 A / (√3 h²)
    n = int(round(2.0 * size * size / (math.sqrt(3.0) * h * h)))
    assert abs(target_spacing(size * size, n) - h) < 0.05 * h
    return mesh_pattern(drafted, n, level="fine").mesh


def skirt_gore(vertices: int):
    """The default skirt's largest panel from the remesher at ``vertices`` for the whole garment."""
    from couture.mesh import GarmentMesh
    from couture.pattern.io import load_design
    from couture.pattern.validate import validate
    from couture.remesh import mesh_pattern

    root = Path(__file__).resolve().parents[1]
    design = load_design(root / "couture" / "pattern" / "examples" / "default_skirt.json")
    mesh = mesh_pattern(validate(design), vertices, level="fine").mesh
    panel = int(np.argmax(np.bincount(mesh.tri_panel)))
    keep = mesh.tris[mesh.tri_panel == panel]
    used = np.unique(keep)
    remap = np.full(len(mesh.X), -1)
    remap[used] = np.arange(len(used))
    return GarmentMesh(X=mesh.X[used].copy(), tris=remap[keep].astype(np.int32)), mesh.panel_names[panel]


def main(argv: list[str] | None = None) -> int:
    from bench.fabric import _isotropic, _strip_mesh
    from couture import fabrics
    from couture.cloth.model import BEND_CONSTANT, BEND_IMPOSED_FIT
    from couture.mesh import grid_sheet

    ap = argparse.ArgumentParser(prog="couture bench bend_relaxation", description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--fabric", default="cotton_shirting", help="library fabric, taken isotropic (default: %(default)s)"
    )
    ap.add_argument("--size", type=float, default=0.08, help="[m] side of the square sheets (default %(default)s)")
    ap.add_argument(
        "--window", type=float, default=0.4, help="interior window: hinges this share of the half-size from the border"
    )
    ap.add_argument(
        "--band",
        type=float,
        default=3.0,
        help="held band: vertices within this many mean edge lengths of the border (0: the border alone, "
        "which leaves the slope free there, so the plate's boundary layer relaxes too); default %(default)s",
    )
    ap.add_argument("--stretch-scale", type=float, default=1.0, help="the membrane stiffness times this (default 1)")
    ap.add_argument("--kinds", nargs="*", default=None, help="mesh kinds to run (default: all)")
    ap.add_argument("--quick", action="store_true", help="two meshes, one radius, two directions (a test)")
    add_out_arg(ap)
    a = ap.parse_args(argv)
    fabric = _isotropic(fabrics.get(a.fabric))
    fabric = msgspec.structs.replace(fabric, stretch_stiffness=fabric.stretch_stiffness * a.stretch_scale)
    L = a.size
    kinds: list[tuple[str, str, Any]] = []  # (kind, label, builder)

    def side(h: float) -> float:
        return max(L, 40.0 * h)  # at least 40 edges across: the window holds enough hinges

    def sheet(h: float):
        n = int(round(side(h) / h)) + 1
        return grid_sheet(side(h), side(h), n, n)

    for h in (0.005, 0.0025, 0.00125):
        kinds.append(("grid_sheet", f"h{1000 * h:g}mm", lambda h=h: sheet(h)))
    for h in (0.0025, 0.00125):
        kinds.append(("strip_mesh", f"h{1000 * h:g}mm", lambda h=h: _strip_mesh(L, L, h, 0.0)[0]))
    for h in (0.008, 0.005, 0.003):
        kinds.append(("remesher_panel", f"h{1000 * h:g}mm", lambda h=h: remesher_panel(side(h), h)))
    kinds.append(("skirt_gore", "fine", lambda: skirt_gore(10000)[0]))
    kinds.append(("skirt_gore", "coarse", lambda: skirt_gore(1600)[0]))
    kinds.append(("right_grid", "h2.5mm", lambda: structured_grid(L, int(round(L / 0.0025)) + 1, False)))
    kinds.append(("equilateral", "h2.5mm", lambda: structured_grid(L, int(round(L / 0.0025)) + 1, True)))
    radii: tuple[float, ...] = RADII
    angles: tuple[float, ...] = ANGLES_DEG
    if a.kinds is not None:
        kinds = [k for k in kinds if k[0] in a.kinds]
    if a.quick:
        kinds = [k for k in kinds if (k[0], k[1]) in {("grid_sheet", "h5mm"), ("remesher_panel", "h8mm")}]
        radii, angles = (0.1,), (0.0, 45.0)
    t_all = time.perf_counter()
    rows = []
    for kind, label, build in kinds:
        mesh = build()
        h = edge_length(mesh)
        span = float(min(np.ptp(mesh.X[:, 0]), np.ptp(mesh.X[:, 1])))
        for R in radii:
            if kind == "skirt_gore" and R < 0.1:
                continue  # a 0.5 m gore on a 2 cm cylinder wraps several turns
            for ang in angles:
                r = measure(mesh, fabric, R, math.radians(ang), a.window, a.band * h)
                r.update(kind=kind, label=label, h_m=h, vertices=len(mesh.X), span_m=span)
                rows.append(r)
                print(
                    f"{kind:15s} {label:8s} h {1000 * h:5.2f} mm n {len(mesh.X):6d} R {100 * R:4.0f} cm "
                    f"{ang:4.0f} deg: imposed {r['imposed_over_continuum']:.3f} relaxed {r['relaxed_over_continuum']:.3f}"
                    f" ratio {r['relaxed_over_imposed']:.3f} | window imposed "
                    f"{r['window_imposed_over_continuum']:.3f} relaxed {r['window_relaxed_over_continuum']:.3f} ratio "
                    f"{r['window_relaxed_over_imposed']:.3f} ({r['newton_its']} its, res {r['residual']:.1e}, "
                    f"{r['seconds']:.1f} s)",
                    flush=True,
                )
    summary: dict[str, Any] = {}
    for kind in dict.fromkeys(r["kind"] for r in rows):
        sel = [r for r in rows if r["kind"] == kind]
        summary[kind] = {
            key: {
                "mean": float(np.mean([r[key] for r in sel])),
                "min": float(min(r[key] for r in sel)),
                "max": float(max(r[key] for r in sel)),
            }
            for key in (
                "relaxed_over_imposed",
                "window_relaxed_over_imposed",
                "imposed_over_continuum",
                "window_imposed_over_continuum",
                "relaxed_over_continuum",
                "window_relaxed_over_continuum",
            )
        }
        s = summary[kind]
        print(
            f"{kind:15s} window relaxed/imposed {s['window_relaxed_over_imposed']['mean']:.4f} "
            f"[{s['window_relaxed_over_imposed']['min']:.4f}, {s['window_relaxed_over_imposed']['max']:.4f}], "
            f"relaxed/continuum {s['window_relaxed_over_continuum']['mean']:.4f}, imposed/continuum "
            f"{s['window_imposed_over_continuum']['mean']:.4f}",
            flush=True,
        )
    # per mesh (kind and size), the bends resolved (R >= 5 h): the calibration averages
    # each kind's meshes, then the kinds that garments (fine level) and benches use
    per_mesh: dict[str, Any] = {}
    for key in dict.fromkeys(f"{r['kind']} {r['label']}" for r in rows):
        sel = [r for r in rows if f"{r['kind']} {r['label']}" == key and r["R_m"] >= 5 * r["h_m"]]
        vals = [r["window_relaxed_over_continuum"] for r in sel]
        per_mesh[key] = {
            "h_m": sel[0]["h_m"] if sel else None,
            "window_relaxed_over_continuum": float(np.mean(vals)) if vals else None,
            "min": min(vals) if vals else None,
            "max": max(vals) if vals else None,
            "bends": len(vals),
        }
    kind_means = {}
    for kind, labels in CALIBRATION_MESHES.items():
        vals = [
            per_mesh[f"{kind} {lb}"]["window_relaxed_over_continuum"] for lb in labels if f"{kind} {lb}" in per_mesh
        ]
        if vals:
            kind_means[kind] = float(np.mean(vals))
    calibration = float(np.mean(list(kind_means.values()))) if kind_means else None
    if calibration is not None:
        print(f"calibration: mean over {kind_means} = {calibration:.4f} (BEND_RELAXED_RESPONSE)")
    results = {
        "bench": "bend_relaxation",
        "commit": source_commit(),
        "fabric": a.fabric,
        "bend_constant": BEND_CONSTANT,
        "energies_at_c": BEND_IMPOSED_FIT,
        "size_m": L,
        "window": a.window,
        "band_edges": a.band,
        "stretch_scale": a.stretch_scale,
        "radii_m": list(radii),
        "angles_deg": list(angles),
        "rows": rows,
        "summary": summary,
        "per_mesh_resolved": per_mesh,
        "calibration_kinds": kind_means,
        "relaxed_response": calibration,
        "total_s": time.perf_counter() - t_all,
    }
    path = write_results(a.out, "bend_relaxation", results)
    print(f"wrote {path} ({results['total_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""``couture bench grading``: one garment draped on every graded body, and how it fits each.

The design (``--design``, default the skirt example) keeps its pattern; only
``Design.body.name`` changes, so a larger body wears the same garment tighter.
Each size is draped as the nodes drape it (``RemeshService`` ->
``SolveService``: placement on that body's sections, friction from the first
iteration on the coarse level; ``--level fine`` goes on cascadically to the
fine mesh). Per size:

- strain map: the largest principal stretch of each triangle minus 1
  (singular value of the deformation gradient against the pattern);
- contact-pressure map: each vertex's contact normal force (the model's
  penalty law in its 1 cm contact layer) over its share of the draped area
  [Pa], per triangle the mean of its vertices;
- fit: ease at the body's bust, waist and hip heights (``couture.bodies``
  landmarks): the garment's girth there (convex hull perimeter of its
  cross-section, a tape round the outside, as ``couture.bodies.measure``
  measures the body) minus the body's girth. A garment resting on the body
  sits in the contact layer, so a skin-tight garment reads about
  2 pi x offset (6 cm) of ease; None where the garment does not go round the
  body at that height (a skirt at the bust, or a skirt slid below the waist).
  Like the body's girth, the garment's is the torso's: where the body's
  section at that height has other loops (the arms at the bust), only the
  cloth nearer the torso than the arms counts, and it must go round the torso
  by itself (a sleeve round the arm is no bust ease; before, the hull went
  round the sleeves and a set-in shirt read 44-49 cm of bust ease; its
  armholes open below the bust line, so it now reads none there).

Prints a progress line per size and the fit table, writes ``grading.json`` and
``grading.png`` (one column per size; rows: strain, pressure; front view) to
``--out``.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from bench import add_out_arg, source_commit, write_results
from couture.pattern.io import EXAMPLES

DEFAULT_DESIGN = EXAMPLES / "default_skirt.json"
LANDMARKS = ("bust", "waist", "hip")
GAP_DEG = 20.0
"""[deg] widest uncovered arc, seen from the body's centre, of a garment section that counts as going round"""


@dataclass
class SizeFit:
    body: str
    vertices: int
    level: str
    body_girth: dict[str, float]
    """[m] the body's bust, waist and hip girths"""
    landmark_y: dict[str, float]
    """[m] world heights of those girths"""
    garment_girth: dict[str, float | None]
    """[m] the draped garment's girth at each landmark height; None where it does not reach"""
    ease: dict[str, float | None]
    """[m] garment girth - body girth"""
    top_y: float
    """[m] world height of the garment's highest point (every body stands on the same floor)"""
    strain_max: float
    """largest principal stretch - 1 over the triangles"""
    strain_p95: float
    pressure_mean: float
    """[Pa] area-weighted mean over the vertices in contact"""
    pressure_max: float
    """[Pa]"""
    contact_fraction: float
    """share of the draped area in contact"""
    converged: bool
    residual: float
    iterations: int
    seconds: float
    diagnosis: str = ""
    strain_max_panel: str = ""
    """the panel of the most stretched triangle"""
    clearance: float = float("nan")
    """[m] the draped garment's least distance to the body (negative: inside)"""
    maps: dict = field(default_factory=dict, repr=False)
    """per triangle: 'strain', 'pressure' (not written to JSON)"""


def principal_stretches(X: np.ndarray, tris: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(m, 2) singular values of each triangle's deformation gradient, largest first.

    F = Ds Dm^-1 maps the triangle's pattern edges (2D) to its draped edges (3D)."""
    Dm = np.stack([X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 0]]], axis=-1)  # (m, 2, 2)
    Ds = np.stack([x[tris[:, 1]] - x[tris[:, 0]], x[tris[:, 2]] - x[tris[:, 0]]], axis=-1)  # (m, 3, 2)
    F = Ds @ np.linalg.inv(Dm)
    return np.linalg.svd(F, compute_uv=False)


def vertex_areas(x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Each vertex's third of the draped area of its triangles [m^2]."""
    a = 0.5 * np.linalg.norm(np.cross(x[tris[:, 1]] - x[tris[:, 0]], x[tris[:, 2]] - x[tris[:, 0]]), axis=1)
    out = np.zeros(len(x))
    np.add.at(out, tris.reshape(-1), np.repeat(a / 3.0, 3))
    return out


def contact_pressure(model, x: np.ndarray) -> np.ndarray:
    """Per vertex contact normal force over its draped area [Pa] (0 out of contact)."""
    if model.body is None:
        return np.zeros(len(x))
    phi = model.body.phi_grad(x)[0]
    fn = model.contact_normal_force(model.contact_offset - phi)
    area = vertex_areas(x, model.tris)
    return np.divide(fn, area, out=np.zeros_like(fn), where=area > 0)


def section_segments(x: np.ndarray, tris: np.ndarray, y: float) -> np.ndarray:
    """(k, 2, 2): the garment's section by the plane at height y, one (x, z)
    segment per triangle it crosses."""
    h = x[:, 1] - y
    h = np.where(h == 0.0, 1e-12, h)  # a vertex on the plane counts as above
    segs = []
    ends = []
    for i, j in ((0, 1), (1, 2), (2, 0)):
        a, b = tris[:, i], tris[:, j]
        cross = (h[a] > 0) != (h[b] > 0)
        t = np.where(cross, h[a] / np.where(cross, h[a] - h[b], 1.0), 0.0)
        ends.append((cross, x[a] + t[:, None] * (x[b] - x[a])))
    n_cross = sum(c.astype(int) for c, _ in ends)
    for f in np.flatnonzero(n_cross == 2):
        segs.append([p[f, [0, 2]] for c, p in ends if c[f]])
    return np.array(segs).reshape(-1, 2, 2)


def uncovered_angle(segs: np.ndarray, centre: np.ndarray) -> float:
    """[rad] the widest arc, seen from ``centre``, that no segment covers."""
    a = np.arctan2(segs[:, :, 1] - centre[1], segs[:, :, 0] - centre[0])  # (k, 2)
    lo, d = a[:, 0], (a[:, 1] - a[:, 0] + np.pi) % (2 * np.pi) - np.pi  # each segment the short way round
    lo = np.where(d < 0, lo + d, lo) % (2 * np.pi)
    hi = lo + np.abs(d)
    order = np.argsort(lo)
    lo, hi = lo[order], hi[order]
    widest, reach = 0.0, hi[0]
    for s0, s1 in zip(lo[1:], hi[1:], strict=True):
        widest = max(widest, s0 - reach)
        reach = max(reach, s1)
    return float(max(widest, lo[0] + 2 * np.pi - reach))


def nearer_torso(points: np.ndarray, torso: np.ndarray, others: list[np.ndarray]) -> np.ndarray:
    """(n,) bool: which points (n, 2) (x, z) [m] lie nearer the torso section's
    points (k, 2) than any other loop of the body's section there (the arms)."""
    from scipy.spatial import cKDTree

    keep = np.ones(len(points), bool)
    if not len(others) or not len(points):
        return keep
    d_t, _ = cKDTree(torso).query(points)
    d_o, _ = cKDTree(np.vstack(others)).query(points)
    return d_t <= d_o


def girth_at(
    x: np.ndarray,
    tris: np.ndarray,
    y: float,
    centre: np.ndarray | None = None,
    max_gap_deg: float = GAP_DEG,
    section: tuple[np.ndarray, list[np.ndarray]] | None = None,
) -> float | None:
    """Convex hull perimeter [m] of the garment's section at height y (every
    piece together: a tape round the outside); None where the garment does not
    reach y, or (given the body's ``centre`` (x, z) there) does not go round it:
    its section leaves an arc wider than ``max_gap_deg`` uncovered, seen from the
    centre (a hem or a waist edge that is not level cuts an arc, whose hull is no
    girth; open seams of a few degrees are bridged, as a tape bridges them).
    ``section``: the body's torso loop and other loops at y (``body_sections``):
    only the cloth nearer the torso than the arms counts (``nearer_torso``),
    and it must go round the torso by itself (a sleeve is no bust ease)."""
    from scipy.spatial import ConvexHull, QhullError

    segs = section_segments(x, tris, y)
    if section is not None and len(segs):
        segs = segs[nearer_torso(segs.mean(axis=1), *section)]
    if len(segs) < 2:
        return None
    if centre is not None and np.degrees(uncovered_angle(segs, centre)) > max_gap_deg:
        return None
    Q = segs.reshape(-1, 2)
    try:
        v = ConvexHull(Q).vertices
    except QhullError:
        return None
    return float(np.linalg.norm(Q[v] - np.roll(Q[v], 1, axis=0), axis=1).sum())


def body_sections(body: str, heights: dict[str, float]) -> dict[str, tuple[np.ndarray, list[np.ndarray]] | None]:
    """Per landmark height, the body's torso section (its loop's points (k, 2),
    (x, z) [m]) and each other loop there (the arms); None where the body has
    no torso section."""
    from couture.bodies.measure import Slicer
    from couture.cloth.body import load_mannequin_mesh

    s = Slicer(*load_mannequin_mesh(body))
    out: dict[str, tuple[np.ndarray, list[np.ndarray]] | None] = {}
    for k, y in heights.items():
        sec = s.torso(y)
        if sec is None:
            out[k] = None
            continue
        loops = [P[:, [0, 2]] for _, P in s.loops(y)]
        # the torso's loop: the one its hull's points came from
        ti = int(np.argmin([np.min(np.linalg.norm(Q[:, None] - sec.points[None, :1], axis=2)) for Q in loops]))
        rest = [Q for i, Q in enumerate(loops) if i != ti]
        out[k] = (loops[ti], rest)
    return out


def body_centres(body: str, heights: dict[str, float]) -> dict[str, np.ndarray | None]:
    """Centre (x, z) [m] of the body's torso section at each landmark height."""
    from couture.bodies.measure import Slicer
    from couture.cloth.body import load_mannequin_mesh

    s = Slicer(*load_mannequin_mesh(body))
    out: dict[str, np.ndarray | None] = {}
    for k, y in heights.items():
        sec = s.torso(y)
        out[k] = None if sec is None else sec.points.mean(axis=0)
    return out


def body_landmarks(name: str) -> tuple[dict[str, float], dict[str, float]]:
    """(girths, heights) [m] of a body's bust, waist and hip (couture.bodies)."""
    from couture import bodies

    row = next(r for r in bodies.table() if r["name"] == name)
    m = row["measured"]
    return {k: float(m[f"{k}_girth"]) for k in LANDMARKS}, {k: float(m[f"{k}_y"]) for k in LANDMARKS}


def drape_on(
    design,
    body: str,
    level: str = "coarse",
    method: str = "newton",
    max_seconds: float = 60.0,
    solver_options: dict | None = None,
):
    """Drape ``design`` on ``body`` the way the nodes do; returns (result, model, mesh).
    ``solver_options`` go to the solver's constructor (``couture.solvers.get_solver``;
    e.g. Newton's ``max_step``), None: the nodes' solver as it is."""
    import msgspec

    from couture import bodies
    from couture.remesh.service import RemeshService
    from couture.solvers.service import SolveService
    from schemas.design import Body

    bodies.check_name(body)
    d = msgspec.structs.replace(design, body=Body(name=body))
    remesher = RemeshService()
    solver = SolveService(method=method, max_seconds={"coarse": max_seconds, "fine": max_seconds})
    if solver_options:
        from couture.solvers import get_solver

        solver.solver = get_solver(method, **solver_options)
    ups = remesher.set_design(d, 1)
    solver.set_design(d)
    for up in ups:
        solver.set_mesh(up.level, up.mesh, up.mesh_generation)
    levels = ("coarse",) if level == "coarse" else ("coarse", "fine")
    runs = solver.run(levels=levels)
    lm = solver.levels[levels[-1]]
    return runs[-1].result, lm.model, lm.mesh


def fit(
    design,
    body: str,
    level: str = "coarse",
    method: str = "newton",
    max_seconds: float = 60.0,
    solver_options: dict | None = None,
) -> SizeFit:
    """Drape on one body and measure the fit."""
    result, model, mesh = drape_on(design, body, level, method, max_seconds, solver_options)
    x = result.x
    stretch = principal_stretches(mesh.X, mesh.tris, x)
    strain = stretch[:, 0] - 1.0
    p = contact_pressure(model, x)
    area = vertex_areas(x, mesh.tris)
    touching = p > 0
    girths, heights = body_landmarks(body)
    centres = body_centres(body, heights)
    sections = body_sections(body, heights)
    garment = {k: girth_at(x, mesh.tris, heights[k], centres[k], section=sections[k]) for k in LANDMARKS}
    ease: dict[str, float | None] = {}
    for k in LANDMARKS:
        g = garment[k]
        ease[k] = None if g is None else g - girths[k]
    return SizeFit(
        body=body,
        vertices=mesh.n_vertices,
        level=level,
        body_girth=girths,
        landmark_y=heights,
        garment_girth=garment,
        ease=ease,
        top_y=float(x[:, 1].max()),
        strain_max=float(strain.max()),
        strain_p95=float(np.percentile(strain, 95)),
        pressure_mean=float((p * area)[touching].sum() / area[touching].sum()) if touching.any() else 0.0,
        pressure_max=float(p.max()),
        contact_fraction=float(area[touching].sum() / area.sum()),
        converged=bool(result.converged),
        residual=float(result.residual),
        iterations=int(result.iterations),
        seconds=float(result.wall_time),
        diagnosis=result.diagnosis,
        strain_max_panel=mesh.panel_names[mesh.tri_panel[int(np.argmax(strain))]] if mesh.panel_names else "",
        clearance=float(model.body.phi_grad(x)[0].min()) if model.body is not None else float("nan"),
        maps={"strain": strain, "pressure": p[mesh.tris].mean(axis=1), "x": x, "tris": mesh.tris},
    )


def _cm(v: float | None) -> str:
    return "    -" if v is None else f"{100 * v:5.1f}"


def table(rows: list[SizeFit]) -> str:
    lines = [
        f"{'body':7s} {'n':>5s} {'top-waist cm':>12s} {'ease cm bust/waist/hip':>22s} {'strain max':>10s} {'p95':>6s} "
        f"{'p mean/max Pa':>14s} {'contact':>7s} {'residual':>9s} conv  {'clear mm':>8s} strain max at"
    ]
    for r in rows:
        e = r.ease
        lines.append(
            f"{r.body:7s} {r.vertices:5d} {_cm(r.top_y - r.landmark_y['waist']):>12s} {_cm(e['bust'])} / {_cm(e['waist'])} / {_cm(e['hip'])}  "
            f"{r.strain_max:10.3f} {r.strain_p95:6.3f} {r.pressure_mean:6.1f}/{r.pressure_max:<7.1f} "
            f"{r.contact_fraction:7.2f} {r.residual:9.1e} {r.converged!s:5s} {1000 * r.clearance:8.1f} {r.strain_max_panel}"
        )
    return "\n".join(lines)


def render(path: Path, rows: list[SizeFit], title: str) -> None:
    """One column per size; rows: strain map, pressure map (front view, back faces first)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import Normalize

    from couture.cloth.body import load_mannequin_mesh

    smax = max(max(float(np.percentile(r.maps["strain"], 99)), 0.01) for r in rows)
    pmax = max(max(float(np.percentile(r.maps["pressure"], 99)), 1e-3) for r in rows)
    norms = {"strain": Normalize(0.0, smax), "pressure": Normalize(0.0, pmax)}
    cmaps = {"strain": "magma", "pressure": "viridis"}
    n = len(rows)
    fig, axes = plt.subplots(2, n, figsize=(2.4 * n + 1.2, 7.5), squeeze=False)
    ylo = min(float(r.maps["x"][:, 1].min()) for r in rows) - 0.05
    yhi = max(float(r.maps["x"][:, 1].max()) for r in rows) + 0.05
    for j, r in enumerate(rows):
        V, F = load_mannequin_mesh(r.body)
        x, tris = r.maps["x"], r.maps["tris"]
        order = np.argsort(x[tris][:, :, 2].mean(axis=1))  # +z faces the viewer: draw the back first
        body_order = np.argsort(V[F][:, :, 2].mean(axis=1))
        for i, key in enumerate(("strain", "pressure")):
            ax = axes[i, j]
            ax.add_collection(
                PolyCollection(V[F][body_order][:, :, :2], facecolor=(0.82, 0.82, 0.82), edgecolor="none")
            )
            pc = PolyCollection(x[tris][order][:, :, :2], cmap=cmaps[key], norm=norms[key], edgecolor="none")
            pc.set_array(r.maps[key][order])
            ax.add_collection(pc)
            ax.set_xlim(-0.35, 0.35)
            ax.set_ylim(ylo, yhi)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            if i == 0:
                e = r.ease["waist"]
                ax.set_title(f"{r.body}\nwaist ease {'-' if e is None else f'{100 * e:.1f} cm'}", fontsize=9)
            if j == 0:
                ax.set_ylabel("max principal stretch - 1" if key == "strain" else "contact pressure [Pa]")
    for i, key in enumerate(("strain", "pressure")):
        sm = plt.cm.ScalarMappable(norm=norms[key], cmap=cmaps[key])
        fig.colorbar(sm, ax=list(axes[i, :]), fraction=0.02, pad=0.01)
    fig.suptitle(title, fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(fig)


def run(
    design_path: Path | str = DEFAULT_DESIGN,
    sizes: list[str] | None = None,
    level: str = "coarse",
    vertices: int | None = None,
    method: str = "newton",
    max_seconds: float = 60.0,
    progress=print,
    solver_options: dict | None = None,
) -> list[SizeFit]:
    """Fit of one design on each body in ``sizes`` (default: every body)."""
    import msgspec

    from couture import bodies
    from couture.pattern.io import load_design

    design = load_design(design_path)
    if vertices is not None:
        design = msgspec.structs.replace(
            design, resolution=msgspec.structs.replace(design.resolution, coarse_vertices=int(vertices))
        )
    sizes = list(bodies.names()) if not sizes else sizes
    for s in sizes:
        bodies.check_name(s)
    rows = []
    for k, s in enumerate(sizes):
        t0 = time.perf_counter()
        r = fit(design, s, level, method, max_seconds, solver_options)
        rows.append(r)
        progress(
            f"[grading] {k + 1}/{len(sizes)} {s}: {r.vertices} vertices, residual {r.residual:.1e} "
            f"({'converged' if r.converged else 'not converged'}), waist ease {_cm(r.ease['waist']).strip()} cm, "
            f"strain max {r.strain_max:.3f}, pressure max {r.pressure_max:.1f} Pa, {time.perf_counter() - t0:.1f} s",
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    from couture import bodies

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--design", type=Path, default=DEFAULT_DESIGN, help="design JSON (default: the skirt example)")
    ap.add_argument("--sizes", nargs="*", default=None, help=f"bodies (default: all of {', '.join(bodies.names())})")
    ap.add_argument("--level", choices=("coarse", "fine"), default="coarse", help="fine: cascadic coarse -> fine")
    ap.add_argument("--vertices", type=int, default=None, help="coarse vertex count (default: the design's)")
    ap.add_argument("--solver", default="newton")
    ap.add_argument("--max-seconds", type=float, default=60.0, help="[s] cap per level solve")
    ap.add_argument(
        "--max-step",
        type=float,
        default=None,
        help="[m] Newton's largest vertex move per step (default: the solver's, a quarter of the garment's extent)",
    )
    ap.add_argument("--no-png", action="store_true")
    add_out_arg(ap)
    args = ap.parse_args(argv)
    if not args.design.exists():
        ap.error(f"--design {args.design}: no such file")
    if args.max_step is not None and (args.solver != "newton" or not args.max_step > 0):
        ap.error("--max-step: a positive length, with --solver newton")
    options = None if args.max_step is None else {"max_step": args.max_step}
    try:
        rows = run(
            args.design, args.sizes, args.level, args.vertices, args.solver, args.max_seconds, solver_options=options
        )
    except ValueError as e:
        ap.error(str(e))
    print(table(rows))
    out = Path(args.out)
    path = write_results(
        out,
        "grading",
        {
            "design": str(args.design),
            "level": args.level,
            "solver": args.solver,
            "solver_options": options or {},
            "commit": source_commit(),
            "rows": [{k: v for k, v in asdict(r).items() if k != "maps"} for r in rows],
        },
    )
    print(f"wrote {path}")
    if not args.no_png:
        how = args.solver if options is None else f"{args.solver}, max step {args.max_step:g} m"
        render(out / "grading.png", rows, f"{args.design.name} on each body ({args.level}, {how})")
        print(f"wrote {out / 'grading.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

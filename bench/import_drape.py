"""``python -m bench.import_drape DESIGN.json DRAPE_DIR [...]``: how an
imported pattern's ``couture drape`` ended, measured and pictured.

For each (design, drape folder) pair: the design (``couture import``'s
output) meshed again at its fine resolution exactly as the remesher meshes it
(the first mesh of a generation; checked against the drape's vertex count),
the drape read back from ``drape.obj``, and measured: the largest seam gap
(every seam spring's emitter to its receiving point), the smallest signed
distance of any vertex to the body (the grid SDF; < 0 is inside), the
solver's residual, iterations and time from ``drape.json``. Writes
``import_drape.json`` (one row per drape) and ``import_<name>.png`` (front,
side and the pattern with its seams, each seam's two segments in one colour)
to ``--out`` (default bench/results/import/).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from bench import RESULTS_DIR, write_results
from bench.drape_slopers import seam_gaps


def read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(positions (n, 3) [m], triangles (m, 3)) of ``couture drape``'s drape.obj."""
    V, F = [], []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            V.append([float(t) for t in line.split()[1:4]])
        elif line.startswith("f "):
            F.append([int(t.split("/")[0]) - 1 for t in line.split()[1:4]])
    return np.array(V), np.array(F, dtype=np.int64)


def measure(design_path: Path, drape_dir: Path) -> tuple[dict, object, np.ndarray, object]:
    """(the row, the fine mesh, the draped positions, the drafted pattern) of one drape."""
    from couture import bodies
    from couture.cloth.body import load_mannequin_sdf
    from couture.pattern.io import load_design
    from couture.pattern.validate import validate
    from couture.remesh.meshing import mesh_pattern

    design = load_design(design_path)
    drafted = validate(design)
    meshed = mesh_pattern(drafted, design.resolution.fine_vertices, level="fine")
    mesh = meshed.mesh
    x, tris = read_obj(drape_dir / "drape.obj")
    if x.shape[0] != mesh.n_vertices or not np.array_equal(tris, np.asarray(mesh.tris)):
        raise ValueError(f"{drape_dir}: the drape's mesh ({x.shape[0]} vertices) is not the design's fine mesh")
    info = json.loads((drape_dir / "drape.json").read_text())
    sdf = load_mannequin_sdf(verbose=False, name=bodies.use(design.body))
    phi = sdf.phi_grad(x)[0]
    seams = [s for s in design.strokes if s.kind == "seam"]
    row = {
        "design": design_path.stem,
        "body": design.body.name,
        "panels": len(design.pieces),
        "seams": len(seams),
        "vertices": int(x.shape[0]),
        "converged": bool(info["converged"]),
        "residual": info["residual"],
        "tolerance": info["tolerance"],
        "iterations": info["iterations"],
        "seconds": info["wall_time_s"],
        "seam_gap_max_mm": float(seam_gaps(mesh, x).max() * 1e3) if len(mesh.seam_emitters) else 0.0,
        "body_distance_min_mm": float(phi.min() * 1e3),
        "inside": int((phi < 0).sum()),
        "diagnosis": info.get("diagnosis", ""),
    }
    torso = {pc.name for pc in design.pieces if pc.placement.ring == "torso"}
    on = np.isin(np.asarray(mesh.panel_names)[meshed.vertex_panel], sorted(torso))
    if on.any():
        # where the torso ring's pieces start and end (a top that rides up: docs/import.md)
        from couture.pattern.landmarks import neck

        x0 = np.asarray(mesh.x0)[on]
        row["torso_placed_top_hem_y"] = [float(x0[:, 1].max()), float(x0[:, 1].min())]
        row["torso_draped_top_hem_y"] = [float(x[on, 1].max()), float(x[on, 1].min())]
        row["torso_mean_rise_m"] = float((x[on, 1] - x0[:, 1]).mean())
        row["neck_base_y"] = neck(design.body.name).base_y
    return row, mesh, x, (design, drafted)


def render(path: Path, title: str, mesh, x: np.ndarray, design_drafted) -> None:
    """Front and side of the drape on its body, and the pattern: each panel's
    sew line, its seams coloured pairwise (one colour per seam, both sides)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from couture.cloth.body import load_mannequin_mesh
    from couture.pattern.draft import segment_points

    design, drafted = design_drafted
    V, F = load_mannequin_mesh(design.body.name)
    fig = plt.figure(figsize=(15, 7))
    lo, hi = x.min(0), x.max(0)
    mid = 0.5 * (lo + hi)
    half = max(0.35, 0.55 * float((hi - lo).max()))
    for k, (elev, azim, label) in enumerate(((0, -90, "front"), (0, 0, "side"))):
        ax = fig.add_subplot(1, 3, k + 1, projection="3d")
        ax.add_collection3d(Poly3DCollection(V[F][:, :, [0, 2, 1]], facecolor=(0.8, 0.8, 0.8, 0.25), edgecolor="none"))
        ax.add_collection3d(
            Poly3DCollection(
                x[mesh.tris][:, :, [0, 2, 1]],
                facecolor=(0.2, 0.4, 0.85, 0.8),
                edgecolor=(0.1, 0.1, 0.3, 0.3),
                linewidth=0.2,
            )
        )
        ax.set_xlim(mid[0] - half, mid[0] + half)
        ax.set_ylim(mid[2] - half, mid[2] + half)
        ax.set_zlim(mid[1] - half, mid[1] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=elev, azim=azim)
        ax.set_axis_off()
        ax.set_title(label)
    ax = fig.add_subplot(1, 3, 3)
    by = {p.name: p for p in drafted.panels}
    shift: dict[str, np.ndarray] = {}
    xo = 0.0
    for p in drafted.panels:
        P = np.asarray(p.outline)
        shift[p.name] = np.array([xo - P[:, 0].min(), -P[:, 1].max()])
        Q = np.vstack([P, P[:1]]) + shift[p.name]
        ax.plot(Q[:, 0], Q[:, 1], color="0.4", lw=0.8)
        c = P.mean(0) + shift[p.name]
        ax.text(c[0], c[1], p.name, ha="center", va="center", fontsize=7)
        xo += float(np.ptp(P[:, 0])) + 0.05
    cmap = plt.get_cmap("tab20")
    for i, sp in enumerate(drafted.seams):
        for pn, sn in ((sp.a_panel, sp.a_segment), (sp.b_panel, sp.b_segment)):
            seg = next(s for s in by[pn].segments if s.name == sn)
            Q = segment_points(by[pn], seg) + shift[pn]
            ax.plot(Q[:, 0], Q[:, 1], color=cmap(i % 20), lw=2.2)
    ax.set_aspect("equal")
    ax.set_axis_off()
    ax.set_title(f"pattern: {len(drafted.seams)} seams (one colour each)")
    fig.suptitle(title)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80, bbox_inches="tight")
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pairs", nargs="+", help="DESIGN.json DRAPE_DIR, repeated")
    ap.add_argument(
        "--out",
        type=Path,
        default=RESULTS_DIR / "import",
        metavar="DIR",
        help="results folder: writes import_drape.json and the pictures there (default: %(default)s)",
    )
    ap.add_argument("--no-png", action="store_true")
    args = ap.parse_args(argv)
    if len(args.pairs) % 2:
        ap.error("give DESIGN.json DRAPE_DIR pairs")
    out = Path(args.out)
    rows = []
    for d, r in zip(args.pairs[::2], args.pairs[1::2], strict=True):
        row, mesh, x, dd = measure(Path(d), Path(r))
        rows.append(row)
        print(json.dumps(row))
        if not args.no_png:
            render(
                out / f"import_{row['design']}.png",
                f"{row['design']} on {row['body']}: {row['iterations']} its, {row['seconds']:.0f} s, "
                f"residual {row['residual']:.1e}, seam gap {row['seam_gap_max_mm']:.2f} mm, "
                f"nearest {row['body_distance_min_mm']:.1f} mm",
                mesh,
                x,
                dd,
            )
    prev = out / "import_drape.json"
    old = json.loads(prev.read_text())["rows"] if prev.exists() else []
    keep = [o for o in old if o["design"] not in {r["design"] for r in rows}]
    write_results(out, "import_drape", {"rows": keep + rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

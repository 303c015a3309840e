"""``couture bench drape_fabrics_gallery``: every example design draped in
several fabrics of the library, side by side.

Per design: remesh once at ``--vertices`` (the coarse level), then drape it
from placement with Newton (``--solver``) to ``--tol`` in each fabric of
``--fabrics`` (library names, ``couture.fabrics``, or ``bench.drape``'s
variants design/stiff/soft; a library fabric replaces the design's, panels'
own fabrics stay), as the solver node solves its coarse level. Prints
iterations, relative residual, converged and time per case (with the solver's
progress), writes ``drape_fabrics_gallery.json`` and, per design, a front view
of the drapes side by side (``<design>.png``) into ``--out`` (default
``bench/results/fabric_gallery/``). Each case also gives the largest share of
the fabric's wearable stretch limit the drape reaches (98th percentile of
``couture.ui.colormaps`` fabric_strain, %).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench import RESULTS_DIR, source_commit, write_results
from bench.drape import check_fabrics, load, with_options
from couture.pattern.io import EXAMPLES

DEFAULT_FABRICS = ("silk_charmeuse", "jersey", "cotton_shirting", "denim")
"""the library fabrics of the gallery (light to heavy, soft to stiff)"""
OUT_DIR = RESULTS_DIR / "fabric_gallery"
"""default results folder"""


def drape_fabrics(
    design: Any,
    fabrics: list[str],
    library: Any,
    *,
    method: str = "newton",
    vertices: int = 1600,
    tol: float = 1e-4,
    max_seconds: float = 300.0,
    label: str = "",
) -> list[dict[str, Any]]:
    """One coarse drape of ``design`` per fabric on one shared mesh: per case
    fabric, iterations, residual, converged, wall time [s], diagnosis, the
    fabric-strain share and (under ``_x``, ``_mesh``) the drape for the picture."""
    import msgspec

    from couture.remesh.service import RemeshService
    from couture.solvers.service import SolveService
    from couture.ui import colormaps

    design = msgspec.structs.replace(
        design, resolution=msgspec.structs.replace(design.resolution, coarse_vertices=int(vertices))
    )
    t0 = time.perf_counter()
    updates = [u for u in RemeshService().set_design(design, 1) if u.level == "coarse"]
    remesh_s = time.perf_counter() - t0
    (up,) = updates
    cases = []
    for k, fabric in enumerate(fabrics):
        d = with_options(design, fabric=fabric, library=library)
        tag = f"{label} [{k + 1}/{len(fabrics)}] {fabric}"
        print(f"{tag}: {up.mesh.n_vertices} vertices...", file=sys.stderr, flush=True)
        service = SolveService(method=method)
        service.tol["coarse"] = float(tol)
        service.max_seconds["coarse"] = float(max_seconds)
        service.set_design(d)
        service.set_mesh("coarse", up.mesh, up.mesh_generation, None)
        t_run = time.perf_counter()

        def on_progress(level: str, it: int, x: np.ndarray, res: float, tag: str = tag, t_run: float = t_run) -> None:
            print(
                f"    {tag}: iteration {it}, residual {res:.2e}, {time.perf_counter() - t_run:.0f} s", file=sys.stderr
            )

        (run,) = service.run(levels=("coarse",), on_progress=on_progress, progress_period_s=10.0)
        r = run.result
        axes = colormaps.fabric_axes(up.mesh, d.fabric, d.panel_fabrics)
        share = colormaps.field_values("fabric_strain", up.mesh.X, r.x, up.mesh.tris, axes=axes)
        case = {
            "fabric": fabric,
            "fabric_values": msgspec.to_builtins(d.fabric),
            "vertices": int(r.x.shape[0]),
            "iterations": int(r.iterations),
            "residual": float(r.residual),
            "converged": bool(r.converged),
            "wall_time_s": float(r.wall_time),
            "diagnosis": r.diagnosis,
            "fabric_strain_p98_pct": float(np.percentile(share, 98)) if share is not None else None,
            "remesh_s": remesh_s,
            "_x": r.x,
            "_mesh": up.mesh,
        }
        print(
            f"{tag}: {case['iterations']} its, residual {case['residual']:.1e}, "
            f"{'converged' if case['converged'] else 'NOT converged'}, {case['wall_time_s']:.1f} s, "
            f"fabric strain p98 {case['fabric_strain_p98_pct']:.1f} % of limit",
            file=sys.stderr,
            flush=True,
        )
        cases.append(case)
    return cases


def render(path: Path, name: str, cases: list[dict[str, Any]], body: str = "default") -> None:
    """Front views side by side, one per fabric: the body grey, the cloth
    lit by its normals (back faces first)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from couture.cloth.body import load_mannequin_mesh

    V, F = load_mannequin_mesh(body)
    body_tris = V[F][np.argsort(V[F][:, :, 2].mean(axis=1))]
    n = len(cases)
    fig, axes = plt.subplots(1, n, figsize=(2.6 * n, 5.2), squeeze=False)
    ylo = min(float(c["_x"][:, 1].min()) for c in cases) - 0.05
    yhi = max(float(c["_x"][:, 1].max()) for c in cases) + 0.05
    light = np.array([0.3, 0.5, 1.0]) / np.linalg.norm([0.3, 0.5, 1.0])
    base = np.array([0.84, 0.47, 0.36])
    for ax, c in zip(axes[0], cases, strict=True):
        x, tris = c["_x"], c["_mesh"].tris
        p = x[tris]
        nrm = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-15)
        shade = 0.35 + 0.65 * np.abs(nrm @ light)  # two-sided
        order = np.argsort(p[:, :, 2].mean(axis=1))  # +z faces the viewer
        ax.add_collection(PolyCollection(body_tris[:, :, :2], facecolor=(0.82, 0.82, 0.82), edgecolor="none"))
        ax.add_collection(
            PolyCollection(p[order][:, :, :2], facecolor=np.clip(shade[order, None] * base, 0, 1), edgecolor="none")
        )
        ax.set_xlim(-0.4, 0.4)
        ax.set_ylim(ylo, yhi)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        state = "" if c["converged"] else ", NOT converged"
        ax.set_title(f"{c['fabric']}\n{c['iterations']} its, {c['wall_time_s']:.0f} s{state}", fontsize=9)
    fig.suptitle(f"{name}: {cases[0]['vertices']} vertices, front", fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80, bbox_inches="tight")
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--designs",
        nargs="*",
        default=sorted(p.stem for p in EXAMPLES.glob("*.json")),
        help="example names or pattern files (default: every example)",
    )
    ap.add_argument(
        "--fabrics",
        default=",".join(DEFAULT_FABRICS),
        help="comma separated: fabric library names or bench drape's variants design, stiff, soft "
        "(default: %(default)s)",
    )
    ap.add_argument("--solver", default="newton", help="solver of every drape (default: %(default)s)")
    ap.add_argument("--vertices", type=int, default=1600, help="coarse-level vertex target (default: %(default)s)")
    ap.add_argument("--tol", type=float, default=1e-4, help="relative residual to reach (default: %(default)s)")
    ap.add_argument("--max-seconds", type=float, default=300.0, help="[s] cap on each drape (default: %(default)s)")
    ap.add_argument(
        "--out",
        type=Path,
        default=OUT_DIR,
        metavar="DIR",
        help=f"results folder: writes drape_fabrics_gallery.json and a PNG per design (default: {OUT_DIR})",
    )
    a = ap.parse_args(argv)
    fabrics = [f for f in a.fabrics.split(",") if f]
    if not fabrics:
        ap.error("--fabrics: none given")
    try:
        library = check_fabrics(fabrics)
    except ValueError as e:
        ap.error(str(e))
    from couture.solvers import SOLVERS

    if a.solver not in SOLVERS:
        ap.error(f"--solver {a.solver}: choose from {', '.join(SOLVERS)}")
    out = Path(a.out)
    results: dict[str, Any] = {
        "bench": "drape_fabrics_gallery",
        "commit": source_commit(),
        "args": dict(vars(a), out=str(a.out)),
        "designs": {},
    }
    t_all = time.perf_counter()
    for i, name_or_path in enumerate(a.designs):
        name, design = load(name_or_path)
        cases = drape_fabrics(
            design,
            fabrics,
            library,
            method=a.solver,
            vertices=a.vertices,
            tol=a.tol,
            max_seconds=a.max_seconds,
            label=f"[{i + 1}/{len(a.designs)}] {name}",
        )
        render(out / f"{name}.png", name, cases, design.body.name)
        results["designs"][name] = [{k: v for k, v in c.items() if not k.startswith("_")} for c in cases]
        write_results(out, "drape_fabrics_gallery", results)  # after every design: a stopped run keeps what it did
    results["total_s"] = time.perf_counter() - t_all
    write_results(out, "drape_fabrics_gallery", results)
    print(
        f"{'design':14s} {'fabric':16s} {'n':>5s} {'its':>5s} {'residual':>9s} {'conv':>5s} {'s':>6s} {'strain %':>8s}"
    )
    for name, cases in results["designs"].items():
        for c in cases:
            print(
                f"{name:14s} {c['fabric']:16s} {c['vertices']:5d} {c['iterations']:5d} {c['residual']:9.1e} "
                f"{c['converged']!s:>5s} {c['wall_time_s']:6.1f} {c['fabric_strain_p98_pct']:8.1f}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

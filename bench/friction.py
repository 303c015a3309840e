"""``couture bench friction``: how friction enters, measured: the slip-event anchors
against the elasto-plastic ('huber') potential with its state carried from the
coarse level to the fine one (``schemas.design.SceneFlags.friction_model``).

For every example design, each friction model and each solver on couture's own
cloth model (Newton, kinetic), the cascadic drape from placement as the solver
node runs it (RemeshService -> SolveService, coarse then fine), at a reduced
resolution (default 400 / 1500 vertices) so that the whole grid runs in
minutes. Reported per case: iterations, converged, residual and wall time per
level, slip events; per design and friction model: how far apart Newton's and
kinetic's fine drapes lie (max and mean vertex distance [mm]): two solvers of
one physics should find the same friction equilibrium, and a friction state
decided by the solver's path makes them differ. Writes ``friction.json`` and
``friction.png`` (distance per design, both models) under ``--out``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench import add_out_arg, source_commit, write_results
from couture.pattern.io import EXAMPLES

MODELS = ("anchors", "huber")
METHODS = ("newton", "kinetic")


def drape(name: str, friction_model: str, method: str, coarse: int, fine: int) -> dict[str, Any]:
    """One cascade from placement; returns its figures and the fine drape."""
    import msgspec

    from couture.pattern.io import load_design
    from couture.remesh.service import RemeshService
    from couture.solvers.service import SolveService
    from schemas.design import Resolution

    design = load_design(EXAMPLES / f"{name}.json")
    design = msgspec.structs.replace(
        design,
        resolution=Resolution(coarse_vertices=coarse, fine_vertices=fine),
        scene=msgspec.structs.replace(design.scene, friction=True, friction_model=friction_model),
    )
    service = SolveService(method=method)
    service.max_seconds = {"coarse": 120.0, "fine": 300.0}
    service.set_design(design)
    for up in RemeshService().set_design(design, 1):
        prolong = None
        if up.fine_parent_tri is not None and up.fine_bary is not None:
            prolong = (up.fine_parent_tri, up.fine_bary)
        service.set_mesh(up.level, up.mesh, up.mesh_generation, prolong)
    levels = {}
    for run in service.run():
        r = run.result
        levels[run.level] = {
            "vertices": int(r.x.shape[0]),
            "iterations": int(r.iterations),
            "converged": bool(r.converged),
            "residual": float(r.residual),
            "wall_s": float(r.wall_time),
            "slip_events": int(r.stats.get("slipped", 0) or 0),
            "dynamics_phases": int(r.stats.get("dynamics_phases", 0) or 0),
            "diagnosis": r.diagnosis,
        }
    x = service.levels["fine"].x
    return {"levels": levels, "x": None if x is None else np.asarray(x)}


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    designs = sorted({r["design"] for r in rows})
    fig, ax = plt.subplots(figsize=(9, 4))
    w = 0.2
    for k, (model, stat) in enumerate([(m, s) for m in MODELS for s in ("max_mm", "mean_mm")]):
        vals = [
            next((r[stat] for r in rows if r["design"] == d and r["friction_model"] == model), np.nan) for d in designs
        ]
        ax.bar(np.arange(len(designs)) + (k - 1.5) * w, vals, w, label=f"{model} {stat[:-3]}")
    ax.set_xticks(np.arange(len(designs)), designs, rotation=20)
    ax.set_yscale("log")
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.set_ylabel("Newton vs kinetic fine drape [mm]")
    ax.set_title("Same physics, two solvers: distance between their friction equilibria")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench friction", description=__doc__.split("\n\n")[0])
    add_out_arg(ap)
    ap.add_argument("--designs", default=",".join(sorted(p.stem for p in EXAMPLES.glob("*.json"))))
    ap.add_argument("--vertices", default="400,1500", help="coarse,fine vertex targets (default %(default)s)")
    a = ap.parse_args(argv)
    coarse, fine = (int(v) for v in a.vertices.split(","))
    designs = [d for d in a.designs.split(",") if d]
    cases, pairs = [], []
    t0 = time.perf_counter()
    total = len(designs) * len(MODELS) * len(METHODS)
    for name in designs:
        for model in MODELS:
            xs = {}
            for method in METHODS:
                out = drape(name, model, method, coarse, fine)
                xs[method] = out.pop("x")
                cases.append({"design": name, "friction_model": model, "method": method, **out})
                lv = out["levels"]
                print(
                    f"[{len(cases)}/{total}] {name} {model} {method}: "
                    + ", ".join(
                        f"{k} {v['iterations']} its {'ok' if v['converged'] else 'NOT converged'}"
                        for k, v in lv.items()
                    )
                    + f" ({time.perf_counter() - t0:.0f} s)",
                    file=sys.stderr,
                    flush=True,
                )
            if all(v is not None for v in xs.values()):
                d = np.linalg.norm(xs["newton"] - xs["kinetic"], axis=1)
                pairs.append(
                    {
                        "design": name,
                        "friction_model": model,
                        "max_mm": float(d.max() * 1e3),
                        "mean_mm": float(d.mean() * 1e3),
                    }
                )
    print(f"{'design':14s} {'model':8s} {'newton-kinetic max/mean [mm]':>30s}")
    for p in pairs:
        print(f"{p['design']:14s} {p['friction_model']:8s} {p['max_mm']:14.2f} / {p['mean_mm']:.2f}")
    res = {
        "bench": "friction",
        "commit": source_commit(),
        "vertices": {"coarse": coarse, "fine": fine},
        "distance": pairs,
        "cases": cases,
        "wall_s": time.perf_counter() - t0,
    }
    path = write_results(a.out, "friction", res)
    plot(pairs, Path(a.out) / "friction.png")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

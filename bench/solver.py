"""``couture bench solver``: equilibrium solvers draping the default skirt on the mannequin.

Scene: ``Design()`` (the default A-line skirt, default fabric: 20 N/m,
poisson 0.3, 1e-6 N·m, 0.15 kg/m²; body, gravity, seams and friction on),
meshed by ``RemeshService`` at its coarse (~1.6k vertices) and fine (~10k)
levels, each solver started from the initial placement ``mesh.x0``. Plus the
cascadic run the solver node does (``SolveService.run``: coarse to 1e-3,
prolongation, fine to 1e-4) per solver.

Per solver and level: time to relative residual 1e-4 and 1e-6 (from the solve
history), or the residual reached within the cap; steps/s and ms per step;
assembly, linear-solve (factorization + solves) and friction time; peak RSS
growth; numba compile (first call, on a tiny sheet) measured separately.
Table on stdout; ``solver.json`` and the convergence plot (relative residual
vs wall time, log scale) ``solver_convergence.png`` to the results folder
(``--out``, default bench/results/). ``--quick``: coarse level only, short
caps (< 2 minutes).

Timings on a shared 2-core machine are noisy: compare solvers within one run.
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

import numpy as np

from bench import OWN_SOLVERS, add_out_arg, write_results

GOALS = {"coarse_steps_per_s": 50.0, "fine_steps_per_s": 10.0, "fine_drape_1e-4_s": 5.0}


def skirt_models(design=None, levels=("coarse", "fine")):
    """{level: ClothModel} of the default skirt (fresh models: fresh friction anchors),
    and the remesher's fine -> coarse prolongation (parent triangle, barycentric)."""
    from couture.cloth import ClothModel
    from couture.remesh.service import RemeshService
    from couture.solvers.service import scene_from_design
    from schemas.design import Design

    design = design or Design()
    ups = RemeshService().set_design(design, 1)
    scene = scene_from_design(design)
    meshes = {u.level: u.mesh for u in ups}
    prol = next(((u.fine_parent_tri, u.fine_bary) for u in ups if u.fine_parent_tri is not None), None)

    def make(level):
        return ClothModel(meshes[level], design.fabric, scene)

    return {lv: make for lv in levels if lv in meshes}, meshes, prol, design


def _time_to(history, level):
    for t, r in history:
        if r <= level:
            return t
    return None


def _rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _row(solver_name, level, model, res, rss0, extra=None):
    steps = max(res.iterations, 1)
    row = {
        "solver": solver_name,
        "level": level,
        "n_vertices": model.n,
        "converged": res.converged,
        "residual": res.residual,
        "diagnosis": res.diagnosis,
        "iterations": res.iterations,
        "wall_s": res.wall_time,
        "time_to_1e-3_s": _time_to(res.history, 1e-3),
        "time_to_1e-4_s": _time_to(res.history, 1e-4),
        "time_to_1e-6_s": _time_to(res.history, 1e-6),
        "step_ms": 1e3 * res.wall_time / steps,
        "steps_per_s": steps / res.wall_time if res.wall_time else None,
        "assembly_s": res.stats.get("assembly_s"),
        "linear_solve_s": res.stats.get("linear_solve_s"),
        "friction_s": res.stats.get("friction_s"),
        "peak_rss_growth_mb": _rss_mb() - rss0,
        "stats": {k: v for k, v in res.stats.items() if isinstance(v, (int, float, str))},
        "history": [(float(t), float(r)) for t, r in res.history[:: max(1, len(res.history) // 400)]],
    }
    row.update(extra or {})
    return row


VARIANTS = {
    # SC's configuration (fixed 5 ms steps, IC(0)-PCG), for comparison with the adaptive default
    "kinetic-sc5ms": ("kinetic", {"adaptive": False, "preconditioner": "ic0"}),
}


def make_solver(name):
    from couture.solvers import get_solver

    base, opts = VARIANTS.get(name, (name, {}))
    return get_solver(base, **opts)


def run_case(solver_name, make_model, level, *, tol, max_seconds, progress):
    model = make_model(level)
    solver = make_solver(solver_name)
    rss0 = _rss_mb()
    seen = {"last": time.perf_counter()}

    def cb(i, x, r):
        now = time.perf_counter()
        if progress and now - seen["last"] > 5.0:
            print(f"    {solver_name} {level}: iteration {i}, residual {r:.2e}", file=sys.stderr, flush=True)
            seen["last"] = now

    res = solver.solve(model, model.mesh.x0, tol=tol, max_seconds=max_seconds, callback=cb)
    return _row(solver_name, level, model, res, rss0)


def run_cascadic(solver_name, design, meshes, prol, *, max_seconds):
    """The solver node's cascadic run: coarse from placement to 1e-3, fine from the
    prolongated coarse drape to 1e-4 (SolveService.run)."""
    from couture.solvers.service import SolveService

    svc = SolveService(
        method=solver_name,
        tol={"coarse": 1e-3, "fine": 1e-4},
        max_seconds={"coarse": max_seconds / 3, "fine": 2 * max_seconds / 3},
    )
    svc.set_design(design)
    svc.set_mesh("coarse", meshes["coarse"], 1)
    svc.set_mesh("fine", meshes["fine"], 1, prolongation=prol)
    rss0 = _rss_mb()
    t0 = time.perf_counter()
    runs = svc.run()
    total = time.perf_counter() - t0
    rows = []
    for run in runs:
        rows.append(
            _row(
                solver_name,
                f"cascadic-{run.level}",
                svc.levels[run.level].model,
                run.result,
                rss0,
                {"warm_start": run.warm_start, "cascadic_total_s": total},
            )
        )
    return rows


def numba_compile_times():
    """First call (compile or cache load) vs warm call of each solver on a tiny sheet."""
    from types import SimpleNamespace

    from couture.cloth import ClothModel, Scene
    from couture.mesh import grid_sheet
    from couture.solvers import get_solver

    m = grid_sheet(0.2, 0.2, 5, 5)
    m.x0 = np.column_stack([m.X[:, 0], np.zeros(len(m.X)), m.X[:, 1]])
    m.pinned = np.array([0], np.int32)
    fab = SimpleNamespace(stretch_stiffness=500.0, bend_stiffness=1e-6, area_density=0.15, poisson_ratio=0.3)
    model = ClothModel(m, fab, Scene())
    out = {}
    for name in OWN_SOLVERS:
        t = time.perf_counter()
        get_solver(name).solve(model, m.x0, max_iters=3)
        first = time.perf_counter() - t
        t = time.perf_counter()
        get_solver(name).solve(model, m.x0, max_iters=3)
        out[name] = {"first_s": first, "warm_s": time.perf_counter() - t}
    return out


def plot(rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    levels = sorted({r["level"] for r in rows}, key=lambda s: ("cascadic" in s, s))
    fig, axes = plt.subplots(1, len(levels), figsize=(5.5 * len(levels), 4.2), squeeze=False)
    for ax, level in zip(axes[0], levels, strict=True):
        for r in rows:
            if r["level"] != level or not r["history"]:
                continue
            t, res = np.array(r["history"]).T
            ax.semilogy(np.maximum(t, 1e-3), res, label=f"{r['solver']} ({r['n_vertices']} v)")
        for lv in (1e-4, 1e-6):
            ax.axhline(lv, color="0.7", lw=0.8, ls="--")
        ax.set_xlabel("wall time [s]")
        ax.set_ylabel("relative residual ||R_free|| / ||F_gravity||")
        ax.set_title(f"default skirt, {level}")
        ax.legend(fontsize=8)
        ax.grid(True, which="major", alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench solver", description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="coarse level only, short caps (< 2 minutes)")
    ap.add_argument("--solvers", default="kinetic,kinetic-sc5ms,newton,verlet")
    ap.add_argument("--levels", default=None, help="comma list of coarse,fine (default both; --quick: coarse)")
    ap.add_argument("--no-cascadic", action="store_true", help="skip the cascadic (solver node) runs")
    ap.add_argument("--max-seconds", type=float, default=None, help="cap per solve [s] (coarse; fine gets 2x)")
    add_out_arg(ap)
    args = ap.parse_args(argv)

    from couture.solvers.linalg import available_backends

    levels = args.levels.split(",") if args.levels else (["coarse"] if args.quick else ["coarse", "fine"])
    cap = args.max_seconds or (15.0 if args.quick else 30.0)
    solvers = args.solvers.split(",")
    print("numba first call vs warm ...", file=sys.stderr, flush=True)
    compile_t = numba_compile_times()
    t = time.perf_counter()
    makers, meshes, prol, design = skirt_models(levels=tuple(levels) + (() if args.quick else ("coarse", "fine")))
    print(
        f"meshed the default skirt in {time.perf_counter() - t:.1f} s: "
        + ", ".join(f"{k} {m.n_vertices} vertices" for k, m in meshes.items()),
        file=sys.stderr,
        flush=True,
    )
    rows = []
    for level in levels:
        for name in solvers:
            print(f"  {name} {level} ...", file=sys.stderr, flush=True)
            rows.append(
                run_case(
                    name,
                    makers[level],
                    level,
                    tol=1e-6,
                    max_seconds=cap if level == "coarse" else 2 * cap,
                    progress=True,
                )
            )
    if not args.quick and not args.no_cascadic and prol is not None:
        for name in solvers:
            if name not in ("kinetic", "newton"):
                continue  # verlet: explicit steps, far from converging a fine level within the cascade's caps
            print(f"  {name} cascadic ...", file=sys.stderr, flush=True)
            rows.extend(run_cascadic(name, design, meshes, prol, max_seconds=3 * cap))

    hdr = (
        f"{'solver':8} {'level':16} {'n':>6} {'conv':>5} {'resid':>9} {'steps':>6} {'t1e-4':>7} {'t1e-6':>7} "
        f"{'step ms':>8} {'steps/s':>8} {'asm s':>6} {'lin s':>6} {'RSS+MB':>7}"
    )
    print(hdr)
    fmt = lambda v: "   -   " if v is None else f"{v:7.2f}"  # noqa: E731
    for r in rows:
        print(
            f"{r['solver']:8} {r['level']:16} {r['n_vertices']:6d} {str(r['converged']):>5} {r['residual']:9.2e} "
            f"{r['iterations']:6d} {fmt(r['time_to_1e-4_s'])} {fmt(r['time_to_1e-6_s'])} {r['step_ms']:8.1f} "
            f"{r['steps_per_s'] or 0:8.1f} {r['assembly_s'] or 0:6.2f} {r['linear_solve_s'] or 0:6.2f} "
            f"{r['peak_rss_growth_mb']:7.1f}"
        )
    for r in rows:
        if r["diagnosis"]:
            print(f"  {r['solver']} {r['level']}: {r['diagnosis']}")
    print(
        "numba first call vs warm [s]:",
        {k: (round(v["first_s"], 2), round(v["warm_s"], 3)) for k, v in compile_t.items()},
    )
    print("goals:", GOALS)
    out = write_results(
        args.out,
        "solver",
        {
            "scene": "default skirt (Design()), friction on",
            "goals": GOALS,
            "backends": available_backends(),
            "numba": compile_t,
            "runs": rows,
            "quick": args.quick,
            "cap_s": cap,
        },
        default=float,
    )
    png = Path(args.out) / "solver_convergence.png"
    plot(rows, png)
    print(f"wrote {out} and {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

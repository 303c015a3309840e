"""``couture bench solver``: equilibrium solvers on a poncho over the mannequin.

Scene (until drafted garments land): a 0.9 x 0.6 m sheet with a round head
hole, placed flat just above the shoulders (lowest height where it clears the
body by 1.5 cm), contact + friction against the mannequin SDF, fabric 500 N/m,
1e-6 N·m, 0.15 kg/m². Per solver and size: time to relative residual 1e-4 and
1e-6 (from the solve history), time per step, assembly and linear-solve time,
peak RSS growth, numba compile (first call) vs warm. Table on stdout, JSON to
bench/results/solver.json.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

GOALS = {"fine_steps_per_s": 10.0, "coarse_steps_per_s": 50.0, "fine_drape_1e-4_s": 5.0}


def poncho_mesh(n_target: int, width: float = 0.9, depth: float = 0.6, hole_r: float = 0.11, head_z: float = 0.056):
    import triangle as tr

    from couture.mesh import GarmentMesh

    area = width * depth - np.pi * hole_r**2
    h = 1.22 * np.sqrt(area / n_target * 2 / np.sqrt(3))  # ~n_target vertices (measured factor)
    nx, nz = int(width / h) + 1, int(depth / h) + 1
    bx, bz = np.linspace(-width / 2, width / 2, nx), np.linspace(-depth / 2, depth / 2, nz) + head_z
    outer = np.concatenate([np.column_stack([bx[:-1], np.full(nx - 1, bz[0])]),
                            np.column_stack([np.full(nz - 1, bx[-1]), bz[:-1]]),
                            np.column_stack([bx[::-1][:-1], np.full(nx - 1, bz[-1])]),
                            np.column_stack([np.full(nz - 1, bx[0]), bz[::-1][:-1]])])
    k = max(12, int(2 * np.pi * hole_r / h))
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    hole = np.column_stack([hole_r * np.cos(t), head_z + hole_r * np.sin(t)])
    pts = np.concatenate([outer, hole])
    no = len(outer)
    segs = np.concatenate([np.column_stack([np.arange(no), (np.arange(no) + 1) % no]),
                           no + np.column_stack([np.arange(k), (np.arange(k) + 1) % k])])
    out = tr.triangulate({"vertices": pts, "segments": segs, "holes": [[0.0, head_z]]},
                         f"pq30a{h * h * np.sqrt(3) / 4 * 1.1:.12f}Q")
    X = out["vertices"].astype(np.float64)
    tris = out["triangles"].astype(np.int32)
    e1, e2 = X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 0]]
    flip = (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) < 0
    tris[flip] = tris[flip][:, [0, 2, 1]]
    return GarmentMesh(X=X, tris=tris)


def poncho_model(n_target: int, body):
    from types import SimpleNamespace

    from couture.cloth import ClothModel, Scene

    mesh = poncho_mesh(n_target)
    X = mesh.X
    y_ok = None
    for y in np.arange(0.80, 0.30, -0.005):
        x0 = np.column_stack([X[:, 0], np.full(len(X), y), X[:, 1]])
        if body.phi_grad(x0)[0].min() < 0.015:
            break
        y_ok = x0
    mesh.x0 = y_ok
    fab = SimpleNamespace(stretch_stiffness=500.0, bend_stiffness=1e-6, area_density=0.15, poisson_ratio=0.3,
                          friction_static=0.5, friction_kinetic=0.3)
    return ClothModel(mesh, fab, Scene(body=body, friction=True))


def _time_to(history, level):
    for t, r in history:
        if r <= level:
            return t
    return None


def _rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_case(solver_name, model, *, tol, max_seconds, progress):
    from couture.solvers import get_solver

    solver = get_solver(solver_name)
    rss0 = _rss_mb()
    seen = {"last": time.perf_counter()}

    def cb(i, x, r):
        now = time.perf_counter()
        if progress and now - seen["last"] > 2.0:
            print(f"    {solver_name}: iteration {i}, residual {r:.2e}", file=sys.stderr, flush=True)
            seen["last"] = now

    res = solver.solve(model, model.mesh.x0, tol=tol, max_seconds=max_seconds, callback=cb)
    steps = max(res.iterations, 1)
    return {
        "solver": solver_name, "n_vertices": model.n, "converged": res.converged, "residual": res.residual,
        "diagnosis": res.diagnosis, "iterations": res.iterations, "wall_s": res.wall_time,
        "time_to_1e-4_s": _time_to(res.history, 1e-4), "time_to_1e-6_s": _time_to(res.history, 1e-6),
        "step_s": res.wall_time / steps, "steps_per_s": steps / res.wall_time if res.wall_time else None,
        "assembly_s": res.stats.get("assembly_s"), "linear_solve_s": res.stats.get("linear_solve_s"),
        "peak_rss_growth_mb": _rss_mb() - rss0,
        "stats": {k: v for k, v in res.stats.items() if isinstance(v, (int, float, str))},
    }


def numba_compile_times():
    """First call (compile or cache load) vs warm call of each solver on a tiny sheet."""
    from couture.cloth import ClothModel, Scene
    from couture.mesh import grid_sheet
    from couture.solvers import get_solver
    from types import SimpleNamespace

    m = grid_sheet(0.2, 0.2, 5, 5)
    m.x0 = np.column_stack([m.X[:, 0], np.zeros(len(m.X)), m.X[:, 1]])
    m.pinned = np.array([0], np.int32)
    fab = SimpleNamespace(stretch_stiffness=500.0, bend_stiffness=1e-6, area_density=0.15, poisson_ratio=0.3)
    model = ClothModel(m, fab, Scene())
    out = {}
    for name in ("kinetic", "newton", "verlet"):
        t = time.perf_counter()
        get_solver(name).solve(model, m.x0, max_iters=3)
        first = time.perf_counter() - t
        t = time.perf_counter()
        get_solver(name).solve(model, m.x0, max_iters=3)
        out[name] = {"first_s": first, "warm_s": time.perf_counter() - t}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench solver", description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="coarse size only, short caps")
    ap.add_argument("--solvers", default="kinetic,newton,verlet")
    ap.add_argument("--sizes", default=None, help="comma list of vertex targets (default 1600,10000)")
    ap.add_argument("--max-seconds", type=float, default=None)
    ap.add_argument("--out", default="bench/results/solver.json")
    args = ap.parse_args(argv)

    from couture.cloth.body import load_mannequin_sdf
    from couture.solvers.linalg import available_backends

    sizes = [int(s) for s in args.sizes.split(",")] if args.sizes else ([1600] if args.quick else [1600, 10000])
    max_s = args.max_seconds or (30.0 if args.quick else 120.0)
    print("numba first call vs warm ...", file=sys.stderr, flush=True)
    compile_t = numba_compile_times()
    body = load_mannequin_sdf()
    rows = []
    for n in sizes:
        model = poncho_model(n, body)
        print(f"poncho with {model.n} vertices", file=sys.stderr, flush=True)
        for name in args.solvers.split(","):
            model.__init__(model.mesh, model.fabric, model.scene)  # fresh friction anchors
            print(f"  {name} ...", file=sys.stderr, flush=True)
            rows.append(run_case(name, model, tol=1e-6, max_seconds=max_s, progress=True))
    hdr = f"{'solver':8} {'n':>6} {'conv':>5} {'resid':>9} {'steps':>6} {'t1e-4':>7} {'t1e-6':>7} {'step ms':>8} {'steps/s':>8} {'asm s':>6} {'lin s':>6} {'RSS+MB':>7}"
    print(hdr)
    fmt = lambda v: "   -   " if v is None else f"{v:7.2f}"  # noqa: E731
    for r in rows:
        print(f"{r['solver']:8} {r['n_vertices']:6d} {str(r['converged']):>5} {r['residual']:9.2e} {r['iterations']:6d} "
              f"{fmt(r['time_to_1e-4_s'])} {fmt(r['time_to_1e-6_s'])} {1e3 * r['step_s']:8.2f} "
              f"{r['steps_per_s'] or 0:8.1f} {r['assembly_s'] or 0:6.2f} {r['linear_solve_s'] or 0:6.2f} {r['peak_rss_growth_mb']:7.1f}")
    for r in rows:
        if r["diagnosis"]:
            print(f"  {r['solver']} n={r['n_vertices']}: {r['diagnosis']}")
    print("numba first call vs warm [s]:", {k: (round(v["first_s"], 2), round(v["warm_s"], 3)) for k, v in compile_t.items()})
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"goals": GOALS, "backends": available_backends(), "numba": compile_t, "runs": rows,
                               "quick": args.quick}, indent=2, default=float))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

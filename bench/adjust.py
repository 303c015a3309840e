"""``couture bench adjust``: direct 3D edits with physics-driven pattern adjustment (Bartle et al. 2016).

Every example design with every edit (hem 10 cm shorter and 5 cm longer,
waist 4 cm looser and 2 cm tighter; an edit the design does not allow is
reported with the reason it was refused), at the coarse resolutions
``--vertices`` (default 400 and 1600), each adjusted once per solver node
(``--solvers``, default newton and kinetic: two different simulators
behind the same ``solve`` request), with the method's settings
(``couture.adjust.settings.DEFAULTS``, what ``couture adjust`` runs). The
solver nodes run as their own processes (``python -m nodes.solver``) under
a supervisor; every solve of an adjustment is a request over the bus
(``couture.client.SolveFanout``).

Reported per run: mean stretch (eq. 8) and Hausdorff distance (% of the
mannequin's height) of every iteration, the start pattern (iteration 0)
against adjusted, the wall time from the edit to the adjusted pattern
(target + iterations, solves included) and in total, seam length mismatch
before and after, and the solver that answered each solve. Then the
design the adjust node would publish (``couture.adjust.service.fit_design``:
sloper options fitted to the adjusted pattern, corrected on its drapes): the
change its own drape achieves against the ask, the options, the drapes it
took (``design_fit``; ``--no-fit`` leaves it out). Writes
``adjust.json`` and ``adjust/<design>_<edit>.png`` (target against the re-simulated
drapes, and the patterns; the first solver at the largest size, or every run
with ``--png-all``) to ``--out``.

Goal (``couture.adjust.settings.GOAL``): Hausdorff <= 1 % of height, mean
stretch >= 0.98, <= 5 re-simulated patterns (the start pattern's
counted) and <= 60 s from the edit to the pattern; each run's verdict
(``couture.adjust.verdict``) names the measured cause of a miss.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import asdict
from pathlib import Path

from bench import add_out_arg, source_commit, write_results
from couture.adjust.settings import DEFAULTS, GOAL
from couture.adjust.verdict import assess, body_for
from couture.client import adjust_on_bus, solver_session
from couture.pattern.io import EXAMPLES
from couture.solvers import SOLVERS

DESIGNS = ["default_skirt", "dress", "dress_waist", "shirt", "shirt_set_in", "trousers", "skirt_edited"]
"""every example design"""
EDITS = {
    "hem_shorter": ("hem", -0.10),
    "hem_longer": ("hem", +0.05),
    "waist_looser": ("waist", +0.04),
    "waist_tighter": ("waist", -0.02),
}
"""the edits every design is asked for (a refused one is reported with its reason)"""
CASES = {f"{d}/{e}": (EXAMPLES / f"{d}.json", *EDITS[e]) for d in DESIGNS for e in EDITS}


def design_fit(client, solver: str, design, case, vertices: int) -> dict:
    """The adjust node's design for ``case`` (its solves on ``solver``,
    ``couture.client.fit_on_bus`` as ``couture adjust`` calls it): what its drape achieves."""
    from couture.client import fit_on_bus

    t0 = time.perf_counter()
    try:
        out = fit_on_bus(client, [solver], design, case, vertices=vertices, max_seconds=60.0)
    except ValueError as e:
        return {"error": str(e), "asked_m": case.amount}
    p = out.projection
    return {
        "asked_m": case.amount,
        "achieved_m": out.achieved,
        "ratio": out.achieved / case.amount,
        "options": p.changed,
        "fit_rms_mm": 1e3 * p.fit_rms_m,
        "loop_cloth_m": p.loop_m,
        "scale": p.scale,
        "drapes": len(out.calibration),
        "calibration": out.calibration,
        "wall_s": time.perf_counter() - t0,
    }


def main(argv: list[str] | None = None) -> int:
    from couture.adjust.pipeline import plot_case
    from couture.client import load_design

    ap = argparse.ArgumentParser(prog="couture bench adjust", description=__doc__.split("\n\n")[0])
    add_out_arg(ap)
    ap.add_argument(
        "--cases", nargs="+", default=list(CASES), choices=list(CASES), metavar="DESIGN/EDIT", help="default: all"
    )
    ap.add_argument("--solvers", nargs="+", default=["newton", "kinetic"], choices=list(SOLVERS))
    ap.add_argument("--vertices", nargs="+", type=int, default=[400, 1600], help="coarse mesh sizes to run")
    ap.add_argument("--iters", type=int, default=None, help=f"fixed-point updates (default {DEFAULTS.updates})")
    ap.add_argument(
        "--gradient-steps",
        type=int,
        default=None,
        help=f"Gauss-Newton steps after the fixed point (default {DEFAULTS.gradient_steps})",
    )
    ap.add_argument("--no-fit", action="store_true", help="leave out the design fit (the adjust node's design)")
    ap.add_argument(
        "--png-all",
        action="store_true",
        help="a PNG per run (default: one per case, the first solver at the largest size)",
    )
    a = ap.parse_args(argv)
    settings = DEFAULTS.with_(updates=a.iters, gradient_steps=a.gradient_steps)
    runs: list[dict] = []
    a.out.mkdir(parents=True, exist_ok=True)
    import tempfile

    log_file = str(Path(tempfile.gettempdir()) / "couture_bench_adjust_nodes.log")
    print(f"solver node logs: {log_file}", file=sys.stderr)
    with solver_session(a.solvers, log_file=log_file) as (client, names):
        for case_name in a.cases:
            path, edit, amount = CASES[case_name]
            design = load_design(path)
            for n in a.vertices:
                for solver in names:
                    print(f"\n== {case_name} ({edit} {amount:+.2f} m), {n} vertices, {solver}", flush=True)
                    try:
                        case, counts = adjust_on_bus(
                            client,
                            [solver],
                            design,
                            edit,
                            amount,
                            vertices=n,
                            name=case_name,
                            settings=settings,
                            log=None,
                        )
                    except ValueError as e:  # an edit the design does not allow: its reason is the result
                        print(f"   refused: {e}", flush=True)
                        runs.append({"case": case_name, "solver_node": solver, "vertices_asked": n, "refused": str(e)})
                        continue
                    except RuntimeError as e:  # the source drape failed: nothing to edit; the next run goes on
                        print(f"   FAILED: {e}", flush=True)
                        runs.append({"case": case_name, "solver_node": solver, "vertices_asked": n, "failed": str(e)})
                        continue
                    case.verdict = assess(case, body=body_for(design))
                    png = None
                    if a.png_all or (solver == names[0] and n == max(a.vertices)):
                        stem = case_name.replace("/", "_")
                        png = a.out / "adjust" / (f"{stem}.png" if not a.png_all else f"{stem}_{solver}_{n}.png")
                        png.parent.mkdir(parents=True, exist_ok=True)
                        plot_case(case, png)
                    s = case.summary()
                    if not a.no_fit:
                        s["design_fit"] = design_fit(client, solver, design, case, n)
                    s.update(
                        case=case_name,
                        solver_node=solver,
                        solves_by_node=counts,
                        vertices_asked=n,
                        png=None if png is None else png.name,
                        goal_met=case.verdict.met,
                    )
                    print(f"   {case.verdict.text()}", flush=True)
                    runs.append(s)
                    write_results(a.out, "adjust", {"partial": True, "runs": runs})  # kept if a later run dies
    print(f"\n{'case':28} {'solver':15} {'verts':>5} {'start H%':>8} {'H%':>6} {'S':>6} {'solves':>6} {'s':>5} goal")
    done = [s for s in runs if "refused" not in s and "failed" not in s]
    for s in runs:
        if "refused" in s or "failed" in s:
            why = f"refused: {s['refused']}" if "refused" in s else f"FAILED: {s['failed']}"
            print(f"{s['case']:28} {s['solver_node']:15} {s['vertices_asked']:5d} {why[:100]}")
            continue
        v = s["verdict"]
        print(
            f"{s['case']:28} {s['solver_node']:15} {s['vertices']:5d} {s['start']['hausdorff_pct']:8.2f} "
            f"{v['hausdorff_pct']:6.2f} {v['stretch']:6.3f} {v['solves']:6d} {v['seconds']:5.1f} "
            f"{'yes' if v['met'] else 'NO'}"
        )
    met = sum(s["goal_met"] for s in done)
    print(f"\ngoal met in {met} of {len(done)} runs ({len(runs) - len(done)} refused or failed)")
    for s in done:
        f = s.get("design_fit")
        if f is None:
            continue
        if "error" in f:
            print(f"{s['case']:28} {s['solver_node']:15} {s['vertices']:5d} | {f['error']}")
            continue
        opts = ", ".join(f"{k} {a:.3f}->{b:.3f}" for k, (a, b) in sorted(f["options"].items()) if abs(b - a) > 2e-3)
        print(
            f"{s['case']:28} {s['solver_node']:15} {s['vertices']:5d} | {100 * f['achieved_m']:+6.1f} / "
            f"{100 * f['asked_m']:+5.1f} ({f['ratio']:.2f}), {f['drapes']} drapes, {f['wall_s']:5.1f} s | {opts}"
        )
    out = write_results(
        a.out,
        "adjust",
        {
            "goal": asdict(GOAL),
            "method": asdict(settings),
            "commit": source_commit(),
            "settings": vars(a) | {"out": str(a.out)},
            "met": met,
            "runs": runs,
        },
    )
    print(f"wrote {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""``couture bench adjust_sweep``: choose pattern adjustment's settings once, for every case.

Every example design with every edit it allows (hem shorter and longer,
waist looser and tighter), at one coarse size, solved in this process
(``--solver``, default newton; the settings are the method's, the bench
``couture bench adjust`` checks them on the solver nodes with both
solvers). Per case: the source drape, the target, then for each fixed-point
start (``--begins``: the update from the source, the target's flattening)
the fixed point run for ``--updates`` updates without its stopping rules
(each iterate kept), and from the iterates after 0, 1 and 2 updates
(``--starts``) the Gauss-Newton steps with each stretch weight of
``--weights`` (2 steps, lengths 1 and ½, each linearized at its own drape,
or with ``--chord`` the second at the first's; every trial recorded).
Every trial is a re-simulation, so any policy "this start, k updates, then
up to s steps with weight w" can be replayed from the record: the policy's
result is exactly what the command would compute with those settings. The
summary scores every policy over all cases: how many meet the goal
(Hausdorff ≤ 1 % of height, mean stretch ≥ 0.98, ≤ 5 re-simulated patterns
counting the start pattern's), the worst Hausdorff distance and stretch,
the mean number of solves.

Writes ``adjust_sweep.json`` (every case, every trial) to ``--out``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from dataclasses import asdict

import numpy as np

from bench import add_out_arg, source_commit, write_results
from couture.adjust.settings import GOAL

EDITS = {
    "hem_shorter": ("hem", -0.10),
    "hem_longer": ("hem", +0.05),
    "waist_looser": ("waist", +0.04),
    "waist_tighter": ("waist", -0.02),
}
DESIGNS = ["default_skirt", "dress", "dress_waist", "shirt", "shirt_set_in", "trousers", "skirt_edited"]


def run_one(
    design_name: str,
    edit_name: str,
    vertices: int,
    solver: str,
    updates: int,
    starts: list[int],
    weights: list[float],
    max_seconds: float,
    begins: tuple[str, ...] = ("flatten", "source"),
    fresh_jacobian: bool = True,
) -> dict:
    from couture.adjust.fixed_point import adjust, local_simulator
    from couture.adjust.gradient import gradient_polish
    from couture.adjust.pipeline import _check_tightening, garment_mesh, make_target
    from couture.client import load_design
    from couture.pattern.io import EXAMPLES

    edit, amount = EDITS[edit_name]
    design = load_design(EXAMPLES / f"{design_name}.json")
    t0 = time.perf_counter()
    mesh = garment_mesh(design, vertices)
    sim = local_simulator(mesh, design, solver, max_seconds=max_seconds)
    src = sim(mesh.X, mesh.x0)
    rec: dict = {
        "design": design_name,
        "edit": edit_name,
        "amount_m": amount,
        "vertices": mesh.n_vertices,
        "source": {"converged": bool(src.converged), "residual": float(src.residual), "seconds": src.wall_time_s},
    }
    try:
        target = make_target(edit, amount, src.x, mesh.tris, mesh)
        if edit == "waist" and amount < 0 and design.scene.body:
            _check_tightening(design, target, src.x, mesh)
    except ValueError as e:
        rec["refused"] = str(e)
        return rec
    rec["target_achieved_m"] = target.achieved
    rec["fixed_point"], rec["polish"] = {}, {}
    for begin in begins:
        fp = adjust(
            mesh,
            target.x,
            sim,
            x_source=src.x,
            max_iters=updates,
            stop_stretch=1.1,
            stagnation=-1.0,
            log=None,
            start=begin,
        )
        rec["fixed_point"][begin] = [asdict(h) for h in fp.history]
        rec["polish"][begin] = {}
        for k in starts:
            if k >= len(fp.patterns):
                continue
            for w in weights:
                try:
                    _, _, steps = gradient_polish(
                        mesh,
                        design,
                        fp.patterns[k],
                        fp_drape(fp, k),
                        target.x,
                        sim,
                        steps=2,
                        stretch_weight=w,
                        reuse_jacobian=not fresh_jacobian,
                        log=None,
                    )
                    rec["polish"][begin][f"{k}:{w:g}"] = [asdict(st) for st in steps]
                except Exception as e:  # noqa: BLE001 - a failed polish is a result of the sweep
                    rec["polish"][begin][f"{k}:{w:g}"] = {"error": f"{type(e).__name__}: {e}"}
    rec["seconds"] = time.perf_counter() - t0
    return rec


def fp_drape(fp, k: int) -> np.ndarray:
    """The drape of the fixed point's iterate k (the AdjustResult keeps the best one's only)."""
    return fp.drapes[k]


def replay(
    case: dict,
    begin: str,
    updates: int,
    weight: float | None,
    steps: int,
    *,
    full_only: bool = False,
    budget: int = GOAL.solves,
    stop_stretch: float = 0.995,
    stagnation: float = 1e-3,
) -> dict | None:
    """What ``run_case`` with these settings computes on the recorded ``case``: the fixed point
    with its stopping rules (stretch reached, stagnated, ``updates`` or the budget spent), the
    best iterate (least Hausdorff), then the gradient steps recorded from that iterate while the
    budget of re-simulated patterns lasts. None where the record does not hold the policy's
    steps (their start was not swept)."""
    hist = case["fixed_point"][begin]
    run = [hist[0]]
    for k in range(1, min(updates, budget - 1) + 1):
        last = run[-1]
        if last["stretch_mean"] >= stop_stretch:
            break
        if k >= 2 and last["stretch_mean"] - run[-2]["stretch_mean"] < stagnation:
            break
        run.append(hist[k])
    best = min(run, key=lambda h: h["hausdorff_pct"])
    h, s, n = best["hausdorff_pct"], best["stretch_mean"], len(run)
    left = budget - n
    if steps > 0 and weight is not None and left > 0:
        pol = case["polish"][begin].get(f"{best['k']}:{weight:g}")
        if not isinstance(pol, list):
            return None
        for g in pol[:steps]:
            if left <= 0:
                break
            if full_only:
                n += 1
                left -= 1
                if g["accepted"] and g["solves"] == 1:
                    h, s = g["hausdorff_pct"], g["stretch_mean"]
                    continue
                break
            if g["accepted"] and g["solves"] <= left:
                n += g["solves"]
                left -= g["solves"]
                h, s = g["hausdorff_pct"], g["stretch_mean"]
            else:
                n += min(g["solves"], left)
                break
    return {"hausdorff_pct": h, "stretch": s, "solves": n, "updates": len(run) - 1}


def score(
    cases: list[dict], begin: str, updates: int, weight: float | None, steps: int, full_only: bool = False
) -> dict:
    """The policy 'the start ``begin`` (flattening, or the update from the source drape), at most ``updates`` updates, then at most ``steps`` gradient steps
    with ``weight``, 5 re-simulated patterns in all', replayed over the recorded cases."""
    met, worst_h, worst_s, solves, rows, missing = 0, 0.0, 1.0, [], [], 0
    for c in cases:
        if "refused" in c:
            continue
        r = replay(c, begin, updates, weight, steps, full_only=full_only)
        if r is None:
            missing += 1
            continue
        ok = r["hausdorff_pct"] <= GOAL.hausdorff_pct and r["stretch"] >= GOAL.stretch and r["solves"] <= GOAL.solves
        met += ok
        worst_h, worst_s = max(worst_h, r["hausdorff_pct"]), min(worst_s, r["stretch"])
        solves.append(r["solves"])
        rows.append({"case": f"{c['design']}/{c['edit']}", **r, "met": ok})
    return {
        "start": begin,
        "updates": updates,
        "weight": weight,
        "steps": steps,
        "lengths": [1.0] if full_only else [1.0, 0.5],
        "met": met,
        "cases": len(rows),
        "not_replayable": missing,
        "worst_hausdorff_pct": worst_h,
        "worst_stretch": worst_s,
        "mean_solves": float(np.mean(solves)) if solves else 0.0,
        "rows": rows,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench adjust_sweep", description=__doc__.split("\n\n")[0])
    add_out_arg(ap)
    ap.add_argument("--designs", nargs="+", default=DESIGNS)
    ap.add_argument("--edits", nargs="+", default=list(EDITS), choices=list(EDITS))
    ap.add_argument("--vertices", type=int, default=400)
    ap.add_argument("--solver", default="newton")
    ap.add_argument("--updates", type=int, default=4, help="fixed-point updates run per case")
    ap.add_argument("--starts", nargs="+", type=int, default=[0, 1, 2], help="gradient steps from these iterates")
    ap.add_argument("--weights", nargs="+", type=float, default=[10.0, 30.0])
    ap.add_argument(
        "--begins", nargs="+", default=["flatten", "source"], choices=["flatten", "source"], help="fixed-point starts"
    )
    ap.add_argument("--chord", action="store_true", help="a second gradient step reuses the first's Jacobian")
    ap.add_argument("--max-seconds", type=float, default=60.0)
    ap.add_argument("--rescore", default=None, help="score an earlier adjust_sweep.json instead of running")
    a = ap.parse_args(argv)
    if a.rescore:
        cases = json.loads(open(a.rescore).read())["cases"]
    else:
        cases = []
        for d, e in itertools.product(a.designs, a.edits):
            print(f"== {d} {e}", flush=True)
            c = run_one(
                d,
                e,
                a.vertices,
                a.solver,
                a.updates,
                a.starts,
                a.weights,
                a.max_seconds,
                tuple(a.begins),
                not a.chord,
            )
            if "refused" in c:
                print(f"   refused: {c['refused']}", flush=True)
            for begin in c.get("fixed_point", {}):
                fp = c["fixed_point"][begin]
                print(
                    f"   {begin}: fixed point H%/S: "
                    + ", ".join(f"{h['hausdorff_pct']:.2f}/{h['stretch_mean']:.3f}" for h in fp)
                    + f"; {c['seconds']:.0f} s",
                    flush=True,
                )
                for key, pol in c["polish"][begin].items():
                    if isinstance(pol, list):
                        print(
                            f"   {begin} polish {key}: "
                            + ", ".join(
                                f"{g['hausdorff_pct']:.2f}/{g['stretch_mean']:.3f}"
                                f"{'' if g['accepted'] else ' refused'} ({g['solves']})"
                                for g in pol
                            ),
                            flush=True,
                        )
            cases.append(c)
            write_results(
                a.out,
                "adjust_sweep",
                {"commit": source_commit(), "settings": vars(a) | {"out": str(a.out)}, "cases": cases},
            )
    begins = sorted({b for c in cases for b in c.get("fixed_point", {})})
    policies = [score(cases, b, u, None, 0) for b in begins for u in range(0, a.updates + 1)]
    for b, u, w, st, fo in itertools.product(begins, range(0, a.updates + 1), a.weights, (1, 2), (False, True)):
        policies.append(score(cases, b, u, w, st, fo))
    print(
        f"\n{'start':>7} {'updates':>7} {'w':>5} {'steps':>5} {'lengths':>8} {'met':>7} {'worst H%':>8} {'worst S':>7} "
        f"{'solves':>6} unreplayable"
    )
    for p in policies:
        print(
            f"{p['start']:>7} {p['updates']:7d} {p['weight'] or 0:5g} {p['steps']:5d} {'1' if len(p['lengths']) == 1 else '1, 0.5':>8} "
            f"{p['met']:3d}/{p['cases']:<3d} "
            f"{p['worst_hausdorff_pct']:8.2f} {p['worst_stretch']:7.3f} {p['mean_solves']:6.1f} {p['not_replayable']}"
        )
    out = write_results(
        a.out,
        "adjust_sweep",
        {"commit": source_commit(), "settings": vars(a) | {"out": str(a.out)}, "cases": cases, "policies": policies},
    )
    print(f"wrote {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())

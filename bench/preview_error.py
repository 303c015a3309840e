"""``couture bench preview_error``: is a preview's error estimate a distance?

Each predicted drape carries an estimate of its distance from the true
equilibrium (``Predictor.distance_of``: the largest vertex motion of a
chord-Newton correction K⁻¹ F(x_pred; X(d)), K the factor at the equilibrium
the prediction started from, followed, where it pulls friction anchors beyond
their Coulomb cone, by rounds that let them slip; ``couture.sensitivity.distance``;
the held-friction chord step alone is reported beside it). This bench checks it against the truth over a
set of edits: the default skirt and the dress on the mannequin, friction on,
each sloper parameter in ``--params`` changed by each of ``--steps`` (both
signs). Per edit:

- the prediction as the node makes it right after a press (linear: the
  cache holds only the equilibrium), with the node's configuration (friction
  state rebuilt from the drape, exact linearisation, no floor);
- the truth: Newton from the prediction with the solver's own friction state
  of the equilibrium (what the solver node does on release), to ``--tol``;
- true error = largest vertex distance between prediction and truth, and the
  ratio estimate / true error; also the error of a frictionless
  linearisation of the same equilibrium (what the node did before).

Writes a table to stdout and ``preview_error.json`` (rows and the fraction of
edits whose estimate is within a factor 2 of the true error) to ``--out``.
"""

from __future__ import annotations

import argparse
import math
import platform
import time

import numpy as np

from bench import add_out_arg, source_commit, write_results
from couture.pattern.io import EXAMPLES

GARMENTS = {"skirt": "default_skirt.json", "dress": "dress.json"}
PARAMS = {"skirt": ("length", "flare", "hip_ease", "waist_ease"), "dress": ("length", "hip_ease", "waist_ease")}


def drape(kind: str, vertices: int, tol: float):
    """(design, remesh result, model holding the solver's friction state, x) of a converged drape."""
    from couture.cloth.model import ClothModel
    from couture.pattern.io import load_design
    from couture.pattern.validate import validate
    from couture.remesh import mesh_pattern
    from couture.solvers import get_solver
    from couture.solvers.service import scene_from_design

    design = load_design(EXAMPLES / GARMENTS[kind])
    res = mesh_pattern(validate(design), vertices, level="coarse")
    model = ClothModel(res.mesh, design.fabric, scene_from_design(design))
    # from the placement with friction at once, as the solver node drapes a coarse level
    r = get_solver("newton").solve(model, res.mesh.x0.copy(), tol=tol, max_seconds=120, friction_after=math.inf)
    if not r.converged:
        raise RuntimeError(f"{kind}: the drape did not converge ({r.diagnosis})")
    return design, res, model, r.x


def run(
    kind: str, vertices: int, params, steps, tol: float, friction_after: float = 0.01, friction_every: int = 5
) -> list[dict]:
    from couture.pattern.edit import edit_jacobian
    from couture.remesh import build_coordinates
    from couture.remesh import psi as remesh_psi
    from couture.sensitivity import Predictor
    from couture.sensitivity.predictor import default_model_at
    from couture.solvers import get_solver
    from couture.solvers.service import carries_anchors

    design, res, model, x = drape(kind, vertices, tol)
    solver_state = model.friction_state()
    coords = build_coordinates(res, "pmvc")
    X0 = model.X.copy()
    rows = []
    for param in params:
        psi = remesh_psi(coords, edit_jacobian(design, f"param:{param}"))
        node_model = default_model_at(model, X0)  # the node's own copy: its friction state is rebuilt
        p = Predictor(method="linear")
        p.set_equilibrium(node_model, x)
        info = p.refactor()
        p.press(psi)
        bare = default_model_at(model, X0)
        bare.release_friction()
        q = Predictor(method="linear", friction=False)
        q.set_equilibrium(bare, x)
        q.press(psi)
        for step in steps:
            for sign in (1.0, -1.0):
                d = np.array([sign * step, 0.0])
                t0 = time.perf_counter()
                pred = p.drag(d, error_estimate=True)
                est_s = pred.residual_s
                truth_model = default_model_at(model, p.rest_at(d))
                truth_model.set_friction_state(solver_state)
                t1 = time.perf_counter()
                newton = get_solver("newton", friction_after=friction_after, friction_every=friction_every)
                # as the solver node: a model carrying its drape's anchors keeps them (a warm start)
                at_once = math.inf if carries_anchors(truth_model) else None
                r = newton.solve(truth_model, pred.x.copy(), tol=tol, max_seconds=60, friction_after=at_once)
                solve_s = time.perf_counter() - t1
                true = float(np.max(np.linalg.norm(pred.x - r.x, axis=1)))
                bare_err = float(np.max(np.linalg.norm(q.drag(d, error_estimate=False).x - r.x, axis=1)))
                ratio = pred.error_m / true if true > 0 else float("inf")
                est = p.last_distance
                chord = est.chord if est is not None else float("nan")
                rows.append(
                    {
                        "garment": kind,
                        "vertices": int(model.n),
                        "param": param,
                        "dg_mm": 1e3 * float(d[0]),
                        "estimate_mm": 1e3 * pred.error_m,
                        "true_error_mm": 1e3 * true,
                        "ratio": ratio,
                        "within_2x": bool(0.5 <= ratio <= 2.0),
                        "chord_estimate_mm": 1e3 * chord,
                        "chord_ratio": chord / true if true > 0 else float("inf"),
                        "estimate_slipped": est.slipped if est is not None else 0,
                        "estimate_rounds": est.rounds if est is not None else 0,
                        "estimate_cg_iterations": est.cg_iterations if est is not None else 0,
                        "estimate_evaluations": est.evaluations if est is not None else 0,
                        "estimate_factorizations": est.factorizations if est is not None else 0,
                        "frictionless_linearisation_error_mm": 1e3 * bare_err,
                        "relative_residual": pred.error_estimate,
                        "estimate_ms": 1e3 * est_s,
                        "truth_converged": bool(r.converged),
                        "truth_residual": float(r.residual),
                        "truth_slipped": int(r.stats.get("slipped", 0)),
                        "truth_s": solve_s,
                        "regularization": info.regularization,
                        "friction_sticking": p.friction_held.sticking,
                        "friction_sliding": p.friction_held.sliding,
                        "wall_s": time.perf_counter() - t0,
                    }
                )
    return rows


def summarize(rows: list[dict]) -> dict:
    ok = [r for r in rows if r["truth_converged"]]
    ratios = np.array([r["ratio"] for r in ok], dtype=float)
    within = float(np.mean([r["within_2x"] for r in ok])) if ok else float("nan")
    return {
        "edits": len(rows),
        "truth_converged": len(ok),
        "within_2x_fraction": within,
        "goal_within_2x_fraction": 0.9,
        "ratio_median": float(np.median(ratios)) if len(ratios) else float("nan"),
        "ratio_p10": float(np.percentile(ratios, 10)) if len(ratios) else float("nan"),
        "ratio_p90": float(np.percentile(ratios, 90)) if len(ratios) else float("nan"),
        "underestimates_2x": int(np.sum(ratios < 0.5)),
        "overestimates_2x": int(np.sum(ratios > 2.0)),
        "chord_within_2x_fraction": float(np.mean([0.5 <= r["chord_ratio"] <= 2.0 for r in ok]))
        if ok
        else float("nan"),
        "estimate_ms_median": float(np.median([r["estimate_ms"] for r in rows])) if rows else float("nan"),
        "estimate_evaluations_median": float(np.median([r["estimate_evaluations"] for r in rows])) if rows else 0.0,
        "estimate_cg_iterations_median": float(np.median([r["estimate_cg_iterations"] for r in rows])) if rows else 0.0,
        "by_garment": {
            g: {
                "edits": len(gr),
                "within_2x_fraction": float(np.mean([r["within_2x"] for r in gr])),
                "ratio_median": float(np.median([r["ratio"] for r in gr])),
            }
            for g in sorted({r["garment"] for r in ok})
            for gr in [[r for r in ok if r["garment"] == g]]
        },
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench preview_error", description=__doc__.split("\n\n")[0])
    ap.add_argument("--garments", default="skirt,dress", help="comma-separated: skirt, dress")
    ap.add_argument("--vertices", type=int, default=400, help="mesh size of each garment")
    ap.add_argument("--steps", default="0.002,0.005,0.01,0.02", help="parameter changes [m], each with both signs")
    ap.add_argument("--params", default="", help="comma-separated sloper options (default: a set per garment)")
    ap.add_argument("--tol", type=float, default=1e-8, help="relative residual of the drape and the truths")
    ap.add_argument(
        "--friction-after",
        type=float,
        default=0.01,
        help="the truth's Newton keeps the anchors when the prediction's relative residual is below this "
        "(the solver's default 0.01, as the solver node does for a warm start from a prediction: above it, "
        "it lets the cloth settle frictionless first); a huge value keeps them always",
    )
    ap.add_argument(
        "--friction-every",
        type=int,
        default=5,
        help="the truth's Newton lets over-pulled anchors slip every this many iterations (the solver's "
        "default 5); a huge value lets them slip only at a balance that breaks the Coulomb cone",
    )
    ap.add_argument("--name", default="preview_error", help="results file NAME.json")
    add_out_arg(ap)
    a = ap.parse_args(argv)
    steps = [float(s) for s in a.steps.split(",")]
    rows: list[dict] = []
    for kind in a.garments.split(","):
        params = a.params.split(",") if a.params else PARAMS[kind]
        rows += run(kind, a.vertices, params, steps, a.tol, a.friction_after, a.friction_every)
    hdr = f"{'garment':7} {'param':10} {'dg mm':>6} {'est mm':>8} {'true mm':>8} {'ratio':>6} {'2x':>3} {'no-fric mm':>10} {'slips':>5}"
    print(hdr)
    for r in rows:
        print(
            f"{r['garment']:7} {r['param']:10} {r['dg_mm']:6.1f} {r['estimate_mm']:8.3f} {r['true_error_mm']:8.3f} "
            f"{r['ratio']:6.2f} {'y' if r['within_2x'] else 'n':>3} {r['frictionless_linearisation_error_mm']:10.3f} "
            f"{r['truth_slipped']:5d}"
        )
    summary = summarize(rows)
    print(summary)
    path = write_results(
        a.out,
        a.name,
        {
            "summary": summary,
            "rows": rows,
            "truth_friction_after": a.friction_after if math.isfinite(a.friction_after) else "inf",
            "truth_friction_every": a.friction_every,
            "machine": platform.platform(),
            "commit": source_commit(),
        },
    )
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

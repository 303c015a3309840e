"""Did an adjustment meet the goal, and if not, why: measured, in words for the user.

:func:`assess` judges a :class:`~couture.adjust.pipeline.CaseResult`
against :data:`~couture.adjust.settings.GOAL` (Hausdorff distance, mean
stretch, re-simulated patterns, seconds) and, for every figure it misses,
measures where and names the cause:

- the Hausdorff distance: where the worst point is (at the hem, at the
  edited loop, elsewhere), how far the cloth is from the body there in the
  target and in the drape (hanging free: a fold that settles elsewhere; on
  the body: the body decides), and how well that region's triangles already
  match the target's (a region whose triangles match but whose place does
  not is a fold or a slide, which matching triangle shapes cannot correct);
- the stretch: where the stretched triangles are (on the body or hanging
  free) and whether the target itself asks the cloth to be shorter than
  the source drape was (a target the fabric cannot reach without stretch);
- a drape that did not converge, the solve budget, the time.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .fixed_point import MANNEQUIN_HEIGHT
from .geometry import SurfaceDistance, frames3, stretch, surface_samples
from .settings import GOAL, Goal

ON_BODY = 0.015
"""[m] cloth within this of the skin rests on the body (the solver's contact layer is 10 mm)"""
NEAR = 0.05
"""[m] a point this close (in height) to the hem or the edited loop is 'at' it"""


@dataclass
class Verdict:
    met: bool
    hausdorff_pct: float
    stretch: float
    solves: int
    seconds: float
    reasons: list[str] = field(default_factory=list)
    """one sentence per figure missed: what was measured, where, and why"""
    worst: dict = field(default_factory=dict)
    """the worst point: position [m], distance [m], height above the hem [m], body distances [m]"""

    def text(self) -> str:
        figures = (
            f"Hausdorff {self.hausdorff_pct:.2f} % of height, stretch {self.stretch:.3f}, "
            f"{self.solves} re-simulated patterns, {self.seconds:.1f} s"
        )
        if self.met:
            return f"goal met: {figures}"
        return f"goal NOT met ({figures}): " + "; ".join(self.reasons)

    def as_dict(self) -> dict:
        return {
            "met": self.met,
            "hausdorff_pct": self.hausdorff_pct,
            "stretch": self.stretch,
            "solves": self.solves,
            "seconds": self.seconds,
            "reasons": list(self.reasons),
            "worst": self.worst,
        }


def _near(value: float, goal: float, digits: int = 2) -> str:
    """``value`` with enough digits to differ from ``goal`` when printed (1.003 %, not 1.00 %)."""
    while digits < 6 and round(value, digits) == round(goal, digits):
        digits += 1
    return f"{value:.{digits}f}"


def worst_point(x_target: np.ndarray, x: np.ndarray, tris: np.ndarray) -> dict:
    """The sample (vertex, edge midpoint or centroid) of either surface farthest from the other:
    where the Hausdorff distance is attained."""
    pa = surface_samples(x_target, tris)
    qa, da, _ = SurfaceDistance(x, tris).closest(pa)
    pb = surface_samples(x, tris)
    qb, db, _ = SurfaceDistance(x_target, tris).closest(pb)
    if da.max() >= db.max():
        i = int(np.argmax(da))
        return {"on": "target", "target_point": pa[i], "drape_point": qa[i], "distance": float(da[i])}
    i = int(np.argmax(db))
    return {"on": "drape", "target_point": qb[i], "drape_point": pb[i], "distance": float(db[i])}


def closing_in(case, last: int = 2, gain: float = 0.1) -> dict | None:
    """Was the Hausdorff distance still falling when the solves ended? Over the run's
    re-simulations in order (the start, each update, each gradient step's trials), the best of
    the ``last`` ones against the best before them: falling by more than ``gain`` (a tenth)
    says the budget, not the method, ended the run; less says the method had stalled there.
    None when the run had too few solves to tell."""
    seq = [h.hausdorff_pct for h in case.result.history]
    for g in case.gradient:
        seq += [g.hausdorff_pct if g.accepted else float("inf")] * max(1, g.solves)
    seq = [v if np.isfinite(v) else float("inf") for v in seq]
    if len(seq) <= last:
        return None
    before, recent = min(seq[:-last]), min(seq[-last:])
    if not np.isfinite(before):
        return None
    falling = recent < (1.0 - gain) * before
    text = (
        f"still closing in when the {len(seq)} re-simulations were spent (best {before:.2f} % before the last "
        f"{last}, {recent:.2f} % in them)"
        if falling
        else (
            f"stalled: the best of the last {last} of {len(seq)} re-simulations ({recent:.2f} %) is within a tenth "
            f"of the best before them ({before:.2f} %)"
            if np.isfinite(recent)
            else f"stalled: none of the last {last} of {len(seq)} re-simulations came closer than {before:.2f} %"
        )
    )
    return {"falling": bool(falling), "best_before_pct": before, "best_last_pct": recent, "text": text}


def assess(case, goal: Goal = GOAL, body=None) -> Verdict:
    """The verdict on ``case`` (a CaseResult): ``body`` is the scene's body
    as a signed distance callable (points (k, 3) -> (k,) [m]), or None (the
    reasons then say nothing about the body)."""
    m = case.mesh
    tris = m.tris
    xt, x = case.target.x, case.x_out
    fin = case._final_metrics()
    h_pct, s_mean = fin["hausdorff_pct"], fin["stretch"]
    solves = case.solves
    seconds = float(case.timings.get("edit_to_pattern", 0.0))
    reasons: list[str] = []
    worst: dict = {}

    chosen = case.result.history[case.result.best]
    unconverged = [] if chosen.converged or any(g.accepted for g in case.gradient) else [chosen.k]
    if not case.source_solve.get("converged", True):
        why = case.source_solve.get("diagnosis") or f"residual {case.source_solve.get('residual', float('nan')):.1e}"
        reasons.append(f"the source drape did not converge ({why}): the target is an edit of an unsettled drape")
    if unconverged:
        reasons.append(
            f"the re-simulation of iteration(s) {unconverged} did not converge within its time: its distance and "
            "stretch are not an equilibrium's"
        )

    if h_pct > goal.hausdorff_pct:
        w = worst_point(xt, x, tris)
        y_hem = float(xt[:, 1].min())
        p = w["target_point"] if w["on"] == "target" else w["drape_point"]
        above_hem = float(p[1] - y_hem)
        y_loop = case.target.info.get("y_loop")
        where = (
            "at the hem"
            if above_hem < NEAR
            else (
                "at the edited loop"
                if case.edit == "waist" and y_loop is not None and abs(p[1] - y_loop) < NEAR
                else f"{100 * above_hem:.0f} cm above the hem"
            )
        )
        worst = {
            "on": w["on"],
            "distance_m": w["distance"],
            "target_point_m": [float(v) for v in w["target_point"]],
            "drape_point_m": [float(v) for v in w["drape_point"]],
            "above_hem_m": above_hem,
        }
        # how well the triangles round the worst point already match the target's
        near = np.linalg.norm(xt[tris].mean(axis=1) - w["target_point"], axis=1) < 0.05
        s_local = float(stretch(frames3(xt, tris[near]), frames3(x, tris[near])).mean()) if near.any() else s_mean
        worst["stretch_near"] = s_local
        how = ""
        if body is not None:
            d_t, d_x = (float(v) for v in body(np.array([w["target_point"], w["drape_point"]])))
            worst["body_distance_target_m"], worst["body_distance_drape_m"] = d_t, d_x
            if d_t > ON_BODY and d_x > ON_BODY:
                how = (
                    f"the cloth hangs free there ({100 * d_t:.1f} cm from the body in the target, {100 * d_x:.1f} cm "
                    "in the drape): "
                    + (
                        "a fold settles elsewhere than the target's, with the triangles round it matching the "
                        f"target's (stretch {s_local:.3f}): their shapes, which the fixed point matches, do not "
                        "say where a fold lies"
                        if s_local >= goal.stretch
                        else f"the triangles round it still differ from the target's (stretch {s_local:.3f})"
                    )
                )
            elif d_t <= ON_BODY and d_x <= ON_BODY:
                how = "the cloth rests on the body there in both: the drape slid along the body"
            else:
                how = f"the target is {100 * d_t:.1f} cm from the body there and the drape {100 * d_x:.1f} cm: " + (
                    "the drape bridges a hollow the target follows"
                    if d_x > d_t
                    else "the drape falls onto the body where the target stands off it"
                )
        trend = closing_in(case)
        reasons.append(
            f"Hausdorff {_near(h_pct, goal.hausdorff_pct)} % > {goal.hausdorff_pct:g} %: the worst point ({1e3 * w['distance']:.0f} mm) is "
            f"{where}"
            + (f"; {how}" if how else f" (triangles round it: stretch {s_local:.3f})")
            + (f"; {trend['text']}" if trend else "")
        )
        if trend:
            worst["trend"] = {k: v for k, v in trend.items() if k != "text"}

    if s_mean < goal.stretch:
        S = stretch(frames3(xt, tris), frames3(x, tris))
        bad = S < goal.stretch
        share = ""
        if body is not None and bad.any():
            d = body(x[tris[bad]].mean(axis=1))
            on = float(np.mean(d <= ON_BODY))
            share = f"; {100 * on:.0f} % of the triangles below {goal.stretch:g} rest on the body"
        # does the target ask for cloth shorter than the source drape had? (a target needing stretch)
        s_src = float(stretch(frames3(xt, tris), frames3(case.x_source, tris)).mean())
        reasons.append(
            f"mean stretch {_near(s_mean, goal.stretch, 3)} < {goal.stretch:g}: {100 * float(bad.mean()):.0f} % of the triangles are "
            f"below it{share}; the source drape itself is at {s_src:.3f} against the target"
        )

    if solves > goal.solves:
        reasons.append(f"{solves} re-simulated patterns > {goal.solves}")
    if seconds > goal.seconds:
        solve_s = sum(h.simulate_s for h in case.result.history) + sum(g.seconds for g in case.gradient)
        reasons.append(
            f"{seconds:.0f} s > {goal.seconds:g} s from the edit to the pattern ({solve_s:.0f} s of it in the solves "
            f"of a {m.n_vertices}-vertex mesh)"
        )
    met = (
        h_pct <= goal.hausdorff_pct
        and s_mean >= goal.stretch
        and solves <= goal.solves
        and seconds <= goal.seconds
        and not unconverged
    )
    return Verdict(met, h_pct, s_mean, solves, seconds, reasons, worst)


def body_for(design):
    """The scene's body as a signed distance callable, or None (no body)."""
    if not design.scene.body:
        return None
    from couture import bodies
    from couture.cloth.body import load_mannequin_sdf

    sdf = load_mannequin_sdf(verbose=False, name=bodies.use(design.body))
    return lambda points: sdf.phi_grad(np.asarray(points, np.float64))[0]


__all__ = ["MANNEQUIN_HEIGHT", "Verdict", "assess", "body_for", "closing_in", "worst_point"]

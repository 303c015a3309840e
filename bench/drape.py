"""``couture bench drape``: every example design drapes from placement, how fast.

For each design in ``couture/pattern/examples/`` and each solver (Newton,
kinetic), the cascadic drape the solver node runs, in this process and through
the same code: :class:`couture.remesh.service.RemeshService` meshes the
design (coarse and fine levels, the fine one with its prolongation map),
:class:`couture.solvers.service.SolveService` solves the coarse level from
the placement, prolongates and polishes, then solves the fine level.

Reported per design x solver:

- time to a relative residual of 1e-4 [s]: the coarse level's solve (to the
  service's coarse tolerance), the fine level's (the first fine history
  sample at or below 1e-4) and the total from the first coarse iteration to
  that fine sample (prolongation and polish included);
- final residual, converged, iterations and steps per second per level;
- the linear algebra figures the solver's ``stats`` hold (factorizations and
  the time per factorization and per solve where the solver records those
  times; the stats key each figure comes from is named beside it);
- one residual-vs-time plot per design (both solvers, both levels).

Then a size sweep of the default skirt (fine level 2.5k to 40k vertices,
Newton), each size in a process of its own so that its peak resident memory
is its own: time to 1e-4, peak RSS, and the exponent of time against size
fitted by least squares in log-log, with a plot.

Numba compiles (or loads from its cache) on first use: one small drape per
solver runs first, and its time is reported apart, never in the figures.
Writes ``DIR/drape.json``, ``DIR/drape_<design>.png`` and
``DIR/drape_sweep.png``; ``DIR`` is ``--out`` (default ``bench/results``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import subprocess
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from bench import add_out_arg, child_env, module_command, source_commit, write_results
from couture.pattern.io import EXAMPLES
from couture.solvers import SOLVERS

TOL = 1e-4
"""relative residual the figures are timed to"""
GOALS = {
    "fine_total_s": 5.0,
    "fine_steps_per_s": 10.0,
    "coarse_steps_per_s": 50.0,
    "coarse_iterations": 60,
    "fine_iterations": 20,
}
"""targets on the 2-core reference machine: fine drape to 1e-4 from
scratch within 5 s, fine steps >= 10/s, coarse steps >= 50/s; coarse from
placement in <= 60 iterations, fine from its cascade start in <= 20"""
TAIL = 4
"""residual ratios printed for a level's last iterations (quadratic
convergence: each ratio about the residual before it, the order near 2)"""
SWEEP_SIZES = (2500, 5000, 10000, 20000, 40000)
"""fine-level vertex targets of the size sweep"""
HISTORY_POINTS = 400
"""residual history samples kept per level in the JSON (evenly thinned)"""


# -- one cascadic drape ---------------------------------------------------------------------------


def load(design: str) -> tuple[str, Any]:
    """(name, Design) for an example name (``dress``) or a pattern file path."""
    from couture.pattern.io import load_design

    path = Path(design)
    if not path.suffix:
        path = EXAMPLES / f"{design}.json"
    return path.stem, load_design(path)


FABRICS: dict[str, dict[str, float]] = {
    "design": {},
    "stiff": {"stretch_stiffness": 2000.0},
    "soft": {"stretch_stiffness": 10.0, "bend_stiffness": 1e-8},
}
"""fabric variants of ``--fabrics``: the design's own, and the ends of the
allowed ranges (couture.pattern.limits.FABRIC_LIMITS) the solver goals must
hold at: stiff 2000 N/m, very soft 10 N/m with 1e-8 N m bending"""


LIBRARY_MODULE = "couture.fabrics"
"""the fabric library (issue 30) whose names ``--fabrics`` also takes"""


def fabric_library() -> dict[str, Any]:
    """name -> ``schemas.design.Fabric`` of every fabric in the library
    (``couture.fabrics``, imported only when a name is not one of
    ``FABRICS``); a LookupError naming the module where it is missing."""
    import importlib

    try:
        lib = importlib.import_module(LIBRARY_MODULE)
    except ImportError as e:
        raise LookupError(f"the fabric library {LIBRARY_MODULE} is not importable here ({e})") from None
    return {name: lib.get(name) for name in lib.names()}


def check_fabrics(names: list[str], library: Mapping[str, Any] | None = None) -> Mapping[str, Any]:
    """The library the names need (empty when all are ``FABRICS`` variants),
    ``library`` or else ``fabric_library()``; a ValueError naming every
    unknown name and the choices (or the missing library)."""
    extra = [n for n in names if n not in FABRICS]
    if not extra:
        return {} if library is None else library
    if library is None:
        try:
            library = fabric_library()
        except LookupError as e:
            raise ValueError(f"--fabrics {', '.join(extra)}: not a variant ({', '.join(FABRICS)}) and {e}") from None
    unknown = [n for n in extra if n not in library]
    if unknown:
        raise ValueError(
            f"--fabrics: unknown {', '.join(unknown)}; choose from {', '.join([*FABRICS, *sorted(library)])}"
        )
    return library


def with_options(
    design: Any,
    *,
    friction: bool | None = None,
    fine_vertices: int | None = None,
    fabric: str = "design",
    library: Mapping[str, Any] | None = None,
) -> Any:
    """A copy of ``design`` with friction switched, another fine-level size
    and/or another fabric: a variant of ``FABRICS``, or a library fabric
    (``library`` [name -> Fabric], default ``fabric_library()``) that replaces
    the design's fabric whole (the panels' own ``panel_fabrics``, a
    waistband's interfacing say, stay)."""
    import msgspec

    if fabric not in FABRICS:
        lib = check_fabrics([fabric], library)
        design = msgspec.structs.replace(design, fabric=lib[fabric])
    elif FABRICS[fabric]:
        design = msgspec.structs.replace(design, fabric=msgspec.structs.replace(design.fabric, **FABRICS[fabric]))
    if friction is not None:
        design = msgspec.structs.replace(design, scene=msgspec.structs.replace(design.scene, friction=friction))
    if fine_vertices is not None:
        design = msgspec.structs.replace(
            design, resolution=msgspec.structs.replace(design.resolution, fine_vertices=int(fine_vertices))
        )
    return design


def convergence_tail(history: list[tuple[float, float]], k: int = TAIL) -> dict[str, Any]:
    """The last ``k`` residual ratios r_{i+1}/r_i of a level and the order
    estimate log(r_{i+1}/r_i) / log(r_i/r_{i-1}) of its last step (2 for
    Newton's quadratic convergence, 1 for linear). A ratio above 1 in the
    tail is a friction event (a slip or a balance that moved the anchors)."""
    rs: list[float] = []
    for _, r in history:
        if r > 0.0 and (
            not rs or abs(r - rs[-1]) > 1e-9 * rs[-1]
        ):  # a state recorded twice (a balance, the verdict) once
            rs.append(r)
    tail = rs[-k - 1 :]
    ratios = [b / a for a, b in zip(tail, tail[1:], strict=False)]
    order = None
    if len(ratios) >= 2 and 0.0 < ratios[-2] != 1.0 and ratios[-1] > 0.0:
        order = float(np.log(ratios[-1]) / np.log(ratios[-2]))
    return {"residuals": tail, "ratios": ratios, "order": order}


def time_to(history: list[tuple[float, float]], tol: float) -> float | None:
    """[s] of the first history sample with residual <= tol (None if never)."""
    for t, r in history:
        if r <= tol:
            return float(t)
    return None


def _thin(history: list[tuple[float, float]], n: int = HISTORY_POINTS) -> list[list[float]]:
    if len(history) > n:
        keep = np.unique(np.linspace(0, len(history) - 1, n).round().astype(int))
        history = [history[i] for i in keep]
    return [[float(t), float(r)] for t, r in history]


def _plain(v: Any) -> Any:
    """JSON-safe copy of a stats value (numpy scalars to numbers, non-finite to None)."""
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, str):
        return v
    return repr(v)


FACTOR_TIME_KEYS = ("factor_s", "factorization_s", "precond_s")
"""stats keys that hold the total time spent factorizing, first present wins
(kinetic with its direct preconditioner books its factorizations as precond_s)"""


def linear_algebra(stats: dict) -> dict[str, Any]:
    """Per-factorization and per-solve times from what a solver's stats hold.

    Each figure names the keys it comes from, since solvers book time under
    different names; a figure whose keys are absent is left out rather than
    estimated."""
    out: dict[str, Any] = {}
    nf = stats.get("factorizations")
    if isinstance(nf, (int, np.integer)):
        out["factorizations"] = int(nf)
        key = next((k for k in FACTOR_TIME_KEYS if isinstance(stats.get(k), (int, float))), None)
        if key is not None and nf > 0:
            out["s_per_factorization"] = float(stats[key]) / int(nf)
            out["s_per_factorization_from"] = f"{key}/factorizations"
    steps = stats.get("steps")
    for time_key, count_keys in (
        ("solve_s", ("solves", "linear_solves", "steps")),
        ("linear_solve_s", ("linear_solves", "solves", "steps")),
    ):
        if not isinstance(stats.get(time_key), (int, float)):
            continue
        count_key = next((k for k in count_keys if isinstance(stats.get(k), (int, np.integer)) and stats[k] > 0), None)
        if count_key is not None:
            out["s_per_solve"] = float(stats[time_key]) / int(stats[count_key])
            out["s_per_solve_from"] = f"{time_key}/{count_key}"
            break
    if isinstance(steps, (int, np.integer)):
        out["steps"] = int(steps)
    if isinstance(stats.get("cg_iterations"), (int, np.integer)):
        out["cg_iterations"] = int(stats["cg_iterations"])
    return out


def linear_solves(iterations: int, stats: dict) -> int:
    """The issue's count of iterations: one per linear solve of the level's
    system, retries and continuation steps included. Newton: its
    factorizations, failed ones too, and the steps of its dynamics phases
    (``iterations`` counts one per accepted Newton step); other solvers: their
    steps."""
    if isinstance(stats.get("factorizations"), (int, np.integer)):
        n = int(stats["factorizations"]) + int(stats.get("factorization_failures", 0) or 0)
        return max(n, int(iterations)) + int(stats.get("dynamics_steps", 0) or 0)
    return int(iterations)


def drape_case(
    design: Any,
    method: str,
    *,
    max_seconds: float = 120.0,
    levels: tuple[str, ...] = ("coarse", "fine"),
    progress: bool = False,
    label: str = "",
) -> dict[str, Any]:
    """One cascadic drape from placement, as the solver node runs it.

    ``max_seconds`` [s] caps each level's solve. Returns per level: vertices,
    residual, converged, iterations, wall time [s], steps per second, time to
    1e-4 [s], warm start, diagnosis, linear algebra figures, raw stats and
    the (thinned) residual history [(s, residual)]; plus ``time_to_tol_s``
    {coarse, fine, total} and the remeshing time [s]."""
    from couture.remesh.service import RemeshService
    from couture.solvers.service import LevelRun, SolveService

    t0 = time.perf_counter()
    updates = RemeshService().set_design(design, 1)
    remesh_s = time.perf_counter() - t0
    service = SolveService(method=method)
    service.max_seconds = {level: float(max_seconds) for level in service.max_seconds}
    service.set_design(design)
    for up in updates:
        prolong = None
        if up.fine_parent_tri is not None and up.fine_bary is not None:  # the fine level's, as the solver node takes it
            prolong = (up.fine_parent_tri, up.fine_bary)
        service.set_mesh(up.level, up.mesh, up.mesh_generation, prolong)

    ends: dict[str, float] = {}

    def on_level(run: LevelRun) -> None:
        ends[run.level] = time.perf_counter()

    def on_progress(level: str, it: int, x: np.ndarray, res: float) -> None:
        print(
            f"    {label} {level}: iteration {it}, residual {res:.2e}, {time.perf_counter() - t_run:.0f} s",
            file=sys.stderr,
            flush=True,
        )

    t_run = time.perf_counter()
    runs = service.run(
        levels=levels, on_level=on_level, on_progress=on_progress if progress else None, progress_period_s=10.0
    )
    out: dict[str, Any] = {"remesh_s": remesh_s, "tolerances": dict(service.tol), "levels": {}}
    for run in runs:
        r = run.result
        # [s] from the start of the cascade to the start of this level's solve
        start = ends[run.level] - r.wall_time - t_run
        tt = time_to(r.history, TOL)
        out["levels"][run.level] = {
            "vertices": int(r.x.shape[0]),
            "residual": float(r.residual),
            "converged": bool(r.converged),
            "iterations": int(r.iterations),
            "solves": linear_solves(r.iterations, r.stats),
            "wall_time_s": float(r.wall_time),
            "steps_per_s": r.iterations / r.wall_time if r.wall_time > 0 else None,
            "time_to_1e-4_s": tt,
            "starts_at_s": start,
            "warm_start": run.warm_start,
            "diagnosis": r.diagnosis,
            "linear_algebra": linear_algebra(r.stats),
            "stats": {k: _plain(v) for k, v in r.stats.items()},
            "history": _thin(r.history),
            "tail": convergence_tail(r.history),
        }
    lv = out["levels"]
    fine = lv.get("fine")
    # coarse: the whole coarse solve, which stops at the service's coarse
    # tolerance (looser than 1e-4 on purpose: the fine level refines it)
    out["time_to_tol_s"] = {
        "coarse": lv["coarse"]["wall_time_s"] if "coarse" in lv else None,
        "fine": fine["time_to_1e-4_s"] if fine else None,
        "total": fine["starts_at_s"] + fine["time_to_1e-4_s"] if fine and fine["time_to_1e-4_s"] is not None else None,
    }
    return out


def warm_up(solvers: list[str]) -> dict[str, float]:
    """Compile (or load from numba's cache) every kernel a drape uses, on a
    small skirt per solver; returns the seconds each took."""
    from schemas.design import Design, Resolution, Sloper

    small = Design(sloper=Sloper(kind="skirt"), resolution=Resolution(coarse_vertices=300, fine_vertices=900))
    took = {}
    for method in solvers:
        t0 = time.perf_counter()
        drape_case(small, method, max_seconds=60.0)
        took[method] = time.perf_counter() - t0
    return took


# -- size sweep -----------------------------------------------------------------------------------


def sweep_one(
    fine_vertices: int, method: str, max_seconds: float, design_name: str = "default_skirt"
) -> dict[str, Any]:
    """One size of the sweep, in this process (run it in a fresh one): warm
    up, drape the design at ``fine_vertices``, add this process's peak
    resident memory [MiB]."""
    warm = warm_up([method])
    _, design = load(design_name)
    case = drape_case(with_options(design, fine_vertices=fine_vertices), method, max_seconds=max_seconds)
    fine = case["levels"]["fine"]
    # ru_maxrss is in KiB on Linux
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {
        "target": fine_vertices,
        "vertices": fine["vertices"],
        "time_to_1e-4_s": case["time_to_tol_s"],
        "fine_converged": fine["converged"],
        "fine_residual": fine["residual"],
        "fine_iterations": fine["iterations"],
        "fine_steps_per_s": fine["steps_per_s"],
        "peak_rss_mib": peak,
        "warmup_s": warm[method],
        "remesh_s": case["remesh_s"],
    }


def sweep(
    sizes: list[int], method: str, max_seconds: float, timeout_s: float, design_name: str = "default_skirt"
) -> dict[str, Any]:
    """Every size in its own process; the time-vs-size exponent by least squares in log-log."""
    rows: list[dict[str, Any]] = []
    for n in sizes:
        print(f"  sweep: {n} fine vertices ({method})...", file=sys.stderr, flush=True)
        cmd = module_command(
            "drape",
            "--sweep-one",
            str(n),
            "--solvers",
            method,
            "--max-seconds",
            str(max_seconds),
            "--sweep-design",
            design_name,
        )
        try:
            p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s, env=child_env())
        except subprocess.TimeoutExpired:
            rows.append({"target": n, "error": f"no result within {timeout_s:g} s"})
            continue
        if p.returncode != 0:
            rows.append({"target": n, "error": f"exit {p.returncode}: {p.stderr.strip().splitlines()[-1:]}"})
            continue
        row = json.loads(p.stdout.strip().splitlines()[-1])
        rows.append(row)
        t = row["time_to_1e-4_s"]["total"]
        print(
            f"  sweep: {row['vertices']} vertices: {'-' if t is None else f'{t:.2f} s'} to 1e-4, "
            f"peak {row['peak_rss_mib']:.0f} MiB",
            file=sys.stderr,
            flush=True,
        )
    pts = [
        (r["vertices"], r["time_to_1e-4_s"]["fine"])
        for r in rows
        if "error" not in r and r["time_to_1e-4_s"]["fine"] is not None and r["time_to_1e-4_s"]["fine"] > 0
    ]
    fit = None
    if len(pts) >= 2:
        slope, intercept = np.polyfit(np.log([p[0] for p in pts]), np.log([p[1] for p in pts]), 1)
        fit = {
            "exponent": float(slope),
            "coefficient_s": float(math.exp(intercept)),
            "of": "fine time to 1e-4 [s] = coefficient * vertices^exponent",
            "points": len(pts),
        }
    return {"solver": method, "design": design_name, "rows": rows, "fit": fit}


# -- plots ----------------------------------------------------------------------------------------


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import logging

    import matplotlib.pyplot as plt

    logging.getLogger("matplotlib").setLevel(logging.WARNING)  # its font cache notice is no result
    return plt


def plot_design(path: Path, name: str, cases: list[dict[str, Any]]) -> None:
    """Residual against time since the cascade started, one line per solver and level."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    colours = {"newton": "tab:blue", "kinetic": "tab:orange", "verlet": "tab:green"}
    for case in cases:
        for level, style in (("coarse", ":"), ("fine", "-")):
            lv = case["levels"].get(level)
            if not lv or not lv["history"]:
                continue
            h = np.asarray(lv["history"])
            fabric = case.get("fabric", "design")
            label = (
                f"{case['solver']} {level}"
                + ("" if fabric == "design" else f", {fabric}")
                + ("" if case["friction"] else ", frictionless")
            )
            ax.semilogy(
                lv["starts_at_s"] + h[:, 0],
                np.maximum(h[:, 1], 1e-16),
                style,
                color=colours.get(case["solver"]),
                alpha=1.0 if case["friction"] else 0.5,
                label=label,
            )
    ax.axhline(TOL, color="k", lw=0.8, ls="--", label="1e-4")
    ax.set_xlabel("time since the coarse solve started [s]")
    ax.set_ylabel("relative force residual")
    ax.set_title(f"{name}: cascadic drape from placement")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_sweep(path: Path, sw: dict[str, Any]) -> None:
    """Fine time to 1e-4 and peak memory against fine-level vertices (log-log), with the fit."""
    plt = _pyplot()
    rows = [r for r in sw["rows"] if "error" not in r]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    n = np.array([r["vertices"] for r in rows], float)
    t = np.array([np.nan if r["time_to_1e-4_s"]["fine"] is None else r["time_to_1e-4_s"]["fine"] for r in rows])
    a1.loglog(n, t, "o-", label=f"{sw['solver']}, fine level")
    if sw["fit"] is not None and len(n):
        f = sw["fit"]
        nn = np.geomspace(n.min(), n.max(), 20)
        a1.loglog(nn, f["coefficient_s"] * nn ** f["exponent"], "k--", label=f"fit: n^{f['exponent']:.2f}")
    a1.set_xlabel("fine-level vertices")
    a1.set_ylabel("time to 1e-4 [s]")
    a1.grid(True, which="both", alpha=0.3)
    a1.legend()
    a2.loglog(n, [r["peak_rss_mib"] for r in rows], "s-", color="tab:red")
    a2.set_xlabel("fine-level vertices")
    a2.set_ylabel("peak resident memory [MiB]")
    a2.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"{sw['design']}: cost of a finer mesh")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


# -- table and command line -----------------------------------------------------------------------


def _f(v: float | None, fmt: str) -> str:
    return "-" if v is None else format(v, fmt)


def goals(case: dict[str, Any]) -> dict[str, bool | None]:
    """Which of the goals (GOALS) one case meets (None: not measured)."""
    lv, tt = case["levels"], case["time_to_tol_s"]
    fine_sps = lv.get("fine", {}).get("steps_per_s")
    coarse_sps = lv.get("coarse", {}).get("steps_per_s")
    return {
        "fine_total_s": None
        if "fine" not in lv
        else (tt["total"] is not None and tt["total"] <= GOALS["fine_total_s"]),
        "fine_steps_per_s": None if fine_sps is None else fine_sps >= GOALS["fine_steps_per_s"],
        "coarse_steps_per_s": None if coarse_sps is None else coarse_sps >= GOALS["coarse_steps_per_s"],
        "coarse_iterations": None if "coarse" not in lv else lv["coarse"]["solves"] <= GOALS["coarse_iterations"],
        "fine_iterations": None if "fine" not in lv else lv["fine"]["solves"] <= GOALS["fine_iterations"],
    }


def print_table(cases: list[dict[str, Any]]) -> None:
    print(
        f"{'design':15s} {'solver':8s} {'fric':4s} {'level':6s} {'n':>6s} {'residual':>9s} {'conv':>4s} "
        f"{'its':>5s} {'solves':>6s} {'s':>7s} {'its/s':>6s} {'to 1e-4':>8s} {'facts':>6s} {'s/fact':>7s} {'s/solve':>8s}"
    )
    for c in cases:
        for level, lv in c["levels"].items():
            la = lv["linear_algebra"]
            print(
                f"{c['design'] + ('' if c.get('fabric', 'design') == 'design' else '/' + c['fabric']):15s} "
                f"{c['solver']:8s} {'on' if c['friction'] else 'off':4s} {level:6s} "
                f"{lv['vertices']:6d} {lv['residual']:9.2e} {'yes' if lv['converged'] else 'NO':>4s} "
                f"{lv['iterations']:5d} {lv['solves']:6d} {lv['wall_time_s']:7.2f} {_f(lv['steps_per_s'], '6.1f')} "
                f"{_f(lv['time_to_1e-4_s'], '8.2f')} {la.get('factorizations', '-'):>6} "
                f"{_f(la.get('s_per_factorization'), '7.3f')} {_f(la.get('s_per_solve'), '8.4f')}"
                + (f"  [{lv['diagnosis']}]" if lv["diagnosis"] else "")
            )
            tail = lv.get("tail")
            if tail and tail["ratios"]:
                order = "-" if tail["order"] is None else f"{tail['order']:.2f}"
                print(
                    f"{'':15s} {'':8s} {'':4s} {'':6s} last residuals "
                    + " ".join(f"{r:.1e}" for r in tail["residuals"])
                    + ", ratios "
                    + " ".join(f"{q:.2g}" for q in tail["ratios"])
                    + f", order {order}"
                )
        tt = c["time_to_tol_s"]
        g = c["goals"]
        print(
            f"{'':15s} {'':8s} {'':4s} total to 1e-4: {_f(tt['total'], '.2f')} s "
            f"(goal <= {GOALS['fine_total_s']:g} s: {g['fine_total_s']}; fine >= {GOALS['fine_steps_per_s']:g} "
            f"its/s: {g['fine_steps_per_s']}; coarse >= {GOALS['coarse_steps_per_s']:g} its/s: "
            f"{g['coarse_steps_per_s']}; coarse <= {GOALS['coarse_iterations']} its: {g['coarse_iterations']}; "
            f"fine <= {GOALS['fine_iterations']} its: {g['fine_iterations']})"
        )
    sources = sorted(
        {
            f"{c['solver']}: s/fact = {lv['linear_algebra'].get('s_per_factorization_from', '-')}, "
            f"s/solve = {lv['linear_algebra'].get('s_per_solve_from', '-')}"
            for c in cases
            for lv in c["levels"].values()
        }
    )
    for line in sources:
        print(f"  ({line}, from the solver's stats)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="couture bench drape",
        description=__doc__.split("\n\n")[0],
        epilog="figures: time to 1e-4, residual, iterations, steps/s, factorizations; JSON and PNGs into --out",
    )
    ap.add_argument(
        "--designs",
        nargs="*",
        default=sorted(p.stem for p in EXAMPLES.glob("*.json")),
        help="example names or pattern files (default: every example; none: the sweep only)",
    )
    ap.add_argument("--solvers", nargs="+", default=["newton", "kinetic"], choices=list(SOLVERS))
    ap.add_argument("--levels", default="coarse,fine", help="levels to solve, comma separated (coarse first)")
    ap.add_argument("--frictionless", action="store_true", help="also drape every design with friction off")
    ap.add_argument(
        "--fabrics",
        default="design",
        help=f"fabrics, comma separated: variants {', '.join(FABRICS)} (stiff: 2000 N/m; soft: 10 N/m, 1e-8 N m) "
        "or fabric library names (`couture fabrics`), which replace the design's fabric",
    )
    ap.add_argument("--max-seconds", type=float, default=120.0, help="[s] cap on each level's solve")
    ap.add_argument(
        "--sizes",
        default=",".join(str(s) for s in SWEEP_SIZES),
        help="fine-level vertex targets of the default-skirt sweep, comma separated",
    )
    ap.add_argument("--sweep-solver", default="newton", choices=list(SOLVERS))
    ap.add_argument("--sweep-design", default="default_skirt", help="design of the size sweep")
    ap.add_argument("--no-sweep", action="store_true", help="skip the size sweep")
    add_out_arg(ap)
    ap.add_argument("--sweep-one", type=int, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    levels = tuple(s for s in a.levels.split(",") if s)

    if a.sweep_one is not None:  # a child of the sweep: one JSON line on stdout
        print(json.dumps(sweep_one(a.sweep_one, a.solvers[0], a.max_seconds, a.sweep_design)))
        return 0

    fabrics = [f for f in a.fabrics.split(",") if f]
    try:
        library = check_fabrics(fabrics)
    except ValueError as e:
        ap.error(str(e))
    out_dir = Path(a.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    warm: dict[str, float] = {}
    if a.designs:
        print(f"warming up (numba compile or cache load) for {', '.join(a.solvers)}...", file=sys.stderr, flush=True)
        warm = warm_up(a.solvers)
        print("warm-up: " + ", ".join(f"{m} {s:.1f} s" for m, s in warm.items()), file=sys.stderr, flush=True)

    cases: list[dict[str, Any]] = []
    variants = [True, False] if a.frictionless else [True]
    total = len(a.designs) * len(a.solvers) * len(variants) * len(fabrics)
    for name_or_path in a.designs:
        name, design = load(name_or_path)
        for fabric in fabrics:
            for friction in variants:
                for method in a.solvers:
                    k = len(cases) + 1
                    label = (
                        f"[{k}/{total}] {name} {method}"
                        + ("" if fabric == "design" else f" {fabric}")
                        + ("" if friction else " frictionless")
                    )
                    print(f"{label}...", file=sys.stderr, flush=True)
                    case = drape_case(
                        with_options(design, friction=friction, fabric=fabric, library=library),
                        method,
                        max_seconds=a.max_seconds,
                        levels=levels,
                        progress=True,
                        label=label,
                    )
                    case.update(design=name, solver=method, friction=friction, fabric=fabric)
                    case["goals"] = goals(case)
                    tt = case["time_to_tol_s"]
                    print(f"{label}: total to 1e-4 {_f(tt['total'], '.2f')} s", file=sys.stderr, flush=True)
                    cases.append(case)
        plot_design(out_dir / f"drape_{name}.png", name, [c for c in cases if c["design"] == name])

    sw = None
    if not a.no_sweep:
        sizes = [int(s) for s in a.sizes.split(",") if s]
        sw = sweep(sizes, a.sweep_solver, a.max_seconds, timeout_s=2 * a.max_seconds + 300, design_name=a.sweep_design)
        plot_sweep(out_dir / "drape_sweep.png", sw)

    if cases:
        print_table(cases)
    if sw is not None:
        print(f"\nsize sweep ({sw['design']}, {sw['solver']}):")
        print(f"{'target':>7s} {'n':>6s} {'fine to 1e-4 s':>14s} {'total s':>8s} {'its':>5s} {'peak MiB':>9s}")
        for r in sw["rows"]:
            if "error" in r:
                print(f"{r['target']:7d} {r['error']}")
                continue
            tt = r["time_to_1e-4_s"]
            print(
                f"{r['target']:7d} {r['vertices']:6d} {_f(tt['fine'], '14.2f')} {_f(tt['total'], '8.2f')} "
                f"{r['fine_iterations']:5d} {r['peak_rss_mib']:9.0f}"
            )
        if sw["fit"] is not None:
            print(
                f"fine time to 1e-4 ~ n^{sw['fit']['exponent']:.2f} (least squares in log-log, "
                f"{sw['fit']['points']} sizes)"
            )

    report = {
        "bench": "drape",
        "tolerance": TOL,
        "goals": GOALS,
        "warmup_s": warm,
        "machine": {
            "platform": platform.platform(),
            "python": platform.python_version(),
            "cpus": os.cpu_count(),
            "load_average_at_end": list(os.getloadavg()),
        },
        "commit": source_commit(),
        "args": dict(vars(a), out=str(a.out)),
        "cases": cases,
        "sweep": sw,
    }
    print(f"wrote {write_results(out_dir, 'drape', report)} and plots in {out_dir}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

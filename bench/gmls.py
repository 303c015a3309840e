"""``couture bench gmls``: GMLS previews against the true drape, with and without consistent derivatives.

The goal case (issue 15, "previews you can trust"): the default skirt, fine
level about 10k vertices (coarse 1600), friction on, lengthened 5 cm
(``param:length``). The cache holds what the node holds mid-drag: the old
equilibrium with its columns (the press) and the converged equilibrium at
half the edit (+2.5 cm) with its columns. Answers at the full edit:

- ``none``: the old drape;
- ``linear``: the press sample's linear prediction;
- ``mls``: the two drapes blended, values only;
- ``gmls_plain``: SC's GMLS as is (``GMLSCache(consistent=False)``);
- ``gmls``: GMLS with consistent derivatives (the default; see
  ``couture.sensitivity.gmls.consistent_derivatives``).

Error: RMS and largest vertex distance [mm] to fine Newton at the edited rest
shape (1e-6, or the tightest of 1e-6, 1e-5, 1e-4 that converges), from the
old drape, as ``couture bench tradeoff`` measures it (same helpers). Latency:
median wall time of ``Predictor.drag`` without the error estimate (what runs
at pointer rate) over ``--repeats`` calls, and, for the worst case the cache
allows, of ``GMLSCache.predict`` with ``max_active`` (6) first-order samples
at the fine vertex count. ``trapezoid_defect``: per pair of first-order
samples, r = |x^k - x^m - ½ (s^m + s^k)·Δd| / |x^k - x^m| (0 for exact columns
of a field quadratic along the pair; 1 when the columns explain nothing), and
φ = r² / (r² + r₀²), the part of the defect charged to the columns (r₀ =
``defect_scale``, 0.1); ``gmls_by_defect_scale``: GMLS's error for other r₀.

Cases (``--cases``): ``skirt5`` (the goal), and, to check nothing got worse,
``couture bench tradeoff``'s ``sheet`` (SC Fig. 5 strip over a frictionless
sphere, 40 mm longer; exact columns) and ``skirt`` (30 mm longer, waist ease
+10 mm), each at its fine level. Writes ``gmls.json``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from bench import add_out_arg, source_commit, write_results

CASES = ("skirt5", "sheet", "skirt")
ANSWERS = ("none", "linear", "mls", "gmls_plain", "gmls")
GOAL_RMS_MM = 2.0
DEFAULT_DEFECT_SCALE = 0.1
DEFECT_SCALES = (0.03, 0.1, 0.3, 1.0)


def build(case: str, size: str, seconds: float):
    from bench import tradeoff as T

    small = size == "small"
    if case == "skirt5":
        return T.garment_scene(
            "skirt5",
            "default_skirt.json",
            ("param:length",),
            (0.05, 0.0),
            *((150, 400) if small else (1600, 10000)),
            "default skirt, 5 cm longer",
            seconds,
        )
    if case in ("sheet", "skirt"):
        return T.build_scene(case, size, seconds)
    raise ValueError(f"unknown case {case!r}; choose from {CASES}")


def trapezoid_defects(cache) -> list[dict]:
    """Relative trapezoid defect r and the weight φ charged to the columns, per pair of first-order samples."""
    from couture.sensitivity.gmls import defect_weight

    by_uid = {s.uid: s for s in cache.samples}
    out = []
    for (a, b), (dn, xn) in sorted(cache._pair_defect.items()):
        out.append(
            {
                "d_m": by_uid[a].d.tolist(),
                "d_k": by_uid[b].d.tolist(),
                "relative": float(np.sqrt(dn / xn)) if xn > 0 else None,
                "phi": defect_weight(dn, xn, cache.defect_scale),
            }
        )
    return out


def latency_full_cache(n: int, repeats: int, max_active: int = 6) -> dict:
    """Median GMLSCache.predict wall time [s] with ``max_active`` first-order samples
    (a smooth field; float32 rows as the node stores them), plain and consistent."""
    from couture.sensitivity import GMLSCache

    rng = np.random.default_rng(0)
    x0 = rng.normal(size=(n, 3))
    S = rng.normal(size=(n, 3, 2))
    out: dict[str, float] = {"vertices": n, "samples": max_active}
    for name, consistent in (("gmls_plain", False), ("gmls", True), ("mls", True)):
        c = GMLSCache(n, consistent=consistent, max_active=max_active)
        for k in range(max_active):
            d = np.array([0.01 * k, 0.004 * (k % 3)])
            c.add(d, x0 + S @ d + 0.1 * np.sin(20 * d[0]), S)
        method = "mls" if name == "mls" else "gmls"
        c.predict((0.025, 0.003), method)  # compile / load
        ts = []
        for i in range(repeats):
            t0 = time.perf_counter()
            c.predict((0.025 + 1e-5 * i, 0.003), method)
            ts.append(time.perf_counter() - t0)
        out[f"{name}_s"] = float(np.median(ts))
    return out


def measure(case: str, size: str, seconds: float, repeats: int, log=print) -> dict:
    from bench import tradeoff as T

    t0 = time.perf_counter()
    sc = build(case, size, seconds)
    f = sc.levels["fine"]
    log(f"[{case}] {sc.description}: fine {f.model.n} vertices, old drape {f.drape_s:.1f} s")
    ref = T.reference(sc, 5 * seconds, log)
    d = sc.d
    x_half, half_s = T.half_sample(f, d, 5 * seconds)
    p, setup_s = T.predictor_for(f, "gmls", (0.5 * d, x_half))
    rows = {"none": T.errors(f.x_eq, ref["x"], ref["model"]) | {"latency_s": 0.0}}
    for answer in ANSWERS[1:]:
        method = "gmls" if answer.startswith("gmls") else answer
        p.cache.consistent = answer != "gmls_plain"
        lat, runs, pred = T._timed(lambda m=method: p.drag(d, method=m, error_estimate=False), repeats)
        rows[answer] = T.errors(pred.x, ref["x"], ref["model"]) | {"latency_s": lat, "runs": runs}
    p.cache.consistent = True
    sweep = {}
    for r0 in DEFECT_SCALES:  # the prior r₀ of the defect weight (default 0.1)
        p.cache.defect_scale = r0
        sweep[f"{r0:g}"] = T.errors(p.drag(d, error_estimate=False).x, ref["x"], ref["model"])
    p.cache.defect_scale = DEFAULT_DEFECT_SCALE
    log(f"  {case:6s} gmls rms by defect_scale: " + ", ".join(f"{k} {v['rms_mm']:.3f}" for k, v in sweep.items()))
    for a, r in rows.items():
        log(f"  {case:6s} {a:10s} rms {r['rms_mm']:7.3f} mm  max {r['max_mm']:7.2f} mm  {1e6 * r['latency_s']:8.1f} us")
    defects = trapezoid_defects(p.cache)
    for q in defects:
        log(f"  {case:6s} trapezoid defect {q['d_m']} -> {q['d_k']}: r {q['relative']:.3g}, phi {q['phi']:.3g}")
    return {
        "case": case,
        "description": sc.description,
        "d": d.tolist(),
        "vertices": {k: int(v.model.n) for k, v in sc.levels.items()},
        "friction": f.friction is not None,
        "reference": {k: ref[k] for k in ("tol", "residual", "s", "iterations")},
        "half_sample_s": half_s,
        "setup_s": setup_s,
        "answers": rows,
        "trapezoid_defect": defects,
        "gmls_by_defect_scale": sweep,
        "goal_rms_mm": GOAL_RMS_MM if case == "skirt5" else None,
        "goal_met": bool(rows["gmls"]["rms_mm"] <= GOAL_RMS_MM) if case == "skirt5" else None,
        "case_s": time.perf_counter() - t0,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench gmls", description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated: " + ", ".join(CASES))
    ap.add_argument("--size", choices=("small", "full"), default="full", help="mesh sizes (small: for tests)")
    ap.add_argument("--repeats", type=int, default=51, help="drag-time predictions per answer (median)")
    ap.add_argument("--max-seconds", type=float, default=300.0, help="cap on each drape [s] (reference: 5x)")
    add_out_arg(ap)
    a = ap.parse_args(argv)
    cases = [c for c in a.cases.split(",") if c]
    for c in cases:
        if c not in CASES:
            ap.error(f"unknown case {c!r}; choose from {', '.join(CASES)}")
    t0 = time.perf_counter()
    results = {"bench": "gmls", "size": a.size, "repeats": a.repeats, "cases": []}
    for c in cases:
        results["cases"].append(measure(c, a.size, a.max_seconds, a.repeats))
    fine = max((r["vertices"]["fine"] for r in results["cases"]), default=10000)
    results["latency_full_cache"] = lat = latency_full_cache(fine, a.repeats)
    print(
        f"latency, {lat['samples']} first-order samples at {lat['vertices']} vertices: "
        f"gmls plain {1e6 * lat['gmls_plain_s']:.1f} us, consistent {1e6 * lat['gmls_s']:.1f} us, "
        f"mls {1e6 * lat['mls_s']:.1f} us"
    )
    results["total_s"] = time.perf_counter() - t0
    results["machine"] = {
        "platform": platform.platform(),
        "cpus": os.cpu_count(),
        "load_average_at_end": list(os.getloadavg()),
        "note": "shared 2-core machine: wall times vary with the load of other processes",
    }
    results["commit"] = source_commit()
    print(f"wrote {write_results(a.out, 'gmls', results)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

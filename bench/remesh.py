"""``couture bench remesh``: remesher timings per sloper (SC Table 1 "remesh").

For every sloper in ``couture.pattern.SLOPERS`` (or the remesher's own
fixtures when the pattern package is unavailable): fine mesh (~10k vertices)
from the drafted pattern, the PMVC precompute (once per mesh), Ψ per edit
(one sparse product), and a Delaunay flip pass after a 30 % stretch.
Medians over repeats. Goals: remesh <= 60 ms, Ψ <= 20 ms at 10k vertices.
Prints a table and writes ``remesh.json`` to the results folder (``--out``, default bench/results/).
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from bench import add_out_arg, write_results

GOAL_REMESH_MS = 60.0
GOAL_PSI_MS = 20.0


def _patterns(use_fixtures: bool):
    out = {}
    if not use_fixtures:
        try:
            from couture.pattern import SLOPERS, draft
            from schemas.design import Design, Sloper

            for kind in SLOPERS:
                out[kind] = draft(Design(sloper=Sloper(kind=kind)))
        except Exception as e:  # the pattern package is optional for this bench
            print(f"couture.pattern unavailable ({e!r}); using the remesher fixtures")
            out = {}
    if not out:
        from couture.pattern.drafted import DraftedPattern
        from couture.remesh.fixtures import l_panel, tube, u_panel

        out["tube4"] = tube(4)
        out["L+U"] = DraftedPattern([l_panel(), u_panel()])
    return out


def _median_ms(fn, repeats: int):
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return 1e3 * float(np.median(ts))


def bench_pattern(drafted, target: int, repeats: int) -> dict:
    from couture.pattern.drafted import PanelJacobian
    from couture.remesh import build_coordinates, flip_to_delaunay, mesh_pattern, psi

    mesh_pattern(drafted, target)  # warm numba / imports
    remesh_ms = _median_ms(lambda: mesh_pattern(drafted, target), repeats)
    r = mesh_pattern(drafted, target)
    build_coordinates(r)
    pre = [build_coordinates(r).precompute_s for _ in range(max(1, repeats // 2))]
    coords = build_coordinates(r)
    # edit 1: a local drag (one panel's outline vertices near a point follow the pointer)
    p0 = drafted.panels[0]
    c = p0.outline[0]
    w = np.clip(1 - np.linalg.norm(p0.outline - c, axis=1) / 0.15, 0, 1)
    local = {p0.name: PanelJacobian(w[:, None, None] * np.eye(2), [np.zeros((len(h), 2, 2)) for h in p0.holes])}
    # edit 2: a global sloper-parameter change (every vertex of every panel moves)
    glob = {
        p.name: PanelJacobian(
            np.repeat(np.diag([1.0, 0.5])[None], len(p.outline), 0),
            [np.repeat(np.diag([1.0, 0.5])[None], len(h), 0) for h in p.holes],
        )
        for p in drafted.panels
    }
    psi(coords, glob)
    psi_local_ms = _median_ms(lambda: psi(coords, local), repeats)
    psi_global_ms = _median_ms(lambda: psi(coords, glob), repeats)
    # flip pass after a 30 % horizontal stretch of the whole pattern through Ψ
    stretch = {
        p.name: PanelJacobian(
            np.array([[[x[0], 0], [0, 0]] for x in p.outline]),
            [np.array([[[x[0], 0], [0, 0]] for x in h]) for h in p.holes],
        )
        for p in drafted.panels
    }
    Xs = r.mesh.X + psi(coords, stretch) @ np.array([0.3, 0.0])
    flip_to_delaunay(Xs, r.mesh.tris)
    flip_ms = _median_ms(lambda: flip_to_delaunay(Xs, r.mesh.tris), repeats)
    return {
        "vertices": r.mesh.n_vertices,
        "triangles": r.mesh.n_triangles,
        "boundary_vertices": int(len(coords.boundary)),
        "pmvc_nnz": int(coords.W.nnz),
        "remesh_ms": remesh_ms,
        "pmvc_precompute_ms": 1e3 * float(np.median(pre)),
        "psi_local_ms": psi_local_ms,
        "psi_global_ms": psi_global_ms,
        "flip_ms": flip_ms,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench remesh", description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=10000, help="target vertices of the fine mesh")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--fixtures", action="store_true", help="bench the remesher's fixtures, not the slopers")
    add_out_arg(ap)
    args = ap.parse_args(argv)

    rows = {}
    for name, drafted in _patterns(args.fixtures).items():
        rows[name] = bench_pattern(drafted, args.vertices, args.repeats)

    hdr = f"{'pattern':10s} {'verts':>6s} {'remesh':>8s} {'PMVC pre':>9s} {'Ψ local':>8s} {'Ψ global':>9s} {'flips':>7s}  [ms]"
    print(hdr)
    print("-" * len(hdr))
    for name, r in rows.items():
        print(
            f"{name:10s} {r['vertices']:6d} {r['remesh_ms']:8.1f} {r['pmvc_precompute_ms']:9.1f} "
            f"{r['psi_local_ms']:8.2f} {r['psi_global_ms']:9.2f} {r['flip_ms']:7.2f}"
        )
    worst_remesh = max(r["remesh_ms"] for r in rows.values())
    worst_psi = max(r["psi_global_ms"] for r in rows.values())
    print(
        f"goals: remesh <= {GOAL_REMESH_MS:.0f} ms (worst {worst_remesh:.1f}: "
        f"{'met' if worst_remesh <= GOAL_REMESH_MS else 'MISSED'}), "
        f"Ψ <= {GOAL_PSI_MS:.0f} ms (worst {worst_psi:.2f}: {'met' if worst_psi <= GOAL_PSI_MS else 'MISSED'})"
    )
    import os

    result = {
        "bench": "remesh",
        "target_vertices": args.vertices,
        "repeats": args.repeats,
        "statistic": "median",
        "goals_ms": {"remesh": GOAL_REMESH_MS, "psi": GOAL_PSI_MS},
        "met": {"remesh": worst_remesh <= GOAL_REMESH_MS, "psi": worst_psi <= GOAL_PSI_MS},
        "machine": {"python": platform.python_version(), "cpus": os.cpu_count(), "platform": platform.platform()},
        "patterns": rows,
    }
    print(f"wrote {write_results(args.out, 'remesh', result)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

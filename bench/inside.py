"""``couture bench inside``: how a drape's vertices end inside the body.

A cascadic drape as the solver node runs it (:class:`RemeshService` meshes,
:class:`SolveService` solves the coarse level from the placement and warm-starts
the fine level from the polished prolongation), with every fine iterate kept.
Then, for the free vertices that end inside the body's surface (phi < 0; or
those named by ``--vertices``), per fine iteration: signed distance phi [m]
(the body's ``phi_grad``), the vertex's move from the previous iterate [m], the
whole step's largest move [m], the contact force on it [N] and the sum of the
other forces on it along the body's normal [N], and where they were in the plain
prolongation and in the polished start. Which of these goes wrong first says
whether a long step carried the vertex through a thin part, the prolongation
put it inside, or a balance was reached inside the surface (the penalty too
soft for what presses there).

The same for the cloth between the vertices: per coarse and fine iteration,
how many mesh edges have both ends outside the body (phi >= 0) but pass
below its surface by more than the contact layer between them
(``edges_through``: the body through the cloth, which vertex contact, the
solvers' ``SurfaceGuard`` and the verdict's ``deepest_inside`` cannot see).

Writes ``DIR/inside.json``; ``--states FILE.npz`` keeps the coarse drape and
every fine iterate, so ``--reuse`` reruns the analysis without solving.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench import add_out_arg, source_commit, write_results

TERMS_PUSHING = ("membrane", "membrane_orthotropic", "bending", "seams", "gravity", "friction")
"""terms whose force along the body's normal the contact force balances"""


SAMPLES = 9
"""interior points per edge at which ``edges_through`` queries the body"""


def mesh_edges(tris: np.ndarray) -> np.ndarray:
    """(e, 2) the distinct edges of triangles (m, 3), each (low, high)."""
    e = np.sort(np.vstack([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0)


def edges_through(body, x: np.ndarray, edges: np.ndarray, depth: float) -> tuple[np.ndarray, np.ndarray]:
    """(through (e,) bool, deepest (e,) [m]): ``deepest`` the lowest phi over
    ``SAMPLES`` evenly spaced interior points of each edge; ``through`` the
    edges whose two ends lie outside the body's surface (phi >= 0) while some
    interior point lies more than ``depth`` [m] below it: a part of the body
    passes through the cloth between two vertices."""
    phi_v, _ = body.phi_grad(np.ascontiguousarray(x, dtype=np.float64))
    deepest = np.full(len(edges), np.inf)
    a, b = x[edges[:, 0]], x[edges[:, 1]]
    for t in np.linspace(0.0, 1.0, SAMPLES + 2)[1:-1]:
        phi, _ = body.phi_grad(np.ascontiguousarray((1.0 - t) * a + t * b))
        deepest = np.minimum(deepest, phi)
    ends_out = (phi_v[edges[:, 0]] >= 0.0) & (phi_v[edges[:, 1]] >= 0.0)
    return ends_out & (deepest < -depth), deepest


def level_trace(model, states: list[tuple[int, float, np.ndarray]]) -> list[dict[str, Any]]:
    """Per recorded iterate (iteration, residual, x): edges through the body
    (``edges_through`` at the contact layer's depth), the deepest edge point and
    vertex [m], and the largest vertex move since the previous iterate [m]."""
    edges = mesh_edges(model.tris)
    free = np.asarray(model.free, bool)
    rows = []
    for k, (it, r, x) in enumerate(states):
        through, deepest = edges_through(model.body, x, edges, model.contact_offset)
        phi, _ = model.body.phi_grad(np.ascontiguousarray(x))
        prev = states[k - 1][2] if k else x
        rows.append(
            dict(
                it=int(it),
                residual=float(r),
                edges_through=int(through.sum()),
                deepest_edge_point_m=float(deepest.min()),
                deepest_vertex_m=float(phi[free].min()),
                largest_move_m=float(np.max(np.linalg.norm(x - prev, axis=1))),
            )
        )
    return rows


def solve_and_record(design: Any, method: str, max_seconds: float) -> dict[str, Any]:
    """Coarse solve, the service's fine warm start, the fine solve with every
    iterate kept. Returns arrays and the two results' summaries."""
    from couture.remesh.service import RemeshService
    from couture.solvers.service import SolveService, carries_anchors

    updates = RemeshService().set_design(design, 1)
    service = SolveService(method=method)
    service.max_seconds = {level: float(max_seconds) for level in service.max_seconds}
    service.set_design(design)
    for up in updates:
        prolong = None
        if up.fine_parent_tri is not None and up.fine_bary is not None:
            prolong = (up.fine_parent_tri, up.fine_bary)
        service.set_mesh(up.level, up.mesh, up.mesh_generation, prolong)
    t0 = time.perf_counter()
    coarse_states: list[tuple[int, float, np.ndarray]] = []

    def on_progress(level: str, it: int, x: np.ndarray, r: float) -> None:
        coarse_states.append((it, r, np.array(x, dtype=np.float64)))

    (coarse,) = service.run(levels=("coarse",), on_progress=on_progress, progress_period_s=0.0)
    coarse_states.append((coarse.result.iterations, coarse.result.residual, coarse.result.x))
    print(
        f"coarse: {coarse.result.iterations} its, residual {coarse.result.residual:.3g}, "
        f"{coarse.result.wall_time:.1f} s, converged {coarse.result.converged} {coarse.result.diagnosis}",
        file=sys.stderr,
        flush=True,
    )
    xc = coarse.result.x
    assert service.prolongation is not None
    parent, bary = service.prolongation
    fine = service.levels["fine"]
    x_raw = np.einsum("nk,nkd->nd", bary, xc[service.levels["coarse"].mesh.tris[parent]])
    x0, how = service._warm("fine", xc)
    states: list[np.ndarray] = []
    res: list[float] = []

    def cb(it: int, x: np.ndarray, r: float) -> bool:
        if len(states) <= it:
            states.append(np.array(x, dtype=np.float64))
            res.append(float(r))
        return False

    at_once = how == "prolongated" and carries_anchors(fine.model)
    result = service.solver.solve(
        fine.model,
        x0,
        tol=service.tol["fine"],
        max_seconds=max_seconds,
        callback=cb,
        friction_after=math.inf if at_once else None,
    )
    states.append(np.array(result.x, dtype=np.float64))
    res.append(float(result.residual))
    print(
        f"fine: {result.iterations} its, residual {result.residual:.3g}, {result.wall_time:.1f} s, "
        f"converged {result.converged}: {result.diagnosis}  ({time.perf_counter() - t0:.0f} s in all)",
        file=sys.stderr,
        flush=True,
    )
    return dict(
        coarse_trace=level_trace(service.levels["coarse"].model, coarse_states),
        coarse_x=xc,
        x_raw=x_raw,
        x_start=x0,
        states=np.stack(states),
        residuals=np.array(res),
        summary=dict(
            coarse=dict(
                iterations=coarse.result.iterations,
                residual=coarse.result.residual,
                seconds=coarse.result.wall_time,
                converged=coarse.result.converged,
                diagnosis=coarse.result.diagnosis,
            ),
            fine=dict(
                iterations=result.iterations,
                residual=result.residual,
                seconds=result.wall_time,
                converged=result.converged,
                diagnosis=result.diagnosis,
                stats={k: v for k, v in result.stats.items() if isinstance(v, (int, float, str))},
            ),
        ),
        service=service,
    )


def analyse(model, rec: dict[str, Any], vertices: list[int] | None) -> dict[str, Any]:
    """Per-iteration figures of the vertices that end inside (or ``vertices``)."""
    body = model.body
    free = np.asarray(model.free, bool)
    states = rec["states"]
    phi_end, _ = body.phi_grad(np.ascontiguousarray(states[-1]))
    if vertices is None:
        vertices = [int(v) for v in np.nonzero(free & (phi_end < 0.0))[0]]
    out: dict[str, Any] = {"vertices": {}}
    terms = [t for t in TERMS_PUSHING if t in model.terms]
    out["fine_trace"] = level_trace(model, [(k, float(rec["residuals"][k]), x) for k, x in enumerate(states)])
    for label, x in (("prolongated", rec["x_raw"]), ("polished", rec["x_start"])):
        phi, _ = body.phi_grad(np.ascontiguousarray(x))
        out[f"{label}_inside"] = int((free & (phi < 0)).sum())
        out[f"{label}_min_phi_m"] = float(phi[free].min())
    mins = []
    for x in states:
        phi, _ = body.phi_grad(np.ascontiguousarray(x))
        mins.append(float(phi[free].min()))
    out["min_phi_per_iteration_m"] = mins
    out["inside_per_iteration"] = [int((free & (body.phi_grad(np.ascontiguousarray(x))[0] < 0)).sum()) for x in states]
    for v in vertices:
        rows = []
        for k, x in enumerate(states):
            phi, g = body.phi_grad(np.ascontiguousarray(x[[v]]))
            n = g[0] / max(float(np.linalg.norm(g[0])), 1e-300)
            fc = model.forces(x, ["contact"])[v]
            fo = model.forces(x, terms)[v]
            step = float(np.linalg.norm(x[v] - states[k - 1][v])) if k else 0.0
            big = float(np.max(np.linalg.norm(x - states[k - 1], axis=1))) if k else 0.0
            rows.append(
                dict(
                    it=k,
                    residual=float(rec["residuals"][k]),
                    phi_m=float(phi[0]),
                    grad_norm=float(np.linalg.norm(g[0])),
                    move_m=step,
                    largest_move_m=big,
                    contact_N=float(np.linalg.norm(fc)),
                    others_normal_N=float(fo @ n),
                    others_N=float(np.linalg.norm(fo)),
                )
            )
        phi_r, _ = body.phi_grad(np.ascontiguousarray(rec["x_raw"][[v]]))
        phi_s, _ = body.phi_grad(np.ascontiguousarray(rec["x_start"][[v]]))
        out["vertices"][str(v)] = dict(
            position_end=states[-1][v].tolist(),
            phi_prolongated_m=float(phi_r[0]),
            phi_polished_m=float(phi_s[0]),
            rows=rows,
        )
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench inside", description=__doc__.splitlines()[0])
    ap.add_argument("design", help="a pattern file (couture/design/v1 JSON)")
    ap.add_argument("--solver", default="newton")
    ap.add_argument("--max-seconds", type=float, default=500.0, help="cap per level [s]")
    ap.add_argument("--states", type=Path, default=None, help="keep the drapes here (.npz)")
    ap.add_argument("--reuse", action="store_true", help="analyse --states without solving")
    ap.add_argument("--vertices", type=int, nargs="*", default=None, help="fine vertices to follow")
    add_out_arg(ap)
    args = ap.parse_args(argv)
    from couture.pattern.io import load_design

    design = load_design(args.design)
    if args.reuse:
        if args.states is None:
            ap.error("--reuse needs --states")
        from couture.cloth.model import ClothModel
        from couture.remesh.service import RemeshService
        from couture.solvers.service import scene_from_design

        data = np.load(args.states, allow_pickle=False)
        rec = {k: data[k] for k in data.files}
        rec["summary"] = {}
        ups = {u.level: u for u in RemeshService().set_design(design, 1)}
        model = ClothModel(ups["fine"].mesh, design.fabric, scene_from_design(design))
    else:
        rec = solve_and_record(design, args.solver, args.max_seconds)
        model = rec.pop("service").levels["fine"].model
        if args.states is not None:
            arrays: dict[str, Any] = {k: v for k, v in rec.items() if isinstance(v, np.ndarray)}
            np.savez(args.states, **arrays)
    result = analyse(model, rec, args.vertices)
    result.update(
        design=args.design,
        solver=args.solver,
        summary=rec["summary"],
        coarse_trace=rec.get("coarse_trace", []),
        commit=source_commit(),
    )
    for name in ("coarse_trace", "fine_trace"):
        print(
            f"{name}: iteration, residual, edges through the body, deepest edge point, vertex [mm], largest move [mm]",
            file=sys.stderr,
        )
        for row in result[name]:
            print(
                f"  {row['it']:4d} {row['residual']:.2e} {row['edges_through']:3d} "
                f"{row['deepest_edge_point_m'] * 1e3:7.1f} {row['deepest_vertex_m'] * 1e3:7.1f} "
                f"{row['largest_move_m'] * 1e3:6.1f}",
                file=sys.stderr,
            )
    for v, d in result["vertices"].items():
        print(
            f"vertex {v}: phi prolongated {d['phi_prolongated_m'] * 1e3:.2f} mm, polished {d['phi_polished_m'] * 1e3:.2f} mm",
            file=sys.stderr,
        )
        for row in d["rows"]:
            print(
                f"  it {row['it']:4d} r {row['residual']:.2e} phi {row['phi_m'] * 1e3:7.2f} mm |g| {row['grad_norm']:.2f}"
                f" move {row['move_m'] * 1e3:7.3f} mm (largest {row['largest_move_m'] * 1e3:7.2f}) contact "
                f"{row['contact_N']:.3e} N others.n {row['others_normal_N']:+.3e} N |others| {row['others_N']:.3e} N",
                file=sys.stderr,
            )
    path = write_results(args.out, "inside", result)
    print(f"wrote {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

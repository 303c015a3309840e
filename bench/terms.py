"""``couture bench terms``: model only what the scene requires, and what that saves.

A model (``couture.cloth.model.ClothModel``) builds the energy terms its
scene names and no others: no body, no distance field and no contact; no
friction, no anchors; no seams on a mesh without them. Every drape a solver
node publishes lists the terms it built (``DrapeMsg.terms``, printed by
``couture drape``). This bench measures, per scene, the time to build the
model and solve it to the tolerance with only the required terms against
the same scene with everything built, the extra terms made inert so both
have the same answer:

- ``sheet``: a 0.6 m sheet hanging from its two top corners, far from the
  mannequin. Required: membrane, bending, gravity. Everything: + the
  mannequin (its distance field loaded, contact evaluated) and friction.
- ``skirt_frictionless``: the default skirt on the mannequin with friction
  off. Everything: + friction with mu_s = mu_k = 0 (anchors made, checked,
  slipped, with no force left).
- ``coarse_only``: a request that needs only the coarse drape (the adjust
  node's re-simulations, a preview): the cascade stopped at the coarse
  level against going on to the fine one.

The answers are checked: the everything-model's answer must balance the
required model, its relative residual there within 10x the tolerance
(``same_answer``: the extra terms changed nothing); a frictionless skirt can
settle turned about the body along its free spin, so positions are
reported, not compared. Writes ``terms.json`` to ``--out``.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import msgspec
import numpy as np

from bench import add_out_arg, source_commit, write_results
from couture.pattern.io import EXAMPLES

TOL = 1e-5
"""relative residual every solve here goes to"""


def _timed_solve(make_model, x0_of, tol: float = TOL, max_seconds: float = 120.0) -> dict[str, Any]:
    from couture.solvers import get_solver

    t0 = time.perf_counter()
    model = make_model()
    build_s = time.perf_counter() - t0
    x0 = x0_of(model)
    r = get_solver("newton").solve(model, x0, tol=tol, max_seconds=max_seconds, friction_after=np.inf)
    return {
        "model": model,
        "x": r.x,
        "terms": list(model.terms),
        "build_s": build_s,
        "solve_s": r.wall_time,
        "total_s": build_s + r.wall_time,
        "iterations": r.iterations,
        "residual": float(r.residual),
        "converged": bool(r.converged),
    }


def _compare(name: str, need: dict[str, Any], every: dict[str, Any], tol: float = TOL) -> dict[str, Any]:
    # the everything-answer in the required model (the other way round would
    # read the friction anchors the everything-model was left with)
    cross = float(need["model"].relative_residual(every["x"]))
    out: dict[str, Any] = {"scene": name}
    for label, r in (("required", need), ("everything", every)):
        out[label] = {k: v for k, v in r.items() if k not in ("model", "x")}
    out["saved_s"] = every["total_s"] - need["total_s"]
    out["saved_fraction"] = out["saved_s"] / every["total_s"] if every["total_s"] > 0 else None
    out["cross_residual"] = cross
    out["same_answer"] = bool(cross <= 10 * tol)
    out["max_vertex_distance_m"] = float(np.linalg.norm(need["x"] - every["x"], axis=1).max())
    return out


def sheet_scene() -> dict[str, Any]:
    from couture.cloth.model import ClothModel, Scene
    from couture.mesh import grid_sheet
    from schemas.design import Fabric

    mesh = grid_sheet(0.6, 0.6, 30, 30)
    X = mesh.X
    mesh.x0 = np.column_stack([X[:, 0] - 0.3, X[:, 1] + 0.4, np.full(len(X), 1.0)])  # 1 m in front of the body
    top = np.nonzero(X[:, 1] > X[:, 1].max() - 1e-9)[0]
    mesh.pinned = top[[np.argmin(X[top, 0]), np.argmax(X[top, 0])]].astype(np.int32)
    fabric = Fabric()
    need = _timed_solve(lambda: ClothModel(mesh, fabric, Scene(body=None)), lambda m: mesh.x0.copy())
    every = _timed_solve(
        lambda: ClothModel(mesh, fabric, Scene(body="mannequin", friction=True)), lambda m: mesh.x0.copy()
    )
    return _compare("sheet", need, every)


def _default_skirt():
    from couture.pattern.io import load_design

    return load_design(EXAMPLES / "default_skirt.json")


def _skirt_mesh(level: str = "coarse"):
    from couture.remesh.service import RemeshService

    design = _default_skirt()
    ups = RemeshService().set_design(design, 1)
    return design, next(u.mesh for u in ups if u.level == level)


def skirt_frictionless_scene() -> dict[str, Any]:
    from couture.cloth.model import ClothModel
    from couture.solvers.service import scene_from_design

    design, mesh = _skirt_mesh()
    design = msgspec.structs.replace(design, scene=msgspec.structs.replace(design.scene, friction=False))
    scene = scene_from_design(design)
    inert = msgspec.structs.replace(design.fabric, friction_static=0.0, friction_kinetic=0.0)
    scene_all = scene_from_design(
        msgspec.structs.replace(design, scene=msgspec.structs.replace(design.scene, friction=True))
    )
    need = _timed_solve(lambda: ClothModel(mesh, design.fabric, scene), lambda m: mesh.x0.copy())
    every = _timed_solve(lambda: ClothModel(mesh, inert, scene_all), lambda m: mesh.x0.copy())
    return _compare("skirt_frictionless", need, every)


def coarse_only_scene() -> dict[str, Any]:
    from couture.remesh.service import RemeshService
    from couture.solvers.service import SolveService

    design = _default_skirt()
    out: dict[str, Any] = {"scene": "coarse_only"}
    for label, levels in (("required", ("coarse",)), ("everything", ("coarse", "fine"))):
        t0 = time.perf_counter()
        ups = RemeshService().set_design(design, 1)
        service = SolveService(method="newton")
        service.set_design(design)
        for up in ups:
            prolong = None
            if up.fine_parent_tri is not None and up.fine_bary is not None:
                prolong = (up.fine_parent_tri, up.fine_bary)
            service.set_mesh(up.level, up.mesh, up.mesh_generation, prolong)
        runs = service.run(levels=levels)
        total = time.perf_counter() - t0
        out[label] = {
            "levels": list(levels),
            "vertices": [int(r.result.x.shape[0]) for r in runs],
            "terms": list(service.levels["coarse"].model.terms),
            "total_s": total,
            "converged": [bool(r.result.converged) for r in runs],
        }
    out["saved_s"] = out["everything"]["total_s"] - out["required"]["total_s"]
    out["saved_fraction"] = out["saved_s"] / out["everything"]["total_s"]
    return out


SCENES = {"sheet": sheet_scene, "skirt_frictionless": skirt_frictionless_scene, "coarse_only": coarse_only_scene}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench terms", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="*", default=list(SCENES), choices=list(SCENES))
    add_out_arg(ap)
    a = ap.parse_args(argv)
    from couture.solvers import get_solver

    t = time.perf_counter()
    get_solver("newton")  # numba kernels loaded outside the figures
    sheet_scene()  # warm-up, whatever is measured: the SDF and the kernels loaded outside the figures
    warm_s = time.perf_counter() - t
    rows = []
    for k, name in enumerate(a.scenes, 1):
        print(f"[{k}/{len(a.scenes)}] {name} ...", flush=True)
        rows.append(SCENES[name]())
    print(f"{'scene':20s} {'required terms':45s} {'s':>7s} {'everything':>10s} {'saved':>7s}  same answer")
    for r in rows:
        need, every = r["required"], r["everything"]
        same = r.get("same_answer", "-")
        print(
            f"{r['scene']:20s} {', '.join(need['terms']):45s} {need['total_s']:7.2f} {every['total_s']:10.2f} "
            f"{100 * r['saved_fraction']:6.0f}%  {same}"
        )
    path = write_results(
        a.out,
        "terms",
        {"bench": "terms", "tolerance": TOL, "warmup_s": warm_s, "commit": source_commit(), "scenes": rows},
    )
    print(f"wrote {path}")
    return 0

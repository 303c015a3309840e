"""``couture bench tradeoff``: every way the system can answer an edit, latency against error.

Scenes (each at a coarse and a fine level), one edit each:

- ``sheet``: SC's Fig. 5 strip pinned above a frictionless sphere
  (``couture bench sensitivity``'s scene), its free end pulled out 40 mm;
- ``skirt``: the default skirt, lengthened and its waist ease changed (the two
  sloper options are the two design coordinates d = (Δlength, Δwaist_ease));
- ``dress``: the dress with its front left waist dart moved along the waist.

Garments keep the design's scene (friction on): every solve at the edited
rest shape starts with the friction state of the old equilibrium, as the
solver node does after an edit.

Answers, at each level (a coarse answer is prolongated to the fine mesh by
the remesher's coarse -> fine map and polished as the cascadic solve does;
that time is part of its latency):

- ``none``: the old drape, unchanged;
- ``linear`` / ``gmls`` / ``mls``: the sensitivity predictor (``Predictor``)
  as the node makes it. The cache holds the old equilibrium's first-order
  sample and, as if a solver result had arrived mid-drag, the converged
  equilibrium at half the edit (with its sensitivity for GMLS; MLS blends the
  two drapes alone, zeroth order: a secant through two converged solves). Latency is the drag-time prediction; the idle refactor, the
  press and the mid-drag sample are paid earlier and reported as ``setup_s``;
- ``newton`` / ``kinetic`` / ``verlet`` at each ``--tols`` relative force
  residual, started from the old drape; latency is the solve's wall time.

Error against a converged reference: Newton on the fine mesh at the edited
rest shape to 1e-6 (or the tightest of 1e-6, 1e-5, 1e-4 that converges), from
the old drape: largest and RMS vertex distance [mm], and the relative force
residual of the answer on the fine model at the edited rest shape (holding
the reference's friction state; stiff contact and friction anchors make it
large for micron-scale differences). Latencies are medians of ``--repeats``
runs (predictions under 1 s, solves under ``--repeat-below`` s; one run
otherwise), after a warm-up that loads or compiles every numba kernel; the
warm-up's extra time is reported as ``compile_s`` per component.

The peer (``--peer``, on by default when the ``couture[peer]`` extra is
installed; otherwise the bench prints that it is skipped and goes on):
NVIDIA newton's ``SolverStyle3D`` (``couture.solvers.peer``), on the fine
mesh at the edited rest shape from the old drape, stopped at each
``--peer-tols`` of its own stationarity measure (``||M v|| / (dt ||F_g||)``),
errors against the same reference (garment seams welded as Style3D sews
them, see ``couture.solvers.peer``). For each peer point the
JSON holds ``ours_over_peer``: the latency of the fastest of our answers
(solvers and predictors at either level; not ``none``, the unchanged old
drape, nor the diagnostic frictionless linearisation) whose RMS error is at
most the peer point's RMS error, divided by the peer point's latency (< 1:
we are faster; the goal is <= 0.2, 5x less time); null when none of ours is
that accurate; ``solver_ours_over_peer`` the same with our solvers only, and
``*_steps`` over the peer's time less its model build (see ``peer_ratios``).

Writes ``tradeoff.json`` and ``tradeoff.png`` (log-log latency vs RMS error
per scene, Pareto front as a step line) to ``--out`` and prints one line per
measurement.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np

from bench import OWN_SOLVERS, PEER, add_out_arg, source_commit, write_results
from couture.pattern.io import EXAMPLES

if TYPE_CHECKING:
    from couture.cloth.model import ClothModel

SOLVER_NAMES = OWN_SOLVERS
PREDICTORS = ("linear", "gmls", "mls")
REFERENCE_TOLS = (1e-6, 1e-5, 1e-4)
SCENES = ("sheet", "skirt", "dress")
PEER_TOLS = (1e-1, 3e-2, 1e-2, 3e-3)
NOT_OURS = ("none", PEER)


@dataclass
class Level:
    """One mesh of a scene: the old equilibrium and the edit's rest-shape Jacobian."""

    name: str
    """'coarse' | 'fine'"""
    model: ClothModel
    """at the old rest shape, holding the old equilibrium's friction state"""
    psi: np.ndarray
    """dX/dd, (n, 2, 2): rest positions X(d) = X0 + psi d"""
    x_eq: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """old equilibrium [m], (n, 3) (empty until ``drape``)"""
    friction: tuple | None = None
    """friction state of the old equilibrium (None without friction)"""
    drape_s: float = 0.0

    def drape(self, x0: np.ndarray, seconds: float) -> None:
        """The old equilibrium: Newton to 1e-6 from x0."""
        self.x_eq, self.drape_s = _drape(self.model, x0, 1e-6, seconds)
        self.friction = self.model.friction_state()

    @property
    def X0(self) -> np.ndarray:
        return self.model.X

    def model_at(self, d: np.ndarray):
        """A private model at X(d) holding the old equilibrium's friction state."""
        from couture.sensitivity.predictor import default_model_at

        m = default_model_at(self.model, self.X0 + self.psi @ d)
        m.set_friction_state(self.friction)
        return m


@dataclass
class Scene:
    name: str
    description: str
    d: np.ndarray
    """the edit, (2,) in the units of psi's columns"""
    levels: dict[str, Level] = field(default_factory=dict)
    to_fine: Callable[[np.ndarray, np.ndarray], np.ndarray] = lambda xc, d: xc
    """(coarse answer, d) -> fine positions (prolongation + polish); set by the scene builders"""


def _drape(model, x0, tol, seconds):
    from couture.solvers import get_solver

    t0 = time.perf_counter()
    r = get_solver("newton").solve(model, x0, tol=tol, max_seconds=seconds, max_iters=3000)
    if not r.converged and r.residual > 10 * tol:
        raise RuntimeError(f"the old drape did not converge ({r.diagnosis}, residual {r.residual:.1e})")
    return r.x, time.perf_counter() - t0


def _drape_levels(sc: Scene, seconds: float) -> None:
    """The old drapes as the solver node makes them (cascadic): coarse from the
    placement, fine from the coarse drape prolongated. Draped apart, the two
    levels of the skirt settle about 30 degrees apart around the body (a soft
    rotation mode under friction), which is no error of the coarse level."""
    c, f = sc.levels["coarse"], sc.levels["fine"]
    c.drape(c.model.mesh.x0.copy(), seconds)
    f.drape(sc.to_fine(c.x_eq, np.zeros(2)), seconds)


def sheet_scene(coarse=(32, 10), fine=(63, 20), edit=0.04, seconds=120.0) -> Scene:
    """The strip over the sphere, its free end pulled out by ``edit`` [m] (length 0.8 m)."""
    from bench.sensitivity import strip_over_sphere
    from couture.solvers.cascadic import locate

    sc = Scene(
        "sheet",
        f"SC Fig. 5 strip (0.8 m x 0.25 m) over a frictionless sphere, lengthened {1e3 * edit:.0f} mm",
        np.array([edit, 0.0]),
    )
    for lvl, (nx, ny) in (("coarse", coarse), ("fine", fine)):
        model = strip_over_sphere(nx, ny)
        L = float(np.ptp(model.X[:, 0]))
        psi = np.zeros((model.n, 2, 2))
        psi[:, 0, 0] = model.X[:, 0] / L  # the free end moves by d[0]: the strip lengthens
        psi[:, 1, 1] = model.X[:, 1] / L
        sc.levels[lvl] = Level(lvl, model, psi)
    c, f = sc.levels["coarse"], sc.levels["fine"]
    P = locate(c.X0, c.model.mesh.tris, f.X0)

    def to_fine(xc, d):
        from couture.solvers.cascadic import polish_prolongated

        return polish_prolongated(f.model_at(d), P.apply(c.model.mesh.tris, xc), c.model_at(d), xc, P.tri, P.bary)

    sc.to_fine = to_fine
    _drape_levels(sc, seconds)
    return sc


def garment_scene(name, file, edits, d, coarse_n, fine_n, description, seconds=120.0) -> Scene:
    """A garment from ``couture/pattern/examples/<file>`` meshed at two sizes;
    ``edits`` names up to two edit elements, the design coordinates d[0], d[1]."""
    from couture.cloth.model import ClothModel
    from couture.pattern.edit import edit_jacobian
    from couture.pattern.io import load_design
    from couture.pattern.validate import validate
    from couture.remesh import build_coordinates, mesh_pattern
    from couture.remesh import psi as remesh_psi
    from couture.remesh.transfer import prolongation
    from couture.solvers.cascadic import polish_prolongated
    from couture.solvers.service import scene_from_design

    design = load_design(EXAMPLES / file)
    drafted = validate(design)
    sc = Scene(name, description, np.asarray(d, float))
    meshes = {}
    for lvl, nv in (("coarse", coarse_n), ("fine", fine_n)):
        res = mesh_pattern(drafted, nv, level=lvl)
        model = ClothModel(res.mesh, design.fabric, scene_from_design(design))
        coords = build_coordinates(res, "pmvc")
        psi = np.zeros((model.n, 2, 2))
        for j, element in enumerate(edits):
            psi[:, :, j] = remesh_psi(coords, edit_jacobian(design, element))[:, :, 0]
        sc.levels[lvl] = Level(lvl, model, psi)
        meshes[lvl] = res.mesh
    c, f = sc.levels["coarse"], sc.levels["fine"]
    tri, bary = prolongation(meshes["coarse"], meshes["fine"])
    ctris = meshes["coarse"].tris

    def to_fine(xc, d):
        x_raw = np.einsum("ij,ijk->ik", bary, xc[ctris[tri]])
        return polish_prolongated(f.model_at(d), x_raw, c.model_at(d), xc, tri, bary)

    sc.to_fine = to_fine
    _drape_levels(sc, seconds)
    return sc


def build_scene(name: str, size: str, seconds: float = 120.0) -> Scene:
    """A scene by name at ``size`` 'small' (tests, development) or 'full'."""
    small = size == "small"
    if name == "sheet":
        return sheet_scene((16, 6), (32, 10), seconds=seconds) if small else sheet_scene(seconds=seconds)
    if name == "skirt":
        return garment_scene(
            "skirt",
            "default_skirt.json",
            ("param:length", "param:waist_ease"),
            (0.03, 0.01),
            *((150, 400) if small else (400, 1600)),
            "default skirt, 30 mm longer, waist ease +10 mm",
            seconds,
        )
    if name == "dress":
        return garment_scene(
            "dress",
            "dress.json",
            ("dart:front.waist_dart_l:position",),
            (0.02, 0.0),
            *((300, 700) if small else (700, 2500)),
            "dress, front left waist dart moved 20 mm",
            seconds,
        )
    raise ValueError(f"unknown scene {name!r}; choose from {SCENES}")


# -- measurements -------------------------------------------------------------


def _timed(fn, repeats: int, quick_s: float = 1.0):
    """(median wall time [s], runs, last result): repeats only while one run is under quick_s."""
    ts, out = [], None
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
        if ts[-1] > quick_s:
            break
    return float(np.median(ts)), len(ts), out


def errors(x: np.ndarray, x_ref: np.ndarray, ref_model) -> dict:
    """Vertex distances [mm] to the reference and the relative force residual on the reference's model."""
    dist = np.linalg.norm(x - x_ref, axis=1)
    return {
        "max_mm": 1e3 * float(dist.max()),
        "rms_mm": 1e3 * float(np.sqrt(np.mean(dist**2))),
        "residual": float(ref_model.relative_residual(x)),
    }


def reference(scene: Scene, seconds: float, log=print) -> dict:
    """Converged fine Newton at the edited rest shape from the old drape: the tightest tolerance that converges."""
    from couture.solvers import get_solver

    f = scene.levels["fine"]
    for tol in REFERENCE_TOLS:
        m = f.model_at(scene.d)
        t0 = time.perf_counter()
        r = get_solver("newton").solve(
            m, f.x_eq.copy(), tol=tol, max_seconds=seconds, max_iters=5000, friction_after=as_live(m)
        )
        s = time.perf_counter() - t0
        log(
            f"  reference newton tol {tol:.0e}: {'converged' if r.converged else 'NOT converged'} "
            f"residual {r.residual:.1e} in {s:.1f} s"
        )
        if r.converged:
            return {"x": r.x, "model": m, "tol": tol, "residual": float(r.residual), "s": s, "iterations": r.iterations}
    raise RuntimeError(f"{scene.name}: no reference: fine Newton did not converge even to {REFERENCE_TOLS[-1]}")


def as_live(model) -> float | None:
    """The friction schedule of a re-solve from the old drape, as the solver node decides it
    for a warm start: a model that carries its drape's anchors keeps them from the first
    iteration (``couture.solvers.service.carries_anchors``), any other the solver's own."""
    from couture.solvers.service import carries_anchors

    return math.inf if carries_anchors(model) else None


LINEAR_FRICTIONLESS = "linear_nofric"
"""diagnostic: the linear prediction from a frictionless linearisation (the node holds friction)"""


def half_sample(level: Level, d: np.ndarray, seconds: float):
    """The converged equilibrium at half the edit, as if the solver sent it mid-drag: (x, seconds)."""
    from couture.solvers import get_solver

    m = level.model_at(0.5 * d)
    t0 = time.perf_counter()
    r = get_solver("newton").solve(m, level.x_eq.copy(), tol=1e-6, max_seconds=seconds, friction_after=as_live(m))
    return r.x, time.perf_counter() - t0


def predictor_for(level: Level, method: str, half: tuple | None = None):
    """A Predictor as the node makes it, pressed on the edit at the old equilibrium; with
    ``half`` = (d_m, x_m), the mid-drag sample too (first order for GMLS, zeroth for MLS).
    ``method`` LINEAR_FRICTIONLESS linearises without friction. Returns (predictor, setup seconds)."""
    from couture.sensitivity import Predictor
    from couture.sensitivity.predictor import default_model_at

    node_model = default_model_at(level.model, level.X0)
    frictionless = method == LINEAR_FRICTIONLESS
    if frictionless:
        node_model.release_friction()
    p = Predictor(method="linear" if frictionless else method, error_estimate=False, friction=not frictionless)
    t0 = time.perf_counter()
    p.set_equilibrium(node_model, level.x_eq)
    p.refactor()
    p.press(level.psi)
    if half is not None:
        p.add_sample(half[0], half[1], sensitivity=(method == "gmls"))
    return p, time.perf_counter() - t0


def measure_scene(
    scene: Scene,
    tols,
    repeats: int,
    seconds: float,
    solvers=SOLVER_NAMES,
    levels=("coarse", "fine"),
    repeat_below: float = 4.0,
    log=print,
    peer_tols=(),
) -> dict:
    from couture.solvers import get_solver

    ref = reference(scene, 12 * seconds, log)
    x_ref, ref_model = ref["x"], ref["model"]
    rows: list[dict] = []
    d = scene.d

    def record(method, level, tol, latency, runs, x_level, **extra):
        x = x_level
        pro_s = 0.0
        if level == "coarse":
            t0 = time.perf_counter()
            x = scene.to_fine(x_level, d)
            pro_s = time.perf_counter() - t0
        row = {
            "scene": scene.name,
            "method": method,
            "level": level,
            "tol": tol,
            "label": f"{method}{'' if tol is None else f' {tol:.0e}'} {level}",
            "latency_s": latency + pro_s,
            "answer_s": latency,
            "prolongation_s": pro_s,
            "runs": runs,
            **errors(x, x_ref, ref_model),
            **extra,
        }
        rows.append(row)
        log(
            f"  {scene.name:6s} {row['label']:22s} latency {row['latency_s'] * 1e3:10.2f} ms   "
            f"rms {row['rms_mm']:9.3f} mm   max {row['max_mm']:9.3f} mm   residual {row['residual']:.1e}"
        )

    for lvl in levels:
        L = scene.levels[lvl]
        record("none", lvl, None, 0.0, 1, L.x_eq)
        x_half, sample_s = half_sample(L, d, 12 * seconds)
        methods = PREDICTORS + ((LINEAR_FRICTIONLESS,) if L.friction is not None else ())
        for method in methods:
            nonlinear = method in ("gmls", "mls")
            p, setup = predictor_for(L, method, (0.5 * d, x_half) if nonlinear else None)
            lat, runs, pred = _timed(lambda p=p: p.drag(d, error_estimate=False), max(repeats, 5))
            record(
                method,
                lvl,
                None,
                lat,
                runs,
                pred.x,
                setup_s=setup,
                sample_solve_s=sample_s if nonlinear else 0.0,
                samples=pred.samples,
                used=pred.method,
            )
        for name in solvers:
            for tol in tols:
                solver = get_solver(name)

                def solve(L=L, solver=solver, tol=tol):
                    m = L.model_at(d)
                    t0 = time.perf_counter()
                    r = solver.solve(m, L.x_eq.copy(), tol=tol, max_seconds=seconds, friction_after=as_live(m))
                    return time.perf_counter() - t0, r

                s, res = solve()
                runs_s = [s]
                while len(runs_s) < repeats and s <= repeat_below:  # model copies are not timed
                    s, res = solve()
                    runs_s.append(s)
                record(
                    name,
                    lvl,
                    tol,
                    float(np.median(runs_s)),
                    len(runs_s),
                    res.x,
                    converged=bool(res.converged),
                    solver_residual=float(res.residual),
                    iterations=int(res.iterations),
                    diagnosis=res.diagnosis,
                )
    peer: dict = {"tols": list(peer_tols)}
    if peer_tols:
        fine = scene.levels["fine"]
        for tol in peer_tols:
            m = fine.model_at(d)
            r = get_solver(PEER).solve(m, fine.x_eq.copy(), tol=tol, max_seconds=seconds)
            record(
                PEER,
                "fine",
                tol,
                float(r.wall_time),
                1,
                r.x,
                converged=bool(r.converged),
                solver_residual=float(r.residual),
                own_residual=float(r.stats["own_residual"]),
                build_s=float(r.stats["build_s"]),
                seams_unwelded=int(r.stats["seams_unwelded"]),
                iterations=int(r.iterations),
                diagnosis=r.diagnosis,
            )
        peer["ratios"] = peer_ratios(rows)
        for q in peer["ratios"]:
            for key in ("", "solver_"):
                v = q[f"{key}ours_over_peer"]
                ratio = "none of ours as accurate" if v is None else f"{v:.3g}"
                log(f"  {scene.name:6s} {q['peer']:22s} vs {q[f'{key}ours'] or '-':22s} ours/peer time {ratio}")
    return {
        "scene": scene.name,
        "description": scene.description,
        "d": scene.d.tolist(),
        "vertices": {k: int(v.model.n) for k, v in scene.levels.items()},
        "old_drape_s": {k: v.drape_s for k, v in scene.levels.items()},
        "reference": {k: ref[k] for k in ("tol", "residual", "s", "iterations")}
        | {"self_rms_mm": errors(x_ref, x_ref, ref_model)["rms_mm"]},
        "rows": rows,
        "pareto": pareto(rows),
        "peer": peer,
    }


def peer_ratios(rows: list[dict]) -> list[dict]:
    """For each peer point: the fastest of our answers with RMS error <= the peer's, and
    ``ours_over_peer`` = its latency / the peer's (None when none of ours is that accurate).

    ``ours_over_peer_steps``: the same over the peer's latency less its model build
    (newton's model and Style3D's PD matrix for the edited rest shape; our solvers get
    their model built outside the timing). ``solver_*``: the same with our solvers only
    (a full re-solve like the peer's, no sensitivity prediction)."""
    ours = [r for r in rows if r["method"] not in NOT_OURS and r["method"] != LINEAR_FRICTIONLESS]
    solvers = [r for r in ours if r["method"] in SOLVER_NAMES]
    out = []
    for p in (r for r in rows if r["method"] == PEER):
        q: dict = {"peer": p["label"], "peer_latency_s": p["latency_s"], "peer_rms_mm": p["rms_mm"]}
        steps_s = max(p["latency_s"] - p.get("build_s", 0.0), 1e-12)
        for key, pool in (("", ours), ("solver_", solvers)):
            good = [r for r in pool if r["rms_mm"] <= p["rms_mm"]]
            best = min(good, key=lambda r: r["latency_s"]) if good else None
            lat = None if best is None else best["latency_s"]
            q[f"{key}ours"] = None if best is None else best["label"]
            q[f"{key}ours_latency_s"] = lat
            q[f"{key}ours_rms_mm"] = None if best is None else best["rms_mm"]
            q[f"{key}ours_over_peer"] = None if lat is None else lat / max(p["latency_s"], 1e-12)
            q[f"{key}ours_over_peer_steps"] = None if lat is None else lat / steps_s
        out.append(q)
    return out


def pareto(rows: list[dict]) -> list[str]:
    """Labels on the Pareto front of (latency, RMS error), fastest first: no other
    answer is both at least as fast and at least as accurate (and better in one).
    The diagnostic frictionless linearisation and the peer are left out: ours only."""
    pts = sorted(
        (r for r in rows if r["method"] not in (LINEAR_FRICTIONLESS, PEER)), key=lambda r: (r["latency_s"], r["rms_mm"])
    )
    front, best = [], np.inf
    for r in pts:
        if r["rms_mm"] < best:
            front.append(r["label"])
            best = r["rms_mm"]
    return front


def warm_up(log=print, peer: bool = False) -> dict:
    """Compile or load every numba kernel on a tiny sheet: the first call's extra time per component [s]."""
    from bench.sensitivity import strip_over_sphere
    from couture.sensitivity import Predictor
    from couture.solvers import get_solver

    out = {}
    model = strip_over_sphere(8, 4)
    x = model.mesh.x0.copy()
    for name in SOLVER_NAMES:
        times = []
        for _ in range(2):
            t0 = time.perf_counter()
            r = get_solver(name).solve(model, model.mesh.x0.copy(), tol=1e-3, max_seconds=60)
            times.append(time.perf_counter() - t0)
            if name == "newton":
                x = r.x
        out[name] = max(0.0, times[0] - times[1])
    psi = np.zeros((model.n, 2, 2))
    psi[:, 0, 0] = model.X[:, 0]
    times = []
    for _ in range(2):
        t0 = time.perf_counter()
        p = Predictor(error_estimate=False)
        p.set_equilibrium(model, x)
        p.refactor()
        p.press(psi)
        p.add_sample((0.01, 0.0), x)
        for m in PREDICTORS:
            p.drag((0.02, 0.0), method=m)
        times.append(time.perf_counter() - t0)
    out["predictor"] = max(0.0, times[0] - times[1])
    if peer:
        times = []
        for _ in range(2):
            t0 = time.perf_counter()
            get_solver(PEER).solve(model, model.mesh.x0.copy(), tol=1e-1, max_iters=5, max_seconds=60)
            times.append(time.perf_counter() - t0)
        out[PEER] = max(0.0, times[0] - times[1])
    log("warm-up (compile/load) s: " + ", ".join(f"{k} {v:.2f}" for k, v in out.items()))
    return out


def run(
    scenes,
    size: str,
    tols,
    repeats: int,
    seconds: float,
    solvers=SOLVER_NAMES,
    repeat_below: float = 4.0,
    log=print,
    peer_tols=(),
) -> dict:
    from couture.solvers import peer

    t_start = time.perf_counter()
    peer_note = ""
    if peer_tols and not peer.available():
        peer_note = f"peer {PEER} skipped: newton is not installed (install couture[peer])"
        log(peer_note)
        peer_tols = ()
    compile_s = warm_up(log, peer=bool(peer_tols))
    results = []
    for name in scenes:
        t0 = time.perf_counter()
        log(f"[{name}] building and draping coarse and fine ({size}) ...")
        sc = build_scene(name, size, 12 * seconds)
        log(
            f"[{name}] vertices {', '.join(f'{k} {v.model.n}' for k, v in sc.levels.items())}; "
            f"drapes {', '.join(f'{k} {v.drape_s:.1f} s' for k, v in sc.levels.items())}"
        )
        res = measure_scene(
            sc, tols, repeats, seconds, solvers, repeat_below=repeat_below, log=log, peer_tols=peer_tols
        )
        res["scene_s"] = time.perf_counter() - t0
        results.append(res)
    return {
        "bench": "tradeoff",
        "size": size,
        "tols": list(tols),
        "solvers": list(solvers),
        "peer": {"solver": PEER, "tols": list(peer_tols), "note": peer_note},
        "repeats": repeats,
        "repeat_below_s": repeat_below,
        "compile_s": compile_s,
        "scenes": results,
        "total_s": time.perf_counter() - t_start,
        "machine": {
            "platform": platform.platform(),
            "cpus": os.cpu_count(),
            "load_average_at_end": list(os.getloadavg()),
            "note": "shared 2-core machine: wall times vary with the load of other processes",
        },
        "commit": source_commit(),
    }


METHOD_STYLE = {
    "none": ("black", "x"),
    "linear": ("tab:blue", "o"),
    LINEAR_FRICTIONLESS: ("tab:cyan", "p"),
    "gmls": ("tab:green", "D"),
    "mls": ("tab:olive", "d"),
    "newton": ("tab:red", "s"),
    "kinetic": ("tab:purple", "^"),
    "verlet": ("tab:orange", "v"),
    PEER: ("tab:brown", "*"),
}


def plot(results: dict, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = results["scenes"]
    fig, axes = plt.subplots(1, len(scenes), figsize=(5.2 * len(scenes), 4.6), squeeze=False)
    floor_s, floor_mm, cap_mm = 1e-6, 1e-4, 1e3  # zero latency/error drawn at the floor; diverged answers at the cap

    def xy(r):
        return max(r["latency_s"], floor_s), min(max(r["rms_mm"], floor_mm), cap_mm)

    for ax, sc in zip(axes[0], scenes, strict=True):
        rows = sc["rows"]
        for r in rows:
            color, marker = METHOD_STYLE[r["method"]]
            x, y = xy(r)
            kw = dict(marker=marker, s=42, zorder=3, alpha=0.9 if r.get("converged", True) else 0.45)
            if marker == "x":  # no hollow cross: the coarse old drape is a plus
                kw.update(color=color, marker="x" if r["level"] == "fine" else "+")
            elif r["level"] == "fine":
                kw["color"] = color
            else:
                kw.update(facecolors="none", edgecolors=color)
            ax.scatter(x, y, **kw)
            note = f"{r['tol']:.0e}" if r["tol"] is not None and r["level"] == "fine" else ""
            if r["rms_mm"] > cap_mm and r["tol"] == min(t for t in results["tols"]):
                note += f" {r['method']} {r['level']}: off chart ({r['rms_mm']:.0e} mm)"
            if note:
                ax.annotate(note, (x, y), fontsize=6, xytext=(3, 2), textcoords="offset points", color=color)
        by_label = {r["label"]: r for r in rows}
        fx, fy = zip(*(xy(by_label[lab]) for lab in sc["pareto"]), strict=True)
        ax.step(fx, fy, where="post", color="gray", lw=1.2, ls="--", zorder=2)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("latency [s] (wall, after warm-up)")
        ax.set_ylabel("RMS vertex error vs fine Newton 1e-6 [mm]")
        v = sc["vertices"]
        ax.set_title(f"{sc['scene']}: {v['coarse']} / {v['fine']} vertices\n{sc['description']}", fontsize=8)
        ax.grid(True, which="both", alpha=0.25)
    handles = [plt.Line2D([], [], color=c, marker=m, ls="", label=k) for k, (c, m) in METHOD_STYLE.items()] + [
        plt.Line2D([], [], color="gray", marker="o", ls="", markerfacecolor="gray", label="fine"),
        plt.Line2D([], [], color="gray", marker="o", ls="", markerfacecolor="none", label="coarse, prolongated"),
        plt.Line2D([], [], color="gray", ls="--", label="Pareto front"),
    ]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def table(results: dict) -> str:
    lines = [f"{'scene':6s} {'answer':22s} {'latency ms':>11s} {'rms mm':>9s} {'max mm':>9s} {'residual':>9s}"]
    for sc in results["scenes"]:
        for r in sc["rows"]:
            star = " *" if r["label"] in sc["pareto"] else ""
            lines.append(
                f"{sc['scene']:6s} {r['label']:22s} {1e3 * r['latency_s']:11.2f} {r['rms_mm']:9.3f} "
                f"{r['max_mm']:9.3f} {r['residual']:9.1e}{star}"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench tradeoff", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default=",".join(SCENES), help="comma-separated: " + ", ".join(SCENES))
    ap.add_argument("--size", choices=("small", "full"), default="full", help="mesh sizes (small: for tests)")
    ap.add_argument("--tols", default="1e-2,1e-3,1e-4", help="solver tolerances (relative force residual)")
    ap.add_argument("--solvers", default=",".join(SOLVER_NAMES), help="comma-separated solvers")
    ap.add_argument("--repeats", type=int, default=3, help="runs per answer (median); predictions under 1 s")
    ap.add_argument(
        "--repeat-below", type=float, default=4.0, help="repeat a solve only if one run took at most this [s]"
    )
    ap.add_argument(
        "--max-seconds",
        type=float,
        default=10.0,
        help="cap on each timed solve [s] (the drapes and the reference get 12x)",
    )
    ap.add_argument(
        "--peer-tols",
        default=",".join(f"{t:g}" for t in PEER_TOLS),
        help="the peer's (style3d) own stopping thresholds; empty: no peer",
    )
    ap.add_argument("--no-plot", action="store_true")
    add_out_arg(ap)
    a = ap.parse_args(argv)
    scenes = [s for s in a.scenes.split(",") if s]
    for s in scenes:
        if s not in SCENES:
            ap.error(f"unknown scene {s!r}; choose from {', '.join(SCENES)}")
    tols = [float(t) for t in a.tols.split(",")]
    solvers = [s for s in a.solvers.split(",") if s]
    for s in solvers:
        if s not in SOLVER_NAMES:
            ap.error(f"unknown solver {s!r}; choose from {', '.join(SOLVER_NAMES)}")
    peer_tols = [float(t) for t in a.peer_tols.split(",") if t]
    results = run(scenes, a.size, tols, a.repeats, a.max_seconds, solvers, a.repeat_below, peer_tols=peer_tols)
    print(table(results))
    print("* on the Pareto front")
    path = write_results(a.out, "tradeoff", results)
    print(f"wrote {path}")
    if not a.no_plot:
        print(f"wrote {plot(results, Path(a.out) / 'tradeoff.png')}")
    print(f"total {results['total_s']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""``couture bench extremes``: every solver at the ends of the parameter ranges.

Two scenes:

- the default skirt (``couture/pattern/examples/default_skirt.json``) on the
  mannequin, meshed by the remesher at ``--skirt-vertices`` (default 1600,
  the design's coarse level), one level solved from its placement as a solver
  node solves a level, but to the fine level's tolerance ``--tol`` (1e-4); the
  10k-vertex fine drapes are ``couture bench drape``'s;
- SC Fig. 5's strip: a 0.8 m x 0.25 m strip pinned at one end, lying over a
  sphere of radius 0.2 m, the rest hanging (``tests/sens_testmodel.py``'s
  ``strip_over_sphere``, here on a ``--strip-grid`` grid, friction on).

Cases, per scene and solver (newton, kinetic, verlet), each against the
default design with one thing changed:

- fabric: stretch 10..1e4 N/m, bending 1e-9..1e-3 N m, density
  0.02..2 kg/m², Poisson ratio 0..0.49 (:data:`SWEEPS`);
- scene: seam and contact stiffness 1e-2..1e2 times the default
  (``SceneFlags.seam_stiffness_scale``, ``contact_stiffness_scale``; the strip
  has no seams, so no seam cases there);
- random initial placements (seeded): skirt panels each turned up to 0.5 rad
  about a random axis through their centroid and moved ~3 cm, the strip
  turned up to 1 rad about its pinned edge (down into the sphere or up),
  both with vertex noise of 0.2 mean edge lengths;
- huge edits (skirt): every sloper option to its minimum and to its
  maximum, one at a time, as a designer's slider jump: the remesher follows
  the default skirt's drape (draped by Newton once) to the edited pattern and
  the solver starts from the state it carried over (a topology option gives
  a new mesh and a fresh placement).

Each case runs in a worker process (``--jobs`` of them) under a time limit
(``--limit-skirt``, ``--limit-strip``); one whose solve does not return
within ``HANG_FACTOR`` x its limit + ``HANG_MARGIN_S`` is killed and counted
hung. Outcomes (:func:`classify`):

- converged: the solver says so and the independent checks pass, recomputed
  here on a fresh model from the returned positions (:func:`checks`): the
  relative residual from fresh forces (with the friction anchors the solver
  balanced against) <= tol, every anchor inside its static Coulomb cone
  (``common.verdict``'s allowance), the deepest vertex no deeper into the
  contact layer than its offset (no vertex inside the body), seams closed to
  1 mm (each seam emitter within 1 mm of its point on the other side);
- failed checks: the solver says converged but a check fails;
- diagnosed: stopped with a diagnosis (a cap, a stall, a detected
  divergence, or the remesher rejecting the design);
- undiagnosed: stopped with an empty diagnosis;
- blew up: non-finite positions, the cloth torn apart (an edge stretched
  more than ``BLOWUP_STRETCH`` times its rest length), an exception, or the
  worker process died;
- hung: killed at the hang deadline.

A stop whose garment no longer touches the body (a static solve sliding off
it and falling, whole) is flagged ``left_body``: a diagnosed stop, counted
apart in the summary, since its diagnosis (a cap) does not say so.

Verlet (``couture.solvers.verlet``) integrates the same ClothModel's forces
explicitly: every check applies to it as to the others.

Goals (:data:`GOALS`): 0 blow-ups, 0 hangs, every stop diagnosed, >= 95 %
converged, per solver. Writes ``DIR/extremes.json`` and the heat map
``DIR/extremes.png`` (``--out``, default bench/results/).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import selectors
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from bench import OWN_SOLVERS, add_out_arg, child_env, module_command, source_commit, write_results
from couture.pattern.io import EXAMPLES

SOLVERS = OWN_SOLVERS
"""the solvers run by default (the registry's, less the peer)"""
SCENES = ("skirt", "strip")
TOL = 1e-4
"""relative residual a case converges to (the solver node's fine tolerance)"""
SKIRT_VERTICES = 1600
"""target vertices of the skirt's one level (the default design's coarse level)"""
STRIP_GRID = (41, 11)
"""grid vertices along and across the strip"""
LIMIT_S = {"skirt": 30.0, "strip": 10.0}
"""[s] max_seconds given to each solve"""
SETUP_LIMIT_S = 300.0
"""[s] meshing, the edit's base drape and model building; beyond it the case is hung"""
HANG_FACTOR = 2.0
HANG_MARGIN_S = 15.0
"""a solve still running HANG_FACTOR x its limit + HANG_MARGIN_S [s] after it started is hung"""
SEAM_GAP_M = 1e-3
"""[m] seams count as closed when every emitter is this close to its point across the seam"""
BLOWUP_STRETCH = 10.0
"""an edge this many times its rest length: the cloth is torn apart (blown up);
the softest fabric here stretches well under 2x under its own weight"""
GOALS: dict[str, float] = {"blew_up": 0, "hung": 0, "undiagnosed": 0, "converged_fraction": 0.95}
"""per solver: at most this many blow-ups, hangs and undiagnosed stops, at least this fraction converged"""
OUTCOMES = ("converged", "failed_checks", "diagnosed", "undiagnosed", "blew_up", "hung")

SWEEPS: dict[str, tuple[float, ...]] = {
    "stretch_stiffness": (10.0, 100.0, 1e3, 1e4),
    "bend_stiffness": (1e-9, 1e-7, 1e-5, 1e-3),
    "area_density": (0.02, 0.0928, 0.431, 2.0),
    "poisson_ratio": (0.0, 0.2, 0.4, 0.49),
    "seam_stiffness_scale": (1e-2, 1e-1, 1e1, 1e2),
    "contact_stiffness_scale": (1e-2, 1e-1, 1e1, 1e2),
}
"""knob -> values: fabric fields [SI] and scene factors (dimensionless); the default design is the baseline"""
FABRIC_KNOBS = ("stretch_stiffness", "bend_stiffness", "area_density", "poisson_ratio")
SCENE_KNOBS = ("seam_stiffness_scale", "contact_stiffness_scale")
SEEDS = (1, 2, 3)
"""random placements"""


# -- cases ----------------------------------------------------------------------------------------


def case_list(
    scenes: tuple[str, ...] = SCENES,
    solvers: tuple[str, ...] = SOLVERS,
    *,
    quick: bool = False,
    tol: float = TOL,
    limits: dict[str, float] | None = None,
) -> list[dict[str, Any]]:
    """Every case as a JSON-able spec (scene, solver, kind, knob, value, seed, limit_s, tol).
    ``quick``: the two ends of each sweep, one seed, edits of two options."""
    from couture.pattern.slopers import SKIRT_OPTIONS

    limits = dict(LIMIT_S, **(limits or {}))
    specs: list[dict[str, Any]] = []
    for scene in scenes:
        variants: list[dict[str, Any]] = [{"kind": "baseline"}]
        for knob, values in SWEEPS.items():
            if scene == "strip" and knob == "seam_stiffness_scale":
                continue  # the strip has no seams
            for v in (values[0], values[-1]) if quick else values:
                variants.append({"kind": "fabric" if knob in FABRIC_KNOBS else "scene", "knob": knob, "value": v})
        for seed in SEEDS[:1] if quick else SEEDS:
            variants.append({"kind": "placement", "seed": seed})
        if scene == "skirt":
            options = [o for o in SKIRT_OPTIONS if not quick or o.name in ("length", "panels")]
            for o in options:
                for end in ("min", "max"):
                    variants.append({"kind": "edit", "knob": o.name, "end": end, "value": getattr(o, end)})
        for solver in solvers:
            for variant in variants:
                spec = {"scene": scene, "solver": solver, "limit_s": limits[scene], "tol": tol, **variant}
                spec["label"] = case_label(spec)
                specs.append(spec)
    return specs


def case_label(spec: dict[str, Any]) -> str:
    """'stretch_stiffness=1e+04', 'placement seed 2', 'edit length max', 'baseline'."""
    kind = spec["kind"]
    if kind in ("fabric", "scene"):
        return f"{spec['knob']}={spec['value']:.3g}"
    if kind == "placement":
        return f"placement seed {spec['seed']}" if spec.get("seed") != "nan" else "placement NaN"
    if kind == "edit":
        return f"edit {spec['knob']} {spec['end']} ({spec['value']:g})"
    return "baseline"


# -- scenes ---------------------------------------------------------------------------------------


def _design(spec: dict[str, Any], skirt_vertices: int):
    """The default skirt design with the case's fabric or scene knob, at the bench resolution."""
    import msgspec

    from couture.pattern.io import load_design

    d = load_design(EXAMPLES / "default_skirt.json")
    n = int(skirt_vertices)
    d = msgspec.structs.replace(d, resolution=msgspec.structs.replace(d.resolution, coarse_vertices=n, fine_vertices=n))
    if spec["kind"] == "fabric":
        d = msgspec.structs.replace(d, fabric=msgspec.structs.replace(d.fabric, **{spec["knob"]: spec["value"]}))
    elif spec["kind"] == "scene":
        d = msgspec.structs.replace(d, scene=msgspec.structs.replace(d.scene, **{spec["knob"]: spec["value"]}))
    return d


_BASE_DRAPE: dict[int, np.ndarray] = {}
"""skirt vertices -> the default skirt's Newton drape (the edits' starting state), per worker"""


def _base_drape(design, mesh) -> np.ndarray:
    from couture.cloth.model import ClothModel
    from couture.solvers import get_solver
    from couture.solvers.service import scene_from_design

    x = _BASE_DRAPE.get(mesh.n_vertices)
    if x is None:
        model = ClothModel(mesh, design.fabric, scene_from_design(design))
        r = get_solver("newton").solve(model, mesh.x0, tol=TOL, max_seconds=SETUP_LIMIT_S / 2)
        if not r.converged:
            raise RuntimeError(f"the default skirt's base drape did not converge: {r.diagnosis}")
        x = _BASE_DRAPE[mesh.n_vertices] = r.x
    return x


def skirt_case(spec: dict[str, Any], skirt_vertices: int) -> tuple[Any, np.ndarray, dict[str, Any]]:
    """(model, start positions, notes) for a skirt case, meshed by the remesher and
    modelled as the solver node models it. Raises PatternError for a rejected design."""
    import msgspec

    from couture.cloth.model import ClothModel
    from couture.remesh.service import RemeshService
    from couture.solvers.service import scene_from_design

    design = _design(spec, skirt_vertices)
    remesher = RemeshService()
    up = remesher.set_design(design, 1)[0]
    notes: dict[str, Any] = {}
    if spec["kind"] == "edit":
        remesher.note_drape("coarse", up.mesh_generation, _base_drape(design, up.mesh))
        params = dict(design.sloper.params, **{spec["knob"]: spec["value"]})
        design = msgspec.structs.replace(design, sloper=msgspec.structs.replace(design.sloper, params=params))
        up = remesher.set_design(design, 2)[0]
        notes["remesher"] = up.how
    mesh = up.mesh
    model = ClothModel(mesh, design.fabric, scene_from_design(design))
    x0 = np.array(mesh.x0, dtype=np.float64)
    if spec["kind"] == "placement":
        x0 = perturbed(model, x0, spec["seed"], turn=0.5, shift=0.03)
    return model, x0, notes


def strip_case(spec: dict[str, Any], grid: tuple[int, int]) -> tuple[Any, np.ndarray, dict[str, Any]]:
    """(model, start, notes) for SC Fig. 5's strip over a sphere with the case's knob."""
    import msgspec

    from couture.cloth.body import SphereBody
    from couture.cloth.model import ClothModel
    from couture.mesh import grid_sheet
    from couture.solvers.service import scene_from_design
    from schemas.design import Design

    length, width, radius = 0.8, 0.25, 0.2
    nx, ny = grid
    mesh = grid_sheet(length, width, nx, ny)
    X = mesh.X
    h = length / (nx - 1)
    mesh.pinned = np.nonzero(X[:, 0] < 0.25 * h)[0].astype(np.int32)
    mesh.x0 = np.column_stack([X[:, 0] - 0.05, np.full(len(X), radius + 0.05), X[:, 1] - width / 2])
    design = Design()
    if spec["kind"] == "fabric":
        design = msgspec.structs.replace(
            design, fabric=msgspec.structs.replace(design.fabric, **{spec["knob"]: spec["value"]})
        )
    elif spec["kind"] == "scene":
        design = msgspec.structs.replace(
            design, scene=msgspec.structs.replace(design.scene, **{spec["knob"]: spec["value"]})
        )
    scene = dataclasses.replace(scene_from_design(design), body=SphereBody(center=np.zeros(3), radius=radius))
    model = ClothModel(mesh, design.fabric, scene)
    x0 = np.array(mesh.x0, dtype=np.float64)
    if spec["kind"] == "placement":
        x0 = perturbed(model, x0, spec["seed"], turn=1.0, shift=0.0, axis_point=mesh.x0[mesh.pinned].mean(axis=0))
    return model, x0, {}


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    a = axis / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def perturbed(
    model,
    x0: np.ndarray,
    seed: int | str,
    *,
    turn: float,
    shift: float,
    axis_point: np.ndarray | None = None,
    noise: float = 0.2,
) -> np.ndarray:
    """A random placement: each panel turned by up to ``turn`` [rad] and moved by
    ``shift`` [m] (standard deviation per axis), then every free vertex moved by
    ``noise`` mean edge lengths. With ``axis_point`` the whole mesh turns about the
    z axis through it (the strip about its pinned edge). Pinned vertices stay
    (the model holds them at their x0). ``seed='nan'``: a non-finite start."""
    if seed == "nan":
        return np.full_like(x0, np.nan)
    rng = np.random.default_rng(int(seed))
    mesh = model.mesh
    x = np.array(x0, dtype=np.float64)
    vp = np.zeros(mesh.n_vertices, np.int64)
    vp[mesh.tris.reshape(-1)] = np.repeat(mesh.tri_panel, 3)
    for p in np.unique(vp):
        idx = np.nonzero(vp == p)[0]
        if axis_point is not None:
            c, R = axis_point, _rotation(np.array([0.0, 0.0, 1.0]), rng.uniform(-turn, turn))
        else:
            c, R = x[idx].mean(axis=0), _rotation(rng.normal(size=3), rng.uniform(-turn, turn))
        x[idx] = (x[idx] - c) @ R.T + c + rng.normal(scale=shift, size=3)
    e = x0[mesh.tris[:, 1]] - x0[mesh.tris[:, 0]]
    h = float(np.mean(np.linalg.norm(e, axis=1)))
    x += rng.normal(scale=noise * h, size=x.shape)
    pinned = ~model.free
    x[pinned] = x0[pinned]
    return x


# -- checks and classification --------------------------------------------------------------------


def checks(model, x: np.ndarray, tol: float) -> dict[str, Any]:
    """The independent checks of a returned state, on a fresh model built from the
    same mesh, fabric and scene (the friction anchors copied from the solver's
    model: a residual means nothing without the anchors it balances against).
    Each check: its value and ``ok`` (None where it does not apply)."""
    from couture.cloth.model import ClothModel
    from couture.solvers.common import friction_allowance

    scene = dataclasses.replace(model.scene, body=model.body) if model.body is not None else model.scene
    fresh = ClothModel(model.mesh, model.fabric, scene)
    fresh.set_friction_state(model.friction_state())
    x = np.ascontiguousarray(x, dtype=np.float64)
    out: dict[str, Any] = {}
    r = float(fresh.relative_residual(x))
    out["residual"] = {"value": r, "limit": tol, "ok": bool(np.isfinite(r) and r <= tol)}
    if "friction" in fresh.terms:
        excess = float(fresh.friction_excess(x))
        allowed = float(friction_allowance(fresh, x, tol))
        out["friction_cone"] = {"excess_n": excess, "allowed_n": allowed, "ok": bool(excess <= allowed)}
    else:
        out["friction_cone"] = {"ok": None}
    if fresh.body is not None:
        phi, _ = fresh.body.phi_grad(x)
        deepest = float(fresh.contact_offset - np.min(phi)) if len(phi) else 0.0
        out["penetration"] = {
            "deepest_m": deepest,
            "offset_m": fresh.contact_offset,
            "ok": bool(np.isfinite(deepest) and deepest <= fresh.contact_offset),
        }
    else:
        out["penetration"] = {"ok": None}
    if fresh.has_seams:
        gap = np.linalg.norm(np.einsum("ek,ekd->ed", fresh.seam_w, x[fresh.seam_stencils]), axis=1)
        worst = float(np.max(gap))
        out["seams"] = {
            "max_gap_m": worst,
            "limit_m": SEAM_GAP_M,
            "worst_emitter": int(fresh.seam_stencils[int(np.argmax(gap)), 0]),
            "ok": bool(np.isfinite(worst) and worst <= SEAM_GAP_M),
        }
    else:
        out["seams"] = {"ok": None}
    return out


def max_edge_stretch(model, x: np.ndarray) -> float:
    """Largest edge length over its rest length: about 1 for a garment that is
    whole wherever it went, far above for one torn apart by a blow-up."""
    t = model.mesh.tris
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    rest = np.linalg.norm(model.X[e[:, 1]] - model.X[e[:, 0]], axis=1)
    now = np.linalg.norm(x[e[:, 1]] - x[e[:, 0]], axis=1)
    return float(np.max(now / np.maximum(rest, 1e-300)))


def classify(
    *,
    converged: bool,
    diagnosis: str,
    finite: bool,
    max_edge_stretch: float,
    checks: dict[str, Any] | None,
    error: str = "",
) -> str:
    """One of :data:`OUTCOMES` (but 'hung', which only the parent sees)."""
    if error or not finite or not np.isfinite(max_edge_stretch) or max_edge_stretch > BLOWUP_STRETCH:
        return "blew_up"
    if converged:
        failed = [k for k, c in (checks or {}).items() if c.get("ok") is False]
        return "failed_checks" if failed else "converged"
    return "diagnosed" if diagnosis.strip() else "undiagnosed"


def stop_kind(diagnosis: str) -> str:
    """The kind of stop a diagnosis names, for the table: 'max_seconds', 'stalled', ..."""
    d = diagnosis.strip()
    if not d:
        return ""
    for kind in (
        "rejected",
        "max_seconds",
        "max_iters",
        "stalled",
        "diverged",
        "friction",
        "in body",
        "exception",
        "worker",
    ):
        if d.startswith(kind):
            return kind
    return d.split()[0].rstrip(":;,")


# -- one case (in a worker) -----------------------------------------------------------------------


def run_case(
    spec: dict[str, Any],
    *,
    skirt_vertices: int = SKIRT_VERTICES,
    strip_grid: tuple[int, int] = STRIP_GRID,
    on_solving: Callable[[], None] = lambda: None,
) -> dict[str, Any]:
    """Build the case, call ``on_solving`` as the solve starts, solve, check, classify."""
    from couture.pattern.errors import PatternError
    from couture.solvers import get_solver

    row: dict[str, Any] = {k: spec[k] for k in spec}
    t0 = time.perf_counter()
    try:
        if spec["scene"] == "skirt":
            model, x0, notes = skirt_case(spec, skirt_vertices)
        else:
            model, x0, notes = strip_case(spec, strip_grid)
    except PatternError as e:
        row.update(outcome="diagnosed", diagnosis=f"rejected by the remesher: {e}", stop="rejected")
        row["setup_s"] = time.perf_counter() - t0
        return row
    row.update(notes, vertices=int(model.n), setup_s=time.perf_counter() - t0)
    on_solving()
    t1 = time.perf_counter()
    try:
        solver = get_solver(spec["solver"])
        # friction from the first iteration, as the solver node solves a level from its
        # placement (couture.solvers.service.FRICTION_AT_ONCE)
        res = solver.solve(
            model, x0, tol=float(spec["tol"]), max_seconds=float(spec["limit_s"]), friction_after=math.inf
        )
    except Exception as e:  # noqa: BLE001 - a solver that raises has blown up; say how
        row.update(outcome="blew_up", diagnosis=f"exception: {type(e).__name__}: {e}", stop="exception")
        row["wall_s"] = time.perf_counter() - t1
        return row
    x = np.asarray(res.x, dtype=np.float64)
    # positions decide: a solver refusing a non-finite start returns finite zeros,
    # an infinite residual and a diagnosis (a stop, not a blow-up)
    finite = bool(np.all(np.isfinite(x)))
    start = np.where(np.isfinite(x0), x0, 0.0)
    move = float(np.max(np.linalg.norm(x - start, axis=1))) if finite and len(x) else float("inf")
    chk = checks(model, x, float(spec["tol"])) if finite else None
    stretch = max_edge_stretch(model, x) if finite else None
    outcome = classify(
        converged=bool(res.converged),
        diagnosis=res.diagnosis,
        finite=finite,
        max_edge_stretch=stretch if stretch is not None else float("inf"),
        checks=chk,
    )
    if outcome == "blew_up":
        row["blew_up_because"] = (
            "non-finite positions"
            if not finite
            else f"torn apart: an edge stretched {stretch:.3g}x its rest length (> {BLOWUP_STRETCH:g}x)"
        )
    pen = (chk or {}).get("penetration", {})
    if outcome != "converged" and pen.get("deepest_m") is not None and pen["deepest_m"] < 0:
        row["left_body"] = True  # no vertex inside the contact layer
    row.update(
        outcome=outcome,
        converged_by_solver=bool(res.converged),
        residual=float(res.residual) if np.isfinite(res.residual) else None,
        iterations=int(res.iterations),
        wall_s=float(res.wall_time),
        diagnosis=res.diagnosis,
        stop="" if res.converged else stop_kind(res.diagnosis),
        max_move_m=move if np.isfinite(move) else None,
        max_edge_stretch=stretch,
        checks=chk,
        failed_checks=[k for k, c in (chk or {}).items() if c.get("ok") is False],
    )
    return row


def worker_main(skirt_vertices: int, strip_grid: tuple[int, int]) -> int:
    """A worker: one JSON spec a line on stdin; on stdout ``{"event": "solving"}``
    when a solve starts and ``{"event": "done", "row": ...}`` when it is over.
    Anything else the case prints goes to stderr."""
    import logging

    logging.basicConfig(level=logging.ERROR)
    out = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    sys.stdout = sys.stderr

    def send(msg: dict[str, Any]) -> None:
        out.write(json.dumps(msg, default=_json_default) + "\n")
        out.flush()

    for line in sys.stdin:
        if not line.strip():
            continue
        spec = json.loads(line)
        row = run_case(
            spec,
            skirt_vertices=skirt_vertices,
            strip_grid=strip_grid,
            on_solving=lambda: send({"event": "solving"}),
        )
        send({"event": "done", "row": row})
    return 0


def _json_default(v: Any) -> Any:
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    raise TypeError(f"cannot write {type(v).__name__} as JSON")


# -- the parent: workers, deadlines ---------------------------------------------------------------


@dataclasses.dataclass
class _Worker:
    proc: subprocess.Popen
    stderr_path: str
    buf: bytes = b""
    spec: dict[str, Any] | None = None
    deadline: float = 0.0
    solving_since: float | None = None
    started: float = 0.0

    def tail(self, n: int = 600) -> str:
        try:
            return Path(self.stderr_path).read_text(errors="replace")[-n:].strip()
        except OSError:
            return ""


def worker_command(skirt_vertices: int, strip_grid: tuple[int, int]) -> list[str]:
    nx, ny = strip_grid
    return module_command("extremes", "--worker", "--skirt-vertices", str(skirt_vertices), "--strip-grid", f"{nx}x{ny}")


def run_cases(
    specs: list[dict[str, Any]],
    *,
    jobs: int = 1,
    command: list[str] | None = None,
    skirt_vertices: int = SKIRT_VERTICES,
    strip_grid: tuple[int, int] = STRIP_GRID,
    hang_factor: float = HANG_FACTOR,
    hang_margin_s: float = HANG_MARGIN_S,
    setup_limit_s: float = SETUP_LIMIT_S,
    on_row: Callable[[int, int, dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Run every spec in worker processes (``command``, default this module's
    ``--worker``), at most ``jobs`` at once; a worker whose case passes its
    deadline is killed (the case is hung) and a fresh one takes the next case.
    Returns the rows in the order of ``specs``."""
    cmd = command or worker_command(skirt_vertices, strip_grid)
    env = child_env()
    if jobs > 1:  # one core each
        for k in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
            env[k] = "1"
    rows: list[dict[str, Any] | None] = [None] * len(specs)
    pending = list(range(len(specs)))[::-1]
    sel = selectors.DefaultSelector()
    workers: list[_Worker] = []
    tmp = tempfile.TemporaryDirectory(prefix="couture-extremes-")
    done = 0

    def spawn() -> _Worker:
        path = os.path.join(tmp.name, f"worker{len(workers)}-{time.monotonic_ns()}.err")
        with open(path, "wb") as err:
            proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=err, env=env)
        w = _Worker(proc, path)
        assert proc.stdout is not None
        os.set_blocking(proc.stdout.fileno(), False)
        sel.register(proc.stdout, selectors.EVENT_READ, w)
        workers.append(w)
        return w

    def retire(w: _Worker) -> None:
        if w.proc.stdout is not None:
            sel.unregister(w.proc.stdout)
        if w.proc.poll() is None:
            w.proc.kill()
        w.proc.wait()
        workers.remove(w)

    def finish(w: _Worker, row: dict[str, Any]) -> None:
        nonlocal done
        assert w.spec is not None
        i = w.spec["_index"]
        row.pop("_index", None)
        rows[i] = row
        done += 1
        w.spec = None
        if on_row is not None:
            on_row(done, len(specs), row)

    def give(w: _Worker) -> None:
        i = pending.pop()
        w.spec = dict(specs[i], _index=i)
        w.started = time.monotonic()
        w.solving_since = None
        w.deadline = w.started + setup_limit_s
        assert w.proc.stdin is not None
        try:
            w.proc.stdin.write((json.dumps(w.spec) + "\n").encode())
            w.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            pass  # a dead worker: its EOF says so

    try:
        while pending or any(w.spec is not None for w in workers):
            while pending and len([w for w in workers if w.spec is not None]) < jobs:
                idle = next((w for w in workers if w.spec is None), None) or spawn()
                give(idle)
            now = time.monotonic()
            busy = [w for w in workers if w.spec is not None]
            timeout = max(0.0, min(w.deadline for w in busy) - now) if busy else None
            for key, _ in sel.select(timeout):
                w = key.data
                try:
                    chunk = os.read(key.fd, 65536)
                except BlockingIOError:
                    continue
                if not chunk:  # the worker died
                    if w.spec is not None:
                        spec = w.spec
                        code = w.proc.wait()
                        tail = w.tail()
                        finish(
                            w,
                            dict(
                                spec,
                                outcome="blew_up",
                                stop="worker",
                                diagnosis=f"worker process died (exit code {code})" + (f": {tail}" if tail else ""),
                            ),
                        )
                    retire(w)
                    continue
                w.buf += chunk
                while b"\n" in w.buf:
                    line, w.buf = w.buf.split(b"\n", 1)
                    try:
                        msg = json.loads(line)
                    except json.JSONDecodeError:
                        continue
                    if msg.get("event") == "solving" and w.spec is not None:
                        w.solving_since = time.monotonic()
                        w.deadline = w.solving_since + hang_factor * float(w.spec["limit_s"]) + hang_margin_s
                    elif msg.get("event") == "done" and w.spec is not None:
                        finish(w, msg["row"])
            now = time.monotonic()
            for w in [w for w in workers if w.spec is not None and now > w.deadline]:
                spec = w.spec
                assert spec is not None
                stage = "solve" if w.solving_since is not None else "setup"
                since = w.solving_since if w.solving_since is not None else w.started
                finish(
                    w,
                    dict(
                        spec,
                        outcome="hung",
                        stop="hung",
                        diagnosis=f"no result {now - since:.0f} s into its {stage} (limit {spec['limit_s']:g} s): killed",
                    ),
                )
                retire(w)
    finally:
        for w in list(workers):
            if w.proc.stdin is not None:
                try:
                    w.proc.stdin.close()
                except OSError:
                    pass
            try:
                w.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                pass
            retire(w)
        tmp.cleanup()
    return [r for r in rows if r is not None]


# -- summary, table, heat map ---------------------------------------------------------------------


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per solver (and per scene x solver): outcome counts, converged fraction, goals met."""

    def count(sel: list[dict[str, Any]]) -> dict[str, Any]:
        c = {o: sum(r["outcome"] == o for r in sel) for o in OUTCOMES}
        n = len(sel)
        frac = c["converged"] / n if n else None
        goals = {
            "blew_up": c["blew_up"] <= GOALS["blew_up"],
            "hung": c["hung"] <= GOALS["hung"],
            "undiagnosed": c["undiagnosed"] <= GOALS["undiagnosed"],
            "converged_fraction": frac is not None and frac >= GOALS["converged_fraction"],
        }
        return {
            "cases": n,
            **c,
            "left_body": sum(bool(r.get("left_body")) for r in sel),
            "converged_fraction": frac,
            "goals_met": goals,
            "all_goals_met": all(goals.values()),
        }

    solvers = sorted({r["solver"] for r in rows}, key=lambda s: SOLVERS.index(s) if s in SOLVERS else 99)
    scenes = sorted({r["scene"] for r in rows}, key=lambda s: SCENES.index(s) if s in SCENES else 99)
    return {
        "all": count(rows),
        "by_solver": {s: count([r for r in rows if r["solver"] == s]) for s in solvers},
        "by_scene_solver": {
            f"{sc}/{s}": count([r for r in rows if r["scene"] == sc and r["solver"] == s])
            for sc in scenes
            for s in solvers
        },
    }


def worst_cases(rows: list[dict[str, Any]], n: int = 12) -> list[dict[str, Any]]:
    """The cases furthest from converged: hung, blown up, undiagnosed, failed checks,
    then diagnosed stops by residual (largest first)."""
    rank = {"hung": 0, "blew_up": 1, "undiagnosed": 2, "failed_checks": 3, "diagnosed": 4, "converged": 5}
    bad = [r for r in rows if r["outcome"] != "converged"]
    bad.sort(key=lambda r: (rank[r["outcome"]], -(r.get("residual") or np.inf)))
    keys = ("scene", "solver", "label", "outcome", "residual", "diagnosis", "failed_checks", "blew_up_because")
    return [{k: r.get(k) for k in keys} for r in bad[:n]]


def _fmt_row(r: dict[str, Any]) -> str:
    res = r.get("residual")
    t = r.get("wall_s")
    extra = r.get("diagnosis") or ""
    if r["outcome"] == "failed_checks":
        extra = "checks failed: " + ", ".join(r.get("failed_checks", []))
    if r.get("blew_up_because"):
        extra = f"{r['blew_up_because']}; {extra}"
    if r.get("left_body"):
        extra = f"left the body; {extra}"
    return (
        f"{r['scene']:6s} {r['solver']:8s} {r['label'][:38]:38s} {r['outcome']:13s} "
        f"{'-' if res is None else f'{res:9.2e}':>9s} {'-' if t is None else f'{t:6.1f}':>6s}  {extra[:90]}"
    )


def print_table(rows: list[dict[str, Any]], summ: dict[str, Any]) -> None:
    print(f"{'scene':6s} {'solver':8s} {'case':38s} {'outcome':13s} {'residual':>9s} {'s':>6s}  diagnosis")
    for r in rows:
        print(_fmt_row(r))
    print()
    print(f"{'solver':10s} {'cases':>5s} " + " ".join(f"{o:>13s}" for o in OUTCOMES) + "  left body  converged  goals")
    for name, c in [*summ["by_solver"].items(), ("all", summ["all"])]:
        frac = c["converged_fraction"]
        print(
            f"{name:10s} {c['cases']:5d} "
            + " ".join(f"{c[o]:13d}" for o in OUTCOMES)
            + f"  {c['left_body']:9d}"
            + f"  {'-' if frac is None else f'{100 * frac:8.1f}%'}  "
            + ("met" if c["all_goals_met"] else "missed: " + ", ".join(k for k, v in c["goals_met"].items() if not v))
        )
    print(
        f"goals per solver: {GOALS['blew_up']:g} blow-ups, {GOALS['hung']:g} hangs, every stop diagnosed, "
        f">= {100 * GOALS['converged_fraction']:.0f} % converged"
    )


CHECK_NAMES = {"residual": "residual", "friction_cone": "friction", "penetration": "in body", "seams": "seam gap"}
"""short names of the checks, for the heat map's cells"""

COLOURS = {
    "converged": "#4caf50",
    "failed_checks": "#ffb300",
    "diagnosed": "#90a4ae",
    "undiagnosed": "#8e24aa",
    "blew_up": "#e53935",
    "hung": "#212121",
}


def plot(rows: list[dict[str, Any]], path: Path, title: str = "") -> None:
    """Heat map: one panel per scene, a row per case, a column per solver, coloured
    by outcome; each cell says the residual reached (or the kind of stop)."""
    import logging

    import matplotlib

    matplotlib.use("Agg")
    logging.getLogger("matplotlib").setLevel(logging.WARNING)
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_rgb
    from matplotlib.patches import Patch

    scenes = [s for s in SCENES if any(r["scene"] == s for r in rows)]
    solvers = [s for s in SOLVERS if any(r["solver"] == s for r in rows)]
    labels = {sc: list(dict.fromkeys(r["label"] for r in rows if r["scene"] == sc)) for sc in scenes}
    height = max(len(v) for v in labels.values()) if labels else 1
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.6 * len(scenes) + 1.0, 0.24 * height + 1.8), squeeze=False)
    for ax, sc in zip(axes[0], scenes, strict=True):
        cases = labels[sc]
        img = np.ones((len(cases), len(solvers), 3))
        for r in rows:
            if r["scene"] != sc:
                continue
            i, j = cases.index(r["label"]), solvers.index(r["solver"])
            img[i, j] = to_rgb(COLOURS[r["outcome"]])
            res = r.get("residual")
            text = r.get("stop") or ""
            if r["outcome"] in ("converged", "failed_checks") or (res is not None and not text):
                text = f"{res:.0e}" if res is not None else ""
            if r["outcome"] == "failed_checks":
                text = "x " + ",".join(CHECK_NAMES.get(c, c) for c in r.get("failed_checks", []))
            if r.get("left_body"):
                text = "left body"
            ax.text(
                j,
                i,
                text[:14],
                ha="center",
                va="center",
                fontsize=6,
                color="white" if r["outcome"] == "hung" else "black",
            )
        ax.imshow(img, aspect="auto", interpolation="nearest")
        ax.set_xticks(range(len(solvers)), solvers, fontsize=8)
        ax.xaxis.tick_top()
        ax.set_yticks(range(len(cases)), cases, fontsize=6.5)
        ax.set_title(sc, fontsize=10, pad=18)
        ax.set_xticks(np.arange(-0.5, len(solvers)), minor=True)
        ax.set_yticks(np.arange(-0.5, len(cases)), minor=True)
        ax.grid(which="minor", color="white", lw=0.8)
        ax.tick_params(which="minor", length=0)
    fig.legend(
        handles=[Patch(color=c, label=o.replace("_", " ")) for o, c in COLOURS.items()],
        loc="lower center",
        bbox_to_anchor=(0.5, 0.02),
        ncol=min(len(COLOURS), 3 * len(scenes)),
        fontsize=7,
        frameon=False,
    )
    fig.text(
        0.5,
        0.005,
        "cell: relative residual reached, the stop, or the failed check",
        ha="center",
        va="bottom",
        fontsize=7,
    )
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout(rect=(0, 0.06, 1, 0.96))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_report(report: dict[str, Any], path: Path) -> None:
    """The heat map of a report (what ``main`` writes; also from a saved extremes.json)."""
    c = report["summary"]["by_solver"]
    plot(
        report["cases"],
        path,
        title=f"couture bench extremes (tol {report['settings']['tol']:g})\n"
        + "; ".join(f"{s} {v['converged']}/{v['cases']} converged" for s, v in c.items()),
    )


# -- command line ---------------------------------------------------------------------------------


def _grid(s: str) -> tuple[int, int]:
    nx, ny = (int(v) for v in s.lower().split("x"))
    return nx, ny


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="couture bench extremes",
        description=__doc__.split("\n\n")[0],
        epilog="outcomes: converged (checks passed), failed checks, diagnosed, undiagnosed, blew up, hung",
    )
    ap.add_argument("--scenes", default=",".join(SCENES), help="comma list of skirt,strip")
    ap.add_argument("--solvers", default=",".join(SOLVERS), help=f"comma list of {','.join(SOLVERS)}")
    ap.add_argument("--skirt-vertices", type=int, default=SKIRT_VERTICES, help="target vertices of the skirt's level")
    ap.add_argument("--strip-grid", type=_grid, default=STRIP_GRID, help="strip grid NXxNY (default 41x11)")
    ap.add_argument("--tol", type=float, default=TOL, help="relative residual to converge to")
    ap.add_argument("--limit-skirt", type=float, default=LIMIT_S["skirt"], help="[s] max_seconds per skirt solve")
    ap.add_argument("--limit-strip", type=float, default=LIMIT_S["strip"], help="[s] max_seconds per strip solve")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes at once (one thread each when > 1)")
    ap.add_argument("--quick", action="store_true", help="the ends of each sweep, one seed, two edits")
    add_out_arg(ap)
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.worker:
        return worker_main(a.skirt_vertices, a.strip_grid)

    scenes = tuple(s for s in a.scenes.split(",") if s)
    solvers = tuple(s for s in a.solvers.split(",") if s)
    for s in scenes:
        if s not in SCENES:
            ap.error(f"unknown scene {s!r}; scenes are {', '.join(SCENES)}")
    for s in solvers:
        if s not in SOLVERS:
            ap.error(f"unknown solver {s!r}; solvers are {', '.join(SOLVERS)}")
    specs = case_list(
        scenes, solvers, quick=a.quick, tol=a.tol, limits={"skirt": a.limit_skirt, "strip": a.limit_strip}
    )
    print(
        f"{len(specs)} cases ({', '.join(scenes)} x {', '.join(solvers)}), {a.jobs} at once; skirt at "
        f"~{a.skirt_vertices} vertices (one level, from its placement), strip {a.strip_grid[0]}x{a.strip_grid[1]}",
        file=sys.stderr,
        flush=True,
    )

    def progress(k: int, n: int, r: dict[str, Any]) -> None:
        print(f"[{k}/{n}] {_fmt_row(r)}", file=sys.stderr, flush=True)

    t0 = time.perf_counter()
    rows = run_cases(specs, jobs=a.jobs, skirt_vertices=a.skirt_vertices, strip_grid=a.strip_grid, on_row=progress)
    total = time.perf_counter() - t0
    summ = summary(rows)
    print_table(rows, summ)
    report = {
        "bench": "extremes",
        "settings": {
            "tol": a.tol,
            "limit_s": {"skirt": a.limit_skirt, "strip": a.limit_strip},
            "hang_deadline": f"{HANG_FACTOR:g} x limit + {HANG_MARGIN_S:g} s after the solve starts "
            f"({SETUP_LIMIT_S:g} s for the setup)",
            "skirt": f"default_skirt.json meshed by the remesher at ~{a.skirt_vertices} vertices, one level, "
            "solved from its placement (edits: from the default skirt's Newton drape carried over)",
            "strip": f"SC Fig. 5 strip 0.8 m x 0.25 m over a 0.2 m sphere, grid {a.strip_grid[0]}x{a.strip_grid[1]}, "
            "pinned at one end, friction on",
            "sweeps": {k: list(v) for k, v in SWEEPS.items()},
            "seeds": list(SEEDS[:1] if a.quick else SEEDS),
            "seam_gap_limit_m": SEAM_GAP_M,
            "blowup_edge_stretch": BLOWUP_STRETCH,
            "jobs": a.jobs,
            "quick": a.quick,
        },
        "goals": GOALS,
        "summary": summ,
        "worst": worst_cases(rows),
        "wall_s": total,
        "machine": {
            "platform": platform.platform(),
            "python": platform.python_version(),
            "cpus": os.cpu_count(),
            "load_average_at_end": list(os.getloadavg()),
        },
        "commit": source_commit(),
        "cases": rows,
    }
    out = write_results(a.out, "extremes", report, default=_json_default)
    png = Path(a.out) / "extremes.png"
    plot_report(report, png)
    print(f"wrote {out} and {png} in {total:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Golden recordings: a design session as a regression test (DESIGN §3).

A *case* is ``recordings/<case>.json``::

    {"solvers": ["newton"],              # solver nodes to run
     "designs": ["examples/small_skirt.json", {"sloper": {"params": {"length": 0.7}}}, ...],
     "floor_m": 1e-4, "safety": 2.0,     # drapes: bound = floor_m + safety (r_g + r_a) ||F_g||/lambda_min [m]
     "cap_m": {"coarse": 0.03, "fine": 0.01},  # ... at most this per level [m]
     "rtol": 1e-3, "atol": 2e-3,        # meshes: float tolerances (positions in m), integers exact
     "timeout_s": 120}

Each entry of ``designs`` is a pattern file (relative to the case file or to
``couture/pattern/examples``) or a patch merged into the previous design.
Instead of ``designs`` a case may give ``steps``, a scripted session driven
through the bus (:mod:`couture.recording.steps`): designs, 2D drags of a
pattern handle at pointer rate (press, drags, release, then the UI's commit),
3D tugs on the hem, a solver switched mid-session, the solver SIGKILLed
mid-drag and restarted by the supervisor. ``designs`` is the same as one
design step per entry. The sensitivity node runs when there are gestures.

Predicted drapes depend on timing: how many predictions a gesture gets, and
at which pointer positions, depends on how fast the sensitivity node keeps
up with the pointer. So intermediate predictions are counted and reported,
never matched; the *release prediction* of every gesture (made at the
recorded release position, on the equilibrium of the design pressed on) must
be there, within ``floor_m + prediction_safety * b`` of the golden's (b: the
physics rule's bound on that generation's fine drape, at most the fine cap),
and a tug's design (the sensitivity node's pattern) must carry the golden's
parameters within ``tug_rtol`` (:func:`prediction_failures`). A check with a
kill also fails when no prediction of the gesture arrived after the SIGKILL
(a killed solver must not freeze the UI).

``make`` starts the nodes with a recorder, runs the steps (each design
waited for until its final drape/fine), and keeps the recording as
``recordings/<case>.mcap``. ``check`` starts the same nodes with a recorder,
replays the golden file's inputs in lockstep, step by step (the same solver
switches and kills at the same points, gestures at their recorded pointer
rate), and compares the outputs with the golden ones, physics not paths
(:func:`rule`, STYLE.md): each final drape has the golden's convergence
status, a converged one a residual within the solver node's tolerance, and
every vertex within ``floor_m + safety * (r_golden + r_actual) * ||F_g|| /
lambda_min`` of the golden, at most the level's ``cap_m`` (lambda_min: the
smallest eigenvalue of the exact free Hessian at the golden drape,
:func:`compliances`), and every seam spring's gap within ``SEAM_FLOOR_M +
safety * (r_golden + r_actual) * ||F_g|| / k_seam`` of the golden's
(:func:`seam_failures`: stiff seams hide from the position bound). Both
drapes are compared polished to ``POLISH_TOL`` on their own recording's model
(:func:`polisher`), and two that lie apart but each balance the other's model
are separate equilibria of the same physics (``PhysicsRule.polish``). Iterations
and wall times are reported, never compared. Meshes (what the remesher drafts) are
compared field by field within ``rtol``/``atol``, integers exactly; their
``x0`` carries the previous drape over, so only the cap holds there, or the
deviation of a previous drape of that level accepted as a separate
equilibrium, when larger.

``make`` records into a temporary file, replaces the golden, and prints what
changed against the old one (:func:`changes`: per topic the largest
deviation, per drape the iterations old -> new). ``python -m
couture.recording.golden`` is the same command as ``couture golden``.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import sys
import tempfile
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec

from couture import supervisor
from couture.bus import BusConfig
from couture.recording.compare import CompareReport, PhysicsRule, TopicReport, compare
from schemas.design import Design

log = logging.getLogger("couture.golden")

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"


@dataclass
class Case:
    name: str
    path: Path
    solvers: list[str] = field(default_factory=lambda: ["newton"])
    designs: list = field(default_factory=list)
    rtol: float = 1e-3
    atol: float = 2e-3
    """meshes only: float fields within atol + rtol * |golden| [field unit]"""
    floor_m: float = 1e-4
    """[m] a drape's vertices may always deviate this much (PhysicsRule.floor_m)"""
    safety: float = 2.0
    """factor on the first-order residual bound (PhysicsRule.safety)"""
    cap_m: dict[str, float] = field(default_factory=lambda: {"coarse": 0.03, "fine": 0.01})
    """level -> [m] never more than this (PhysicsRule.cap_m)"""
    timeout_s: float = 120.0
    steps: list = field(default_factory=list)
    """a scripted session (couture.recording.steps); empty: one design step per ``designs`` entry"""
    prediction_safety: float = 2.0
    """a gesture's release prediction may deviate ``floor_m`` + this times the
    bound of the fine drape it was made on, at most the fine cap (:func:`prediction_failures`)"""
    tug_rtol: float = 0.01
    """a tug's design parameter within this relative deviation of the golden's (:func:`prediction_failures`)"""
    cap_only: list[str] = field(default_factory=list)
    """levels whose drapes are held to their cap alone, not to the residual bound: a
    frictionless skirt's coarse level has near-null modes along which two converged
    drapes lie in separate equilibria (measured: the tugged skirt's coarse drape under
    SuperLU 41.6 mm from PARDISO's, residuals 1.0e-4 and 3.6e-6, bound 5 mm, while
    the fine drapes made from them agree to 0.003 mm)"""

    def all_steps(self) -> list:
        return self.steps or [{"design": d} for d in self.designs]

    @property
    def gestures(self) -> bool:
        return any(next(iter(st)) in ("drag", "tug") for st in self.all_steps())

    @property
    def tugs(self) -> bool:
        return any(next(iter(st)) == "tug" for st in self.all_steps())

    @property
    def n_designs(self) -> int:
        """designs the session drapes (design, drag and tug steps; a try-on op re-drapes the current one)"""
        return sum(next(iter(st)) not in ("switch_solver", "tryon") for st in self.all_steps())

    @property
    def mcap(self) -> Path:
        return self.path.with_suffix(".mcap")


def load_case(name_or_path: str) -> Case:
    p = Path(name_or_path)
    if not p.suffix:
        p = RECORDINGS / f"{name_or_path}.json"
    spec = json.loads(p.read_text())
    keys = {
        "solvers",
        "designs",
        "steps",
        "rtol",
        "atol",
        "floor_m",
        "safety",
        "cap_m",
        "timeout_s",
        "prediction_safety",
        "tug_rtol",
        "cap_only",
    }
    unknown = set(spec) - keys - {"doc"}
    if unknown:
        raise ValueError(f"{p}: unknown keys {sorted(unknown)}")
    if "steps" in spec and "designs" in spec:
        raise ValueError(f"{p}: give 'designs' or 'steps', not both")
    from couture.recording.steps import validate

    validate(spec.get("steps", []), str(p))
    return Case(name=p.stem, path=p, **{k: spec[k] for k in keys if k in spec})


def _nodes(case: Case, record: Path) -> list[supervisor.NodeSpec]:
    # the sensitivity node only where the case has gestures (it answers presses)
    return [
        n
        for n in supervisor.default_nodes(solvers=case.solvers, ui=False, record=str(record))
        if n.name != "sensitivity" or case.gestures
    ]


def _session() -> BusConfig:
    from couture.bus.ports import free_port

    return BusConfig(session=f"golden{uuid.uuid4().hex[:8]}", listen=[f"tcp/127.0.0.1:{free_port()}"])


def _wait_recorder(sup: supervisor.Supervisor, timeout: float = 60.0) -> None:
    """Wait until the nodes are live *and* the recorder's subscription reaches
    us: liveliness comes up before the recorder subscribes, and a publisher's
    matching status on ``pattern`` is already satisfied by the remesher. A
    probe key that only the recorder's ``couture/<session>/**`` matches tells."""
    from couture.bus import open_session
    from couture.bus.session import has_subscribers
    from couture.client import Client

    with Client(bus=sup.child_bus) as c:
        c.wait_nodes(list(sup.children), timeout)
    with open_session(sup.child_bus, name="golden-probe") as bus:
        probe = bus.zenoh.declare_publisher(bus.key(f"probe/{uuid.uuid4().hex[:8]}"))
        deadline = time.monotonic() + timeout
        while not has_subscribers(probe):
            if time.monotonic() > deadline:
                raise TimeoutError("the recorder never subscribed")
            time.sleep(0.02)
        probe.undeclare()


def make(case: Case) -> Path:
    """Record the case's session into ``case.mcap``: into a temporary file
    first, which replaces the golden only once the session is complete (a
    make that fails keeps the old golden)."""
    from couture.recording.parts import expand, numbered

    out = case.mcap
    new = out.with_name(f".{out.stem}.new.mcap")
    # a failed make's leftovers are this command's own scratch files, not recordings
    for stale in [new, *numbered(new).values()]:
        stale.unlink(missing_ok=True)
    _drive(case, new, None)
    files = expand(new)
    if len(files) > 1:  # messages sent while it was down are missing: not a golden
        raise RuntimeError(
            f"the recorder restarted during make ({', '.join(map(str, files))}); the golden "
            f"{out} is unchanged, make it again"
        )
    new.replace(out)
    return out


def changes(case: Case, old: Path, new: Path) -> str:
    """What a re-recording changed, per topic: the largest deviation, and per
    drape the status, residual, iterations and worst vertex, old -> new."""
    rep = compare_case(case, old, new, labels={"design_id"})
    lines = [f"[golden] {case.name}: what changed (old golden -> new recording)"]
    for name, t in sorted(rep.topics.items()):
        its = sum(r.iterations[0] for r in t.drapes), sum(r.iterations[1] for r in t.drapes)
        lines.append(
            f"  {name:<14} max deviation {t.worst_abs * 1e3:8.3f} mm"
            + (f"  iterations {its[0]} -> {its[1]}" if t.drapes else "")
            + (f"  ({t.worst_where})" if t.worst_where else "")
            + (f"  {len(t.missing)} missing, {len(t.extra)} new" if t.missing or t.extra else "")
        )
    lines.append(rep.text())
    verdict = "the new golden agrees with the old one" if rep.ok else "the physics changed (or the session did)"
    lines.append(f"[golden] {case.name}: {verdict}")
    return "\n".join(lines)


def solver_tolerances() -> dict[str, float]:
    """level -> relative residual the solver node converges to (the service's default)."""
    from couture.solvers.service import SolveService

    return dict(SolveService(method="newton").tol)


def _final_drapes(path: Path | str) -> dict[str, tuple[Any, Any, Design | None]]:
    """Match key of each final drape in a recording -> (DrapeMsg, the MeshMsg it
    was solved on or None, the design of that mesh's pattern or None)."""
    from couture.recording.compare import _match_key
    from couture.recording.mcapio import read_session
    from schemas.messages import DrapeMsg, MeshMsg, PatternMsg, decode

    designs: dict[str, Design] = {}
    meshes: dict[tuple[str, int], MeshMsg] = {}
    drapes: dict[str, DrapeMsg] = {}
    for rec in read_session(str(path), ["pattern", "mesh/coarse", "mesh/fine", "drape/coarse", "drape/fine"]):
        if rec.topic == "pattern":
            p = decode(rec.data, PatternMsg)
            designs[p.design_id] = p.design
        elif rec.topic.startswith("mesh/"):
            mm = decode(rec.data, MeshMsg)
            meshes[(mm.level, mm.mesh_generation)] = mm
        else:
            d = decode(rec.data, DrapeMsg)
            if d.final:
                drapes[_match_key(rec.topic, d)] = d
    out: dict[str, tuple[Any, Any, Design | None]] = {}
    for key, d in drapes.items():
        m = meshes.get((d.level, d.mesh_generation))
        out[key] = (d, m, designs.get(m.design_id) if m is not None else None)
    return out


def compliances(path: Path | str) -> dict[str, float]:
    """Match key of each final drape in a recording -> ||F_g|| / lambda_min [m]:
    the cloth model built as the solver node builds it (the recorded mesh and
    the design of its pattern message), its exact free Hessian at the drape
    (not the PSD-projected one the solvers factor: projection stiffens the
    compressed membrane, and the bound needs the true soft modes), the smallest
    eigenvalue by shift-invert Lanczos. A drape converged to relative residual
    r is within about r times this of the equilibrium; a non-positive
    lambda_min gives inf (the cap decides)."""
    import numpy as np
    import scipy.sparse.linalg as spla

    from couture.cloth.model import ClothModel
    from couture.solvers.service import scene_from_design
    from schemas.convert import msg_to_mesh

    out: dict[str, float] = {}
    for key, (d, m, design) in _final_drapes(path).items():
        if m is None or design is None:
            out[key] = float("inf")
            continue
        model = ClothModel(msg_to_mesh(m), design.fabric, scene_from_design(design))
        x = d.x.numpy().astype(np.float64)
        free = model.free_dofs
        K = model.stiffness(x, project=False)[free][:, free]
        try:
            lmin = float(spla.eigsh(K, k=1, sigma=-1e-6, which="LM", return_eigenvectors=False)[0])
        except Exception as e:  # noqa: BLE001 - no bound rather than no check
            log.warning("%s: no lambda_min (%s); the cap decides", key, e)
            lmin = 0.0
        out[key] = model.residual_denominator(x) / lmin if lmin > 0 else float("inf")
    return out


SEAM_FLOOR_M = 1e-6
"""[m] seam gaps may always differ this much: drapes travel as float32, which
rounds positions near 1 m by up to 6e-8 m, and a gap combines three of them"""


def seam_failures(case: Case, golden: Path | str, actual: Path | str) -> dict[str, list[str]]:
    """Drape topic -> the final drapes whose seams opened or closed more than
    their residuals allow. Per seam spring the gap vector g = x_e - ((1 - w) x_a
    + w x_b) (emitter e, its point on the edge (a, b)); a spring's force k g
    changes between two drapes by at most the force their residuals leave
    unbalanced, so |g_actual - g_golden| <= SEAM_FLOOR_M + safety (r_golden +
    r_actual) ||F_g|| / k_seam (k_seam and ||F_g|| from the golden's design).
    The position rule cannot see this: seams are stiff (k_seam = 5000 mu), so
    a tenth of the seam stiffness moves a drape by microns, far inside the
    soft modes' compliance, while every seam gap grows tenfold."""
    import numpy as np

    from couture.cloth.model import ClothModel
    from couture.solvers.service import scene_from_design
    from schemas.convert import msg_to_mesh

    def gaps(d: Any, m: Any) -> np.ndarray:
        x = d.x.numpy().astype(np.float64)
        e, ab, w = m.seam_emitters.numpy(), m.seam_edges.numpy(), m.seam_weights.numpy()
        return x[e] - (1.0 - w)[:, None] * x[ab[:, 0]] - w[:, None] * x[ab[:, 1]]

    g_all, a_all = _final_drapes(golden), _final_drapes(actual)
    out: dict[str, list[str]] = {}
    for key, (gd, gm, design) in g_all.items():
        if key not in a_all or gm is None or design is None:
            continue  # missing drapes and meshes are the comparison's to report
        ad, am, _ = a_all[key]
        if am is None or len(gm.seam_emitters.numpy()) == 0:
            continue
        if not (
            np.array_equal(gm.seam_emitters.numpy(), am.seam_emitters.numpy())
            and np.array_equal(gm.seam_edges.numpy(), am.seam_edges.numpy())
        ):
            continue  # another seam topology: the mesh comparison says so
        scene = dataclasses.replace(scene_from_design(design), body=None, friction=False)
        model = ClothModel(msg_to_mesh(gm), design.fabric, scene)
        x = gd.x.numpy().astype(np.float64)
        bound = SEAM_FLOOR_M + case.safety * (gd.residual + ad.residual) * model.residual_denominator(x) / float(
            model.seam_stiffness
        )
        dev = np.linalg.norm(gaps(ad, am) - gaps(gd, gm), axis=1)
        worst = int(np.argmax(dev))
        if not dev[worst] <= bound:
            topic = key.split(" ", 1)[0]
            vertex = int(gm.seam_emitters.numpy()[worst])
            out.setdefault(topic, []).append(
                f"{key}: {topic} generation {gd.generation}: seam gap at worst vertex {vertex} changed "
                f"{dev[worst] * 1e6:.3f} um > bound {bound * 1e6:.3f} um "
                f"({int(np.sum(dev > bound))} of {len(dev)} seam springs off; golden gap "
                f"{np.linalg.norm(gaps(gd, gm)[worst]) * 1e6:.3f} um)"
            )
    return out


POLISH_TOL = 1e-9
"""relative residual the compared drapes are carried to (:func:`polisher`)"""


def polisher(recordings: dict[str, Path | str]):
    """``polish(key, drape, side)`` for :class:`PhysicsRule`: the final drape ``key``
    of recording ``recordings[side]`` carried by Newton from its recorded state to
    relative residual ``POLISH_TOL`` on the model of that recording's own mesh and
    design (friction anchored where the drape rests), as (x, residual, model), or
    None where the recording lacks them or Newton does not get there.

    Why: a drape converged to the node's tolerance (1e-4) lies up to r ||F||/lambda_min
    from its equilibrium, and along a soft mode beyond that first-order estimate
    (measured: a frictionless skirt's hem vertex 1.54 mm off at r = 1.8e-5, 3.6x
    the estimate), so recorded drapes can only be compared loosely; carried to
    1e-9 the same physics agrees to micrometres and a changed physics stands out."""
    import numpy as np

    from couture.cloth.model import ClothModel
    from couture.solvers import get_solver
    from couture.solvers.service import scene_from_design
    from schemas.convert import msg_to_mesh

    tables = {side: _final_drapes(p) for side, p in recordings.items()}
    done: dict[tuple[str, str], Any] = {}

    def polish(key: str, drape, side: str):
        if (key, side) in done:
            return done[(key, side)]
        entry = tables.get(side, {}).get(key)
        out = None
        _, m, design = entry if entry is not None else (None, None, None)
        if m is None or design is None:
            # the comparison then falls back to the recorded residuals: say why
            what = "the drape" if entry is None else "its mesh" if m is None else "its mesh's pattern message"
            log.warning("%s (%s): not polished: %s is not in the recording", key, side, what)
        else:
            model = ClothModel(msg_to_mesh(m), design.fabric, scene_from_design(design))
            x = drape.x.numpy().astype(np.float64)
            if x.shape != model.mesh.x0.shape:
                log.warning("%s (%s): not polished: x %s on a mesh of %s", key, side, x.shape, model.mesh.x0.shape)
            else:
                r = get_solver("newton").solve(
                    model, x, tol=POLISH_TOL, max_iters=200, max_seconds=600.0, friction_after=math.inf
                )
                if r.converged:
                    out = (r.x, float(r.residual), model)
                else:
                    log.warning("%s (%s): not polished (%s)", key, side, r.diagnosis)
        done[(key, side)] = out
        return out

    return polish


def rule(
    case: Case,
    golden: Path | str | None = None,
    labels: set[str] | None = None,
    actual: Path | str | None = None,
) -> PhysicsRule:
    """The physics rule for a case (module doc), compliances from ``golden``; with
    ``actual``, the drapes of both are compared polished (:func:`polisher`)."""
    table = compliances(golden or case.mcap)
    polish = polisher({"golden": golden or case.mcap, "actual": actual}) if actual is not None else None
    return PhysicsRule(
        tol=solver_tolerances(),
        cap_m=dict(case.cap_m),
        floor_m=case.floor_m,
        safety=case.safety,
        compliance=lambda key, g: float("inf") if g.level in case.cap_only else table.get(key, float("inf")),
        polish=polish,
        path_fields={"mesh/coarse": {"x0"}, "mesh/fine": {"x0"}},
        labels=labels or set(),
    )


TOPICS = ["mesh/coarse", "mesh/fine", "drape/coarse", "drape/fine"]


def compare_case(case: Case, golden: Path | str, actual: Path | str, labels: set[str] | None = None) -> CompareReport:
    """Compare two recordings of the case under its physics rule. A replay
    re-sends the golden's patterns, so their design ids come back; two makes
    publish fresh ones (``labels={"design_id"}`` leaves them out)."""
    if case.tugs:
        # the sensitivity node names each tugged design afresh (a uuid); and the
        # tugged length comes from the equilibrium, so the rest mesh moves by
        # round-off (X within atol), and a fine vertex on a coarse edge may be
        # located in either neighbour (the prolongation map's triangle and
        # barycentrics: integers that round-off decides, measured under SuperLU)
        labels = (labels or set()) | {"design_id", "fine_parent_tri", "fine_bary"}
    rep = compare(
        str(golden), str(actual), rtol=case.rtol, atol=case.atol, topics=TOPICS, rule=rule(case, golden, labels, actual)
    )
    rep.rule += f"; seam gaps within {SEAM_FLOOR_M * 1e6:g} um + {case.safety:g} (r_golden + r_actual) ||F_g||/k_seam"
    for topic, fails in seam_failures(case, golden, actual).items():
        tr = rep.topics.get(topic)
        if tr is not None:
            tr.failures.extend(fails)
            rep.first_deviation = rep.first_deviation or fails[0]
    if case.gestures:
        rep.rule += (
            f"; each gesture predicted, its release prediction within {case.floor_m * 1e3:g} mm + "
            f"{case.prediction_safety:g} x the bound of the fine drape it was made on (at most "
            f"{case.cap_m.get('fine', math.inf) * 1e3:g} mm), a tug's design parameters within {case.tug_rtol:g} "
            "(relative) of the golden's"
        )
        fine_bounds = (
            {r.generation: r.bound_m for r in rep.topics["drape/fine"].drapes} if "drape/fine" in rep.topics else {}
        )
        tr = rep.topics.setdefault("drape/predicted", TopicReport("drape/predicted"))
        tr.failures.extend(prediction_failures(case, golden, actual, tr, fine_bounds))
        if tr.failures:
            rep.first_deviation = rep.first_deviation or tr.failures[0]
    return rep


def _gestures(path: Path | str) -> tuple[dict[str, list[Any]], list[Any]]:
    """edit_id -> its predictions, in arrival order; the sensitivity node's tug designs, in order."""
    from couture.recording.mcapio import read_session
    from schemas.messages import DrapeMsg, PatternMsg, decode

    preds: dict[str, list[Any]] = {}
    tugs: list[Any] = []
    for rec in read_session(str(path), ["drape/predicted", "pattern"]):
        if rec.topic == "pattern":
            p = decode(rec.data, PatternMsg)
            if p.source == "sensitivity":
                tugs.append(p)
        else:
            d = decode(rec.data, DrapeMsg)
            preds.setdefault(d.edit_id, []).append(d)
    return preds, tugs


def prediction_failures(
    case: Case, golden: Path | str, actual: Path | str, tr: TopicReport, fine_bounds: dict[int, float]
) -> list[str]:
    """Predicted drapes, compared where they do not depend on timing. How many
    predictions a gesture gets, and at which pointer positions, depends on how
    fast the node keeps up with the pointer (it predicts the newest position
    and drops the rest), so intermediate predictions are counted and
    reported, never matched. The release prediction is made at the recorded
    release position from the equilibrium of the design pressed on (the
    sensitivity node's factorization there and the remesher's Ψ): every
    gesture of the golden must have one in the actual session too, its worst
    vertex within ``floor_m + prediction_safety * b`` of the golden's, at most
    the fine cap, where b is the bound the physics rule gave that
    generation's fine drape: the prediction is that equilibrium moved by its
    first-order response, so it may move with the equilibrium (and its
    response with it: hence the safety factor), no more. A 3D tug's design
    (the sensitivity node's pattern) must have the golden's parameter values
    within ``case.tug_rtol``."""
    import numpy as np

    g_preds, g_tugs = _gestures(golden)
    a_preds, a_tugs = _gestures(actual)
    fails: list[str] = []
    for edit_id, gl in g_preds.items():
        g_rel = next((d for d in gl if d.diagnosis == "release"), None)
        if g_rel is None:
            continue
        al = a_preds.get(edit_id, [])
        a_rel = next((d for d in al if d.diagnosis == "release"), None)
        if a_rel is None:
            tr.missing.append(f"drape/predicted edit_id={edit_id} (release)")
            fails.append(f"drape/predicted edit {edit_id}: no release prediction ({len(al)} predictions)")
            continue
        tr.matched += 1
        gx, ax = g_rel.x.numpy().astype(np.float64), a_rel.x.numpy().astype(np.float64)
        if gx.shape != ax.shape:
            fails.append(f"drape/predicted edit {edit_id}: x shape {ax.shape} != golden {gx.shape}")
            continue
        dist = np.linalg.norm(ax - gx, axis=1)
        i = int(np.argmax(dist))
        if dist[i] > tr.worst_abs:
            tr.worst_abs, tr.worst_where = float(dist[i]), f"edit {edit_id} vertex {i}"
        print(
            f"[golden] {case.name}: edit {edit_id}: {len(gl)}/{len(al)} predictions (golden/actual, reported), "
            f"release prediction worst vertex {i} {dist[i] * 1e3:.3f} mm "
            f"(its fine drape's bound {fine_bounds.get(g_rel.generation, math.inf) * 1e3:.3f} mm)",
            file=sys.stderr,
        )
        bound = min(
            case.cap_m.get("fine", math.inf),
            case.floor_m + case.prediction_safety * fine_bounds.get(g_rel.generation, math.inf),
        )
        if not dist[i] <= bound:
            fails.append(
                f"drape/predicted edit {edit_id} generation {g_rel.generation}: release prediction's worst vertex "
                f"{i} deviates {dist[i] * 1e3:.3f} mm > bound {bound * 1e3:.3f} mm"
            )
    if len(a_tugs) != len(g_tugs):
        fails.append(f"pattern: {len(a_tugs)} tug designs from the sensitivity node vs golden {len(g_tugs)}")
    for k, (gp, ap) in enumerate(zip(g_tugs, a_tugs, strict=False)):
        for name, gv in gp.design.sloper.params.items():
            av = ap.design.sloper.params.get(name, float("nan"))
            if not abs(av - gv) <= case.tug_rtol * abs(gv):
                fails.append(f"pattern: tug {k}: {name} = {av!r} vs golden {gv!r} (> {case.tug_rtol:g} relative)")
    return fails


def scaled_inputs(
    golden: Path | str,
    out: Path | str,
    fabric_scale: dict[str, float] | None = None,
    scene_scale: dict[str, float] | None = None,
) -> Path:
    """A copy of the golden's replayed inputs with every pattern's fabric
    fields (``{"bend_stiffness": 1.5}``) and scene factors
    (``{"seam_stiffness_scale": 0.1}``) multiplied: a deliberate physics change
    made where a designer would make it, in the design, so that a test can
    show the comparison catches it."""
    from couture.recording.mcapio import SessionWriter, read_session
    from schemas import topics as topic_table
    from schemas.messages import PatternMsg, decode, encode

    w = SessionWriter(str(out))
    try:
        for rec in read_session(str(golden), topic_table.replayed_topics()):
            data = rec.data
            if rec.topic == "pattern":
                msg = decode(data, PatternMsg)
                d = msg.design
                fabric = {k: getattr(d.fabric, k) * f for k, f in (fabric_scale or {}).items()}
                scene = {k: getattr(d.scene, k) * f for k, f in (scene_scale or {}).items()}
                design = msgspec.structs.replace(
                    d,
                    fabric=msgspec.structs.replace(d.fabric, **fabric),
                    scene=msgspec.structs.replace(d.scene, **scene),
                )
                data = encode(msgspec.structs.replace(msg, design=design))
            w.write(rec.key, data, rec.log_time, schema=rec.schema or None)
    finally:
        w.close()
    return Path(out)


def check(
    case: Case,
    actual: Path | None = None,
    fabric_scale: dict[str, float] | None = None,
    scene_scale: dict[str, float] | None = None,
) -> CompareReport:
    """Replay the golden inputs into fresh nodes and compare their outputs
    with the golden ones; ``fabric_scale`` or ``scene_scale`` replays a
    physically different session instead (:func:`scaled_inputs`), which must fail."""
    if not case.mcap.exists():
        raise FileNotFoundError(f"{case.mcap}: no golden recording; make it with `couture golden make {case.name}`")
    with tempfile.TemporaryDirectory(prefix="couture-golden-") as tmp:
        if actual is None:
            actual = Path(tmp) / f"{case.name}.mcap"
        inputs = case.mcap
        if fabric_scale or scene_scale:
            inputs = scaled_inputs(case.mcap, Path(tmp) / "inputs.mcap", fabric_scale, scene_scale)
        steplog = _drive(case, actual, inputs)
        rep = compare_case(case, case.mcap, actual)
        for k, n in enumerate(steplog.predictions_after_kill):
            # DESIGN §2: a killed solver must not freeze the UI (predictions keep flowing)
            print(f"[golden] {case.name}: kill {k}: {n} predictions after the SIGKILL", file=sys.stderr)
            if n == 0:
                tr = rep.topics.setdefault("drape/predicted", TopicReport("drape/predicted"))
                tr.failures.append(f"drape/predicted: no prediction of the gesture after SIGKILL {k} of the solver")
                rep.first_deviation = rep.first_deviation or tr.failures[-1]
        return rep


def _drive(case: Case, record: Path, inputs: Path | None) -> Any:
    """Fresh nodes recording into ``record``; the case's steps driven through
    the bus (couture.recording.steps): made afresh (``inputs`` None, make) or
    the inputs of ``inputs`` replayed in lockstep (check). Returns the
    driver's :class:`couture.recording.steps.StepLog`."""
    from couture.client import Client
    from couture.recording.steps import Driver, GoldenInputs

    golden_inputs = GoldenInputs.read(inputs) if inputs is not None else None
    with supervisor.Supervisor(supervisor.SupervisorConfig(bus=_session(), nodes=_nodes(case, record))) as sup:
        _wait_recorder(sup)
        with Client(bus=sup.child_bus) as client:
            steplog = Driver(case, sup, client, golden_inputs, timeout=case.timeout_s).run(case.all_steps())
            time.sleep(0.5)  # let the recorder take the last messages
    return steplog


def main(argv: list[str] | None = None) -> int:
    import argparse

    p = argparse.ArgumentParser(prog="couture golden", description=__doc__.split("\n\n")[0])
    p.add_argument(
        "action",
        choices=["make", "check", "list"],
        help="make: re-record (prints what changed against the old golden); "
        "check: replay into fresh nodes and compare; list: the cases",
    )
    p.add_argument("cases", nargs="*", help="case names (recordings/<case>.json); default: all")
    p.add_argument("--json", default=None, help="check: write the reports here (one JSON object per case name)")
    a = p.parse_args(argv)
    names = a.cases or sorted(f.stem for f in RECORDINGS.glob("*.json"))
    if a.action == "list":
        for n in names:
            c = load_case(n)
            print(
                f"{n}: {len(c.all_steps())} steps, solvers {c.solvers}, golden {'present' if c.mcap.exists() else 'missing'}"
            )
        return 0
    failed = 0
    reports = {}
    for n in names:
        case = load_case(n)
        if a.action == "make":
            with tempfile.TemporaryDirectory(prefix="couture-golden-") as tmp:
                old = Path(tmp) / "old.mcap"
                if case.mcap.exists():
                    old.write_bytes(case.mcap.read_bytes())
                print(f"[golden] wrote {make(case)}", file=sys.stderr)
                print(changes(case, old, case.mcap) if old.exists() else f"[golden] {n}: new golden (no old one)")
        else:
            rep = check(case)
            print(rep.text())
            reports[n] = rep.to_json()
            failed += not rep.ok
    if a.json:
        from couture.jsonout import dumps  # standard JSON: non-finite numbers as null

        Path(a.json).write_text(dumps(reports, indent=2, default=str))
    return 1 if failed else 0


if __name__ == "__main__":
    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    sys.exit(main())

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

``make`` starts the nodes with a recorder, publishes the designs one at a
time, waiting for each one's final drape/fine, and keeps the recording as
``recordings/<case>.mcap``. ``check`` starts the same nodes with a recorder,
replays the golden file's inputs in lockstep (``couture replay --lockstep``)
and compares the outputs with the golden ones, physics not paths
(:func:`rule`, STYLE.md): each final drape has the golden's convergence
status, a converged one a residual within the solver node's tolerance, and
every vertex within ``floor_m + safety * (r_golden + r_actual) * ||F_g|| /
lambda_min`` of the golden, at most the level's ``cap_m`` (lambda_min: the
smallest eigenvalue of the exact free Hessian at the golden drape,
:func:`compliances`), and every seam spring's gap within ``SEAM_FLOOR_M +
safety * (r_golden + r_actual) * ||F_g|| / k_seam`` of the golden's
(:func:`seam_failures`: stiff seams hide from the position bound). Iterations
and wall times are reported, never compared. Meshes (what the remesher drafts) are
compared field by field within ``rtol``/``atol``, integers exactly; their
``x0`` carries the previous drape over, so only the cap holds there.

``make`` records into a temporary file, replaces the golden, and prints what
changed against the old one (:func:`changes`: per topic the largest
deviation, per drape the iterations old -> new). ``python -m
couture.recording.golden`` is the same command as ``couture golden``.
"""

from __future__ import annotations

import dataclasses
import json
import logging
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
from couture.recording.compare import CompareReport, PhysicsRule, compare
from couture.recording.replay import ReplayConfig
from couture.recording.replay import main as replay
from schemas.design import Design

log = logging.getLogger("couture.golden")

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"
EXAMPLES = Path(__file__).resolve().parents[1] / "pattern" / "examples"


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

    @property
    def mcap(self) -> Path:
        return self.path.with_suffix(".mcap")


def load_case(name_or_path: str) -> Case:
    p = Path(name_or_path)
    if not p.suffix:
        p = RECORDINGS / f"{name_or_path}.json"
    spec = json.loads(p.read_text())
    keys = {"solvers", "designs", "rtol", "atol", "floor_m", "safety", "cap_m", "timeout_s"}
    unknown = set(spec) - keys - {"doc"}
    if unknown:
        raise ValueError(f"{p}: unknown keys {sorted(unknown)}")
    return Case(name=p.stem, path=p, **{k: spec[k] for k in keys if k in spec})


def _merge(base: dict, patch: dict) -> dict:
    out = dict(base)
    for k, v in patch.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def case_designs(case: Case) -> list[Design]:
    from couture.pattern.io import load_design

    designs: list[Design] = []
    current: dict | None = None
    for entry in case.designs:
        if isinstance(entry, str):
            f = case.path.parent / entry
            d = load_design(f if f.exists() else EXAMPLES / entry)
            current = msgspec.to_builtins(d)
        else:
            if current is None:
                current = msgspec.to_builtins(Design())
            current = _merge(current, entry)
        designs.append(msgspec.convert(current, Design))
    return designs


def _nodes(case: Case, record: Path) -> list[supervisor.NodeSpec]:
    nodes = [
        n
        for n in supervisor.default_nodes(solvers=case.solvers, ui=False, record=str(record))
        if n.name != "sensitivity"
    ]  # inputs here are whole patterns, no drags
    return nodes


def _session() -> BusConfig:
    from couture.bus.ports import free_port

    return BusConfig(session=f"golden{uuid.uuid4().hex[:8]}", listen=[f"tcp/127.0.0.1:{free_port()}"])


def _wait_recorder(sup: supervisor.Supervisor, timeout: float = 30.0) -> None:
    """Wait until the nodes are live *and* the recorder's subscription reaches
    us: liveliness comes up before the recorder subscribes, and a publisher's
    matching status on ``pattern`` is already satisfied by the remesher. A
    probe key that only the recorder's ``couture/<session>/**`` matches tells."""
    from couture.bus import open_session
    from couture.bus.session import has_subscribers
    from couture.client import Client

    with Client(bus=sup.child_bus) as c:
        c.wait_nodes(["recorder", "remesher", *[f"solver-{s}" for s in sup_solvers(sup)]], timeout)
    with open_session(sup.child_bus, name="golden-probe") as bus:
        probe = bus.zenoh.declare_publisher(bus.key(f"probe/{uuid.uuid4().hex[:8]}"))
        deadline = time.monotonic() + timeout
        while not has_subscribers(probe):
            if time.monotonic() > deadline:
                raise TimeoutError("the recorder never subscribed")
            time.sleep(0.02)
        probe.undeclare()


def sup_solvers(sup: supervisor.Supervisor) -> list[str]:
    return [n[len("solver-") :] for n in sup.children if n.startswith("solver-")]


def make(case: Case) -> Path:
    """Record the case's session into ``case.mcap``: into a temporary file
    first, which replaces the golden only once the session is complete (a
    make that fails keeps the old golden)."""
    from couture.client import Client
    from couture.recording.parts import expand, numbered

    designs = case_designs(case)
    out = case.mcap
    new = out.with_name(f".{out.stem}.new.mcap")
    # a failed make's leftovers are this command's own scratch files, not recordings
    for stale in [new, *numbered(new).values()]:
        stale.unlink(missing_ok=True)
    with supervisor.Supervisor(supervisor.SupervisorConfig(bus=_session(), nodes=_nodes(case, new))) as sup:
        _wait_recorder(sup)
        with Client(bus=sup.child_bus) as client:
            for i, d in enumerate(designs):
                gen = client.publish_pattern(d, name=f"{case.name}-{i}")
                drape = client.wait_drape("fine", generation=gen, timeout=case.timeout_s, final=True)
                print(
                    f"[golden] {case.name}: design {i} (generation {gen}) residual {drape.residual:.2e} "
                    f"{'converged' if drape.converged else drape.diagnosis}",
                    file=sys.stderr,
                )
            time.sleep(0.5)  # let the recorder take the last messages
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
            if not mm.unchanged:
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


def rule(case: Case, golden: Path | str | None = None, labels: set[str] | None = None) -> PhysicsRule:
    """The physics rule for a case (module doc), compliances from ``golden``."""
    table = compliances(golden or case.mcap)
    return PhysicsRule(
        tol=solver_tolerances(),
        cap_m=dict(case.cap_m),
        floor_m=case.floor_m,
        safety=case.safety,
        compliance=lambda key, _g: table.get(key, float("inf")),
        path_fields={"mesh/coarse": {"x0"}, "mesh/fine": {"x0"}},
        labels=labels or set(),
    )


TOPICS = ["mesh/coarse", "mesh/fine", "drape/coarse", "drape/fine"]


def compare_case(case: Case, golden: Path | str, actual: Path | str, labels: set[str] | None = None) -> CompareReport:
    """Compare two recordings of the case under its physics rule. A replay
    re-sends the golden's patterns, so their design ids come back; two makes
    publish fresh ones (``labels={"design_id"}`` leaves them out)."""
    rep = compare(
        str(golden), str(actual), rtol=case.rtol, atol=case.atol, topics=TOPICS, rule=rule(case, golden, labels)
    )
    rep.rule += f"; seam gaps within {SEAM_FLOOR_M * 1e6:g} um + {case.safety:g} (r_golden + r_actual) ||F_g||/k_seam"
    for topic, fails in seam_failures(case, golden, actual).items():
        tr = rep.topics.get(topic)
        if tr is not None:
            tr.failures.extend(fails)
            rep.first_deviation = rep.first_deviation or fails[0]
    return rep


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
        _run(case, inputs, actual)
        return compare_case(case, case.mcap, actual)


def _run(case: Case, inputs: Path, record: Path) -> None:
    """Fresh nodes recording into ``record``; the inputs replayed in lockstep."""
    with supervisor.Supervisor(supervisor.SupervisorConfig(bus=_session(), nodes=_nodes(case, record))) as sup:
        _wait_recorder(sup)
        replay(
            ReplayConfig(
                path=str(inputs), bus=sup.child_bus, rate=0.0, lockstep=True, lockstep_timeout_s=case.timeout_s
            )
        )
        time.sleep(0.5)


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
                f"{n}: {len(c.designs)} designs, solvers {c.solvers}, golden {'present' if c.mcap.exists() else 'missing'}"
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

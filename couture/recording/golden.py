"""Golden recordings: a design session as a regression test (DESIGN §3).

A *case* is ``recordings/<case>.json``::

    {"solvers": ["newton"],              # solver nodes to run
     "designs": ["examples/small_skirt.json", {"sloper": {"params": {"length": 0.7}}}, ...],
     "rtol": 1e-3, "atol": 2e-3,        # float tolerances for compare (positions in m)
     "timeout_s": 120}

Each entry of ``designs`` is a pattern file (relative to the case file or to
``couture/pattern/examples``) or a patch merged into the previous design.

``make`` starts the nodes with a recorder, publishes the designs one at a
time, waiting for each one's final drape/fine, and keeps the recording as
``recordings/<case>.mcap``. ``check`` starts the same nodes with a recorder,
replays the golden file's inputs in lockstep (``couture replay --lockstep``)
and compares the outputs with the golden ones: floats within the case's
tolerances, integers exactly, the worst deviation per topic reported.
"""

from __future__ import annotations

import json
import logging
import sys
import tempfile
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import msgspec

from couture import supervisor
from couture.bus import BusConfig
from couture.recording.compare import CompareReport, compare
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
    timeout_s: float = 120.0

    @property
    def mcap(self) -> Path:
        return self.path.with_suffix(".mcap")


def load_case(name_or_path: str) -> Case:
    p = Path(name_or_path)
    if not p.suffix:
        p = RECORDINGS / f"{name_or_path}.json"
    spec = json.loads(p.read_text())
    unknown = set(spec) - {"solvers", "designs", "rtol", "atol", "timeout_s", "doc"}
    if unknown:
        raise ValueError(f"{p}: unknown keys {sorted(unknown)}")
    return Case(name=p.stem, path=p, solvers=spec.get("solvers", ["newton"]), designs=spec["designs"],
                rtol=spec.get("rtol", 1e-3), atol=spec.get("atol", 2e-3), timeout_s=spec.get("timeout_s", 120.0))


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
    nodes = [n for n in supervisor.default_nodes(solvers=case.solvers, ui=False, record=str(record))
             if n.name != "sensitivity"]  # inputs here are whole patterns, no drags
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
    return [n[len("solver-"):] for n in sup.children if n.startswith("solver-")]


def make(case: Case) -> Path:
    """Record the case's session into ``case.mcap`` (overwrites)."""
    from couture.client import Client

    designs = case_designs(case)
    out = case.mcap
    with supervisor.Supervisor(supervisor.SupervisorConfig(bus=_session(), nodes=_nodes(case, out))) as sup:
        _wait_recorder(sup)
        with Client(bus=sup.child_bus) as client:
            for i, d in enumerate(designs):
                gen = client.publish_pattern(d, name=f"{case.name}-{i}")
                drape = client.wait_drape("fine", generation=gen, timeout=case.timeout_s, final=True)
                print(f"[golden] {case.name}: design {i} (generation {gen}) residual {drape.residual:.2e} "
                      f"{'converged' if drape.converged else drape.diagnosis}", file=sys.stderr)
            time.sleep(0.5)  # let the recorder take the last messages
    return out


def check(case: Case, actual: Path | None = None) -> CompareReport:
    """Replay the golden inputs into fresh nodes and compare their outputs."""
    if not case.mcap.exists():
        raise FileNotFoundError(f"{case.mcap}: no golden recording; make it with `couture golden make {case.name}`")
    tmp = None
    if actual is None:
        tmp = tempfile.TemporaryDirectory(prefix="couture-golden-")
        actual = Path(tmp.name) / f"{case.name}.mcap"
    try:
        with supervisor.Supervisor(supervisor.SupervisorConfig(bus=_session(), nodes=_nodes(case, actual))) as sup:
            _wait_recorder(sup)
            replay(ReplayConfig(path=str(case.mcap), bus=sup.child_bus, rate=0.0, lockstep=True,
                                lockstep_timeout_s=case.timeout_s))
            time.sleep(0.5)
        return compare(str(case.mcap), str(actual), rtol=case.rtol, atol=case.atol,
                       topics=["mesh/coarse", "mesh/fine", "drape/coarse", "drape/fine"])
    finally:
        if tmp is not None:
            tmp.cleanup()


def main(argv: list[str] | None = None) -> int:
    import argparse

    p = argparse.ArgumentParser(prog="couture golden", description=__doc__.split("\n\n")[0])
    p.add_argument("action", choices=["make", "check", "list"])
    p.add_argument("cases", nargs="*", help="case names (recordings/<case>.json); default: all")
    a = p.parse_args(argv)
    names = a.cases or sorted(f.stem for f in RECORDINGS.glob("*.json"))
    if a.action == "list":
        for n in names:
            c = load_case(n)
            print(f"{n}: {len(c.designs)} designs, solvers {c.solvers}, golden {'present' if c.mcap.exists() else 'missing'}")
        return 0
    failed = 0
    for n in names:
        case = load_case(n)
        if a.action == "make":
            print(f"[golden] wrote {make(case)}", file=sys.stderr)
        else:
            rep = check(case)
            print(rep.text())
            failed += not rep.ok
    return 1 if failed else 0

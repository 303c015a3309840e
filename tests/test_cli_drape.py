"""`couture drape` end to end, real nodes over Zenoh on a small skirt: the
exit status says whether the fine drape converged (0), stopped short (3, the
drape written and the diagnosis printed) or the design was bad (4, at once,
naming the field: the remesher's and the solver's rejections on the bus);
the default output carries no log chatter. The progress lines and the
client's wait are also checked without a bus."""

from __future__ import annotations

import contextlib
import io
import json
import os
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

from couture.cli import DrapeExit, _DrapeProgress
from couture.client import Client, PatternRejected
from schemas import DrapeMsg, RejectedMsg

pytestmark = pytest.mark.timeout(120)

SMALL = {"sloper": {"kind": "skirt", "params": {}}, "resolution": {"coarse_vertices": 300, "fine_vertices": 900}}


def _drape(
    tmp_path: Path, design: dict, *extra: str, timeout: float = 100.0, session: str = ""
) -> tuple[subprocess.CompletedProcess, float]:
    tmp_path.mkdir(parents=True, exist_ok=True)
    pattern = tmp_path / "p.json"
    pattern.write_text(json.dumps(design))
    # a session of its own, so parallel runs never see each other's drapes
    cmd = [
        sys.executable,
        "-m",
        "couture.cli",
        "drape",
        str(pattern),
        "--out",
        str(tmp_path / "out"),
        "--session",
        session or f"t{uuid.uuid4().hex[:8]}",
        *extra,
    ]
    t0 = time.monotonic()
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=dict(os.environ))
    return r, time.monotonic() - t0


def test_converged_drape_exits_0_and_keeps_logs_out_of_the_default_output(tmp_path):
    r, _ = _drape(tmp_path, SMALL)
    assert r.returncode == DrapeExit.CONVERGED, r.stderr[-3000:]
    meta = json.loads((tmp_path / "out" / "drape.json").read_text())
    assert meta["converged"] is True and meta["residual"] <= meta["tolerance"]
    # what the solver built for the scene (the example skirt: on the mannequin, with friction)
    assert meta["terms"] == ["membrane", "bending", "gravity", "seams", "contact", "friction"], meta["terms"]
    assert 0.8 * 900 <= meta["vertices"] <= 1.5 * 900  # the fine level (target 900)
    assert (tmp_path / "out" / "drape.obj").stat().st_size > 0
    out = r.stdout + r.stderr
    assert "[drape] fine: converged" in out and "terms membrane, bending, gravity, seams, contact, friction" in out
    # node lifecycle and library (ezdxf) logs go to nodes.log, not the terminal
    for chatter in (" INFO ", "ezdxf", "node remesher up", "started remesher"):
        assert chatter not in out, f"{chatter!r} in the default output:\n{out[-3000:]}"
    assert "node remesher up" in (tmp_path / "out" / "nodes.log").read_text()


def test_capped_solve_exits_3_writes_the_drape_and_prints_the_diagnosis(tmp_path):
    # a cap far below one level's solve: the solver stops short and says so
    r, _ = _drape(tmp_path, SMALL, "--solver-max-seconds", "0.05")
    assert r.returncode == DrapeExit.NOT_CONVERGED, r.stderr[-3000:]
    meta = json.loads((tmp_path / "out" / "drape.json").read_text())
    assert meta["converged"] is False and meta["diagnosis"]
    assert (tmp_path / "out" / "drape.obj").exists()
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("couture drape: not converged: fine residual")
    assert "solver-newton" in last and meta["diagnosis"] in last


BAD_DESIGNS = [
    # name, design, the element the rejection names, a piece of its reason
    ("unknown_sloper", {**SMALL, "sloper": {"kind": "cape", "params": {}}}, "sloper", "unknown sloper kind 'cape'"),
    ("negative_length", {**SMALL, "sloper": {"kind": "skirt", "params": {"length": -1.0}}}, "param:length", "-1 m"),
    ("no_density", {**SMALL, "fabric": {"area_density": 0}}, "fabric.area_density", "[0.001, 10] kg/m^2"),
    ("no_stretch", {**SMALL, "fabric": {"stretch_stiffness": 0}}, "fabric.stretch_stiffness", "[0.1, 1e+06] N/m"),
    ("huge_stretch", {**SMALL, "fabric": {"stretch_stiffness": 1e308}}, "fabric.stretch_stiffness", "1e+308 N/m"),
]


def test_rejected_designs_answer_at_once_and_the_nodes_keep_draping(tmp_path):
    """One session of real nodes (remesher, Newton solver): a bad design
    exits 4 naming its field (exit 5 would mean the wait ran to --timeout),
    every bad design is rejected naming its field (the others through a
    client: the command adds nothing per design, and each run of it is a
    process of its own, 7 s on a loaded machine) and a good one then drapes; a mesh whose design has a bad fabric, sent to
    the solver past the remesher, is rejected by the solver on the bus, a
    solve request with one is answered with the error, a lockstep replay of a
    bad design goes on at its rejection, and the next good design still
    drapes; no node ever restarts."""
    from couture import supervisor
    from couture.bus import BusConfig
    from couture.recording.mcapio import SessionWriter
    from couture.recording.replay import ReplayConfig
    from couture.recording.replay import main as replay
    from couture.remesh.service import RemeshService
    from schemas import MeshMsg, PatternMsg, encode
    from schemas.convert import mesh_to_msg
    from schemas.design import Design, Fabric, Resolution

    session = f"t{uuid.uuid4().hex[:8]}"
    nodes = [n for n in supervisor.default_nodes(solvers=["newton"], ui=False) if n.name != "sensitivity"]
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=session), nodes=nodes, child_log=str(tmp_path / "nodes.log")
    )
    with supervisor.Supervisor(cfg) as sup:
        connect = ("--connect", sup.endpoint, "--timeout", "90")
        with Client(bus=BusConfig(session=session, connect=[sup.endpoint], listen=["tcp/127.0.0.1:0"])) as c:
            c.wait_nodes(["remesher", "solver-newton"], timeout=60)
            pids = sup.pids()
            for k, (name, design, element, piece) in enumerate(BAD_DESIGNS):
                if k == 0:
                    r, seconds = _drape(tmp_path / name, design, *connect, session=session)
                    print(f"{name}: exit {r.returncode} after {seconds:.1f} s")
                    assert r.returncode == DrapeExit.BAD_DESIGN, r.stderr[-3000:]
                    said = r.stderr.strip().splitlines()[-1]
                    assert said.startswith("couture drape: bad design: remesher rejected pattern generation "), said
                    assert not (tmp_path / name / "out" / "drape.obj").exists()
                else:
                    # the command prints the rejection the client raises (checked above, once):
                    # the others through this client, with no process of their own to start
                    pattern = tmp_path / f"{name}.json"
                    pattern.write_text(json.dumps(design))
                    gen = c.publish_pattern(pattern)
                    with pytest.raises(PatternRejected) as e:
                        c.follow_drape(gen, timeout=90)
                    said = str(e.value)
                    assert said.startswith("remesher rejected pattern generation "), said
                assert f": {element}: " in said and piece in said, said
            rejected = [(m.node, m.element) for m in c.rejections()]
            assert rejected == [("remesher", e) for _, _, e, _ in BAD_DESIGNS], rejected
            r, _ = _drape(tmp_path / "good", SMALL, *connect, session=session)
            assert r.returncode == DrapeExit.CONVERGED, r.stderr[-3000:]

            # past the remesher: a mesh naming a design with no stretch stiffness reaches the solver
            res = Resolution(coarse_vertices=300, fine_vertices=900)
            coarse = RemeshService().set_design(Design(resolution=res), 1)[0].mesh
            bad = Design(resolution=res, fabric=Fabric(stretch_stiffness=0.0))
            c.bus.publisher("pattern", PatternMsg).put(
                PatternMsg(design=bad, generation=50, design_id="past-the-remesher", source="test")
            )
            c.bus.publisher("mesh/coarse", MeshMsg).put(
                mesh_to_msg(coarse, generation=50, mesh_generation=10_000, design_id="past-the-remesher")
            )
            deadline = time.monotonic() + 30
            while not (by_solver := [m for m in c.rejections() if m.node == "solver-newton"]):
                assert time.monotonic() < deadline, f"the solver never rejected the mesh: {c.rejections()}"
                time.sleep(0.05)
            assert by_solver[0].design_id == "past-the-remesher" and by_solver[0].element == "fabric.stretch_stiffness"
            answer = c.solve(coarse, solver="solver-newton", design=bad, max_seconds=5.0)
            assert answer.x is None and "fabric.stretch_stiffness" in answer.error, answer.error

            # replay --lockstep takes the rejection as the pattern's answer (not its drape/fine timeout)
            recording = tmp_path / "bad.mcap"
            with contextlib.closing(SessionWriter(str(recording))) as w:
                bad_pattern = PatternMsg(design=bad, generation=60, design_id="recorded-bad", source="ui", seq=1)
                w.write("couture/rec/pattern", encode(bad_pattern), 1)
            cfg = ReplayConfig(path=str(recording), bus=c.cfg, rate=0.0, lockstep=True, lockstep_timeout_s=60.0)
            assert replay(cfg) == 1
            assert any(m.design_id == "recorded-bad" for m in c.rejections())

            gen = c.publish_pattern(Design(resolution=res, fabric=Fabric(stretch_stiffness=50.0)))
            drape = c.wait_drape("fine", generation=gen, timeout=90, final=True)
            assert drape.solver == "solver-newton" and drape.x.shape[0] > 0
            assert sup.pids() == pids, "a node restarted"


def _drape_msg(
    level: str,
    residual: float,
    *,
    generation: int = 1,
    final: bool = False,
    converged: bool = False,
    diagnosis: str = "",
) -> DrapeMsg:
    return DrapeMsg(
        level=level,
        x=np.zeros((3, 3)),
        residual=residual,
        iterations=7,
        solver="solver-newton",
        method="newton",
        generation=generation,
        final=final,
        converged=converged,
        diagnosis=diagnosis,
    )


def test_progress_prints_one_line_per_level_result():
    out = io.StringIO()
    progress = _DrapeProgress({"coarse": 1e-3, "fine": 1e-4}, stream=out)
    for msg in (
        _drape_msg("coarse", 10.0),
        _drape_msg("coarse", 0.1),
        _drape_msg("coarse", 5e-4, final=True, converged=True),
        _drape_msg("coarse", 4e-4),
        _drape_msg("fine", 0.2),
        _drape_msg("fine", 3e-2, final=True, diagnosis="max_seconds 1 reached"),
    ):
        progress(msg)
    progress.close()
    lines = out.getvalue().splitlines()
    assert lines == [
        "[drape] coarse: converged, residual 5.00e-04 (tolerance 1e-03) after 7 iterations in 0.0 s "
        "(solver-newton, newton)",
        "[drape] fine: NOT converged, residual 3.00e-02 (tolerance 1e-04) after 7 iterations in 0.0 s "
        "(solver-newton, newton): max_seconds 1 reached",
    ]


def test_follow_drape_passes_its_generation_on_and_raises_on_the_remeshers_rejection():
    """Bus-free: messages fed to the client's callbacks as the bus would."""
    client = Client(name="t")
    seen: list[tuple[int, str, bool]] = []
    client._on_drape(_drape_msg("fine", 1.0, generation=1, final=True))  # an older design's drape
    feeder = threading.Timer(
        0.2,
        lambda: [
            client._on_drape(m)
            for m in (
                _drape_msg("coarse", 0.5, generation=2),
                _drape_msg("coarse", 1e-3, generation=2, final=True),
                _drape_msg("fine", 1e-5, generation=2, final=True, converged=True),
            )
        ],
    )
    feeder.start()
    d = client.follow_drape(2, timeout=10, on_drape=lambda m: seen.append((m.generation, m.level, m.final)))
    assert (d.generation, d.level, d.converged) == (2, "fine", True)
    assert seen == [(2, "coarse", False), (2, "coarse", True), (2, "fine", True)]

    reason = "param:length: value -1 m is outside [0.38, 1] m"
    client._on_rejected(RejectedMsg(node="remesher", generation=2, element="param:length", reason=reason))
    assert client.rejection(3) is None  # another generation's rejection says nothing about 3
    threading.Timer(
        0.2,
        lambda: client._on_rejected(RejectedMsg(node="remesher", generation=3, element="param:length", reason=reason)),
    ).start()
    # answered by the rejection, not by the 10 s timeout (that would raise TimeoutError)
    with pytest.raises(PatternRejected) as e:
        client.follow_drape(3, timeout=10)
    assert e.value.reason == reason and e.value.generation == 3
    assert e.value.element == "param:length" and e.value.node == "remesher"

    # a design this client published is matched by its design_id, not by the number it asked for
    client._own.add("ours", 7)
    client._on_rejected(RejectedMsg(node="remesher", generation=7, design_id="theirs", reason="x: bad"))
    assert client.rejection(7) is None
    client._on_rejected(
        RejectedMsg(node="solver-newton", generation=7, design_id="ours", element="fabric.area_density", reason="y")
    )
    with pytest.raises(PatternRejected) as e:
        client.wait_drape("fine", generation=7, timeout=10)
    assert e.value.node == "solver-newton" and e.value.element == "fabric.area_density"

"""Recording with a real recorder process: record -> replay -> compare, and
crash tolerance (SIGTERM finalizes; SIGKILL loses nothing before the last
flush and `couture recover` restores it)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from couture.bus import BusConfig, free_port, open_session
from couture.mesh import grid_sheet
from couture.recording import SessionWriter, compare, read_session
from schemas import DrapeMsg, EditMsg, MeshMsg, PatternMsg, decode, encode
from schemas.convert import mesh_to_msg
from schemas.design import Design, Sloper

pytestmark = pytest.mark.timeout(90)

CLI = [sys.executable, "-m", "couture.cli"]


def _start_recorder(path: Path, session: str, endpoint: str, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        [*CLI, "record", str(path), "--session", session, "--connect", endpoint, "--quiet", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _wait_recorder(bus, proc: subprocess.Popen) -> None:
    missing = bus.wait_nodes(["recorder"], 20)
    if missing:
        proc.kill()
        raise AssertionError(f"recorder did not come up: {proc.communicate()[1][-2000:]}")


class FakePipeline:
    """Stands in for remesher + solver: answers each pattern with mesh/fine and
    drape/fine, deterministic in the design (``offset`` perturbs the drape)."""

    def __init__(self, bus, offset: float = 0.0) -> None:
        self.offset = offset
        self.mesh_pub = bus.publisher("mesh/fine", MeshMsg)
        self.drape_pub = bus.publisher("drape/fine", DrapeMsg)
        self.done = threading.Event()
        self.edits: list[EditMsg] = []
        bus.subscribe("pattern", self.on_pattern)
        bus.subscribe("edit", self.edits.append)

    def on_pattern(self, msg: PatternMsg) -> None:
        length = msg.design.sloper.params.get("length", 0.5)
        mesh = grid_sheet(0.4, length, 5, 5)
        mesh.generation = msg.generation
        self.mesh_pub.put(mesh_to_msg(mesh, mesh_generation=1))
        x = np.column_stack([mesh.X[:, 0], np.zeros(len(mesh.X)), -mesh.X[:, 1]]) + self.offset
        self.drape_pub.put(
            DrapeMsg(
                level="fine",
                generation=msg.generation,
                mesh_generation=1,
                x=x,
                residual=1e-5,
                iterations=42,
                solver="fake",
                method="kinetic",
                converged=True,
            )
        )
        self.done.set()


def test_record_replay_compare(tmp_path):
    golden, actual, bad = tmp_path / "golden.mcap", tmp_path / "actual.mcap", tmp_path / "bad.mcap"
    endpoint = f"tcp/127.0.0.1:{free_port()}"

    # --- a live session, recorded by a real recorder process
    sa = f"a{uuid.uuid4().hex[:8]}"
    with open_session(BusConfig(session=sa, listen=[endpoint])) as bus:
        pipe = FakePipeline(bus)
        rec = _start_recorder(golden, sa, endpoint)
        _wait_recorder(bus, rec)
        design = Design(sloper=Sloper(kind="skirt", params={"length": 0.6}))
        pat = bus.publisher("pattern", PatternMsg)
        pat.put(PatternMsg(design=design, generation=1, source="test"))
        assert pipe.done.wait(10)
        bus.publisher("edit", EditMsg).put(
            EditMsg(edit_id="e1", phase="press", element="hem", d=np.zeros(2), generation=1)
        )
        time.sleep(0.5)
        rec.send_signal(signal.SIGTERM)
        assert rec.wait(15) == 0, rec.communicate()[1]

    # the file is a finalized MCAP with versioned schemas and msgpack channels
    with open(golden, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics.message_count > 0
        names = {s.name for s in summary.schemas.values()}
        assert {"couture/pattern/v1", "couture/edit/v1", "couture/mesh/v1", "couture/drape/v1"} <= names
        assert all(s.encoding == "jsonschema" and json.loads(s.data) for s in summary.schemas.values())
        assert {c.message_encoding for c in summary.channels.values()} == {"msgpack"}
        topics = {c.topic for c in summary.channels.values()}
        assert f"couture/{sa}/drape/fine" in topics and f"couture/{sa}/status/recorder" in topics
    msgs = list(read_session(str(golden), ["drape/fine"]))
    assert len(msgs) == 1 and msgs[0].publish_time == decode(msgs[0].data).stamp_ns <= msgs[0].log_time

    # --- replay its inputs into a fresh session with the same pipeline; record; compare
    def replay_into(out: Path, offset: float) -> None:
        sb = f"b{uuid.uuid4().hex[:8]}"
        with open_session(BusConfig(session=sb, listen=[endpoint])) as bus:
            pipe = FakePipeline(bus, offset=offset)
            rec = _start_recorder(out, sb, endpoint)
            _wait_recorder(bus, rec)
            r = subprocess.run(
                [
                    *CLI,
                    "replay",
                    str(golden),
                    "--rate",
                    "0",
                    "--session",
                    sb,
                    "--connect",
                    endpoint,
                    "--wait-nodes",
                    "recorder",
                ],
                capture_output=True,
                text=True,
                timeout=30,
            )
            assert r.returncode == 0, r.stderr
            assert pipe.done.wait(10)
            deadline = time.monotonic() + 5
            while not pipe.edits and time.monotonic() < deadline:
                time.sleep(0.02)
            assert [e.edit_id for e in pipe.edits] == ["e1"]
            time.sleep(0.3)
            rec.send_signal(signal.SIGTERM)
            assert rec.wait(15) == 0

    replay_into(actual, 0.0)
    rep = compare(str(golden), str(actual), rtol=1e-6, atol=1e-9)
    assert rep.ok, rep.text()
    assert rep.topics["drape/fine"].matched == 1 and rep.topics["mesh/fine"].matched == 1

    replay_into(bad, 1e-3)
    out_json = tmp_path / "cmp.json"
    r = subprocess.run(
        [*CLI, "compare", str(golden), str(bad), "--atol", "1e-6", "--rtol", "0", "--json", str(out_json)],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert r.returncode == 1
    assert "drape/fine" in r.stdout and "first deviation: drape/fine gen=1" in r.stdout and "FAIL" in r.stdout
    report = json.loads(out_json.read_text())
    assert report["ok"] is False and report["topics"]["mesh/fine"]["ok"] is True
    assert report["topics"]["drape/fine"]["worst_abs"] == pytest.approx(1e-3, rel=1e-6)


def _has_summary(path: Path) -> bool:
    try:
        with open(path, "rb") as f:
            return make_reader(f).get_summary() is not None
    except Exception:
        return False


def _publish_drapes(bus, n: int, gen0: int = 0) -> None:
    pub = bus.publisher("drape/coarse", DrapeMsg)
    assert pub.wait_matching(10)
    for i in range(n):
        pub.put(DrapeMsg(level="coarse", generation=gen0 + i, x=np.full((500, 3), float(i), np.float32)))


def test_sigterm_finalizes_and_sigkill_loses_nothing_before_last_flush(tmp_path):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    s = f"k{uuid.uuid4().hex[:8]}"
    term, kill, fixed = tmp_path / "term.mcap", tmp_path / "kill.mcap", tmp_path / "fixed.mcap"
    with open_session(BusConfig(session=s, listen=[endpoint])) as bus:
        # SIGTERM right after publishing: everything already received is written and the file finalized
        rec = _start_recorder(term, s, endpoint)
        _wait_recorder(bus, rec)
        _publish_drapes(bus, 40)
        time.sleep(0.3)
        rec.send_signal(signal.SIGTERM)
        assert rec.wait(15) == 0
        assert _has_summary(term)
        assert [decode(m.data).generation for m in read_session(str(term), ["drape/coarse"])] == list(range(40))

        # SIGKILL: flushed chunks survive
        rec = _start_recorder(kill, s, endpoint, "--flush-interval", "0.2", "--name", "recorder")
        _wait_recorder(bus, rec)
        _publish_drapes(bus, 30, gen0=100)
        time.sleep(1.0)  # > flush interval: the 30 are in a closed chunk on disk
        rec.send_signal(signal.SIGKILL)
        rec.wait(10)
    assert not _has_summary(kill)  # cut short: no summary, only the non-seeking reader gets through
    r = subprocess.run([*CLI, "recover", str(kill), str(fixed)], capture_output=True, text=True, timeout=30)
    assert r.returncode == 0, r.stderr
    gens = [decode(m.data).generation for m in read_session(str(fixed), ["drape/coarse"])]
    assert gens == list(range(100, 130))
    with open(fixed, "rb") as f:
        assert make_reader(f).get_summary().statistics.message_count >= 30


def test_compare_reports_missing_and_integer_mismatch(tmp_path):
    def write(path: Path, tris_shift: int, with_coarse: bool) -> None:
        w = SessionWriter(str(path))
        m = grid_sheet(0.3, 0.3, 4, 4)
        mm = mesh_to_msg(m, generation=1)
        if tris_shift:
            t = mm.tris.numpy().copy()
            t[0] = t[0][[1, 2, 0]]
            mm.tris = t
        w.write("couture/x/mesh/fine", encode(mm), 1)
        if with_coarse:
            w.write("couture/x/drape/coarse", encode(DrapeMsg(level="coarse", x=np.zeros((2, 3)), generation=1)), 2)
        w.close()

    write(tmp_path / "g.mcap", 0, True)
    write(tmp_path / "a.mcap", 1, False)
    rep = compare(str(tmp_path / "g.mcap"), str(tmp_path / "a.mcap"))
    assert not rep.ok
    assert rep.topics["drape/coarse"].missing == ["drape/coarse gen=1"]
    assert any("$.tris" in f and "integers must match" in f for f in rep.topics["mesh/fine"].failures)
    assert rep.first_deviation.startswith("mesh/fine gen=1")
    assert compare(str(tmp_path / "g.mcap"), str(tmp_path / "g.mcap")).ok

"""Recording with a real recorder process: record -> replay -> compare, and
crash tolerance (SIGTERM finalizes; SIGKILL loses nothing before the last
flush and `couture recover` restores it; a recorder restarted by the
supervisor writes the next numbered part, never over the file it had open;
garbage on a recorded topic is recorded apart and never replayed)."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import msgspec
import numpy as np
import pytest
from mcap.reader import make_reader

from couture import supervisor
from couture.bus import BusConfig, free_port, open_session
from couture.mesh import grid_sheet
from couture.recording import SessionWriter, compare, read_session
from couture.recording.parts import INFO_NAME, create_part, expand
from schemas import Array, DrapeMsg, EditMsg, MeshMsg, PatternMsg, PsiMsg, StatusMsg, decode, encode
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


def test_a_prolongation_is_compared_as_points_on_the_coarse_mesh(tmp_path):
    """A fine vertex on an edge two coarse triangles share may name either (which
    one is round-off: two CPUs gave triangles 10 and 30 for one golden vertex):
    the same points pass; a point moved by more than the tolerance fails."""
    coarse, fine = grid_sheet(0.3, 0.3, 3, 3), grid_sheet(0.3, 0.3, 6, 6)
    coarse.level = "coarse"
    T, X = coarse.tris, coarse.X
    a, b, c = X[T[:, 0]], X[T[:, 1]], X[T[:, 2]]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    first, last, bary_first, bary_last = [], [], [], []
    for p in fine.X:
        l1 = ((b[:, 0] - p[0]) * (c[:, 1] - p[1]) - (b[:, 1] - p[1]) * (c[:, 0] - p[0])) / det
        l2 = ((c[:, 0] - p[0]) * (a[:, 1] - p[1]) - (c[:, 1] - p[1]) * (a[:, 0] - p[0])) / det
        w = np.stack([l1, l2, 1.0 - l1 - l2], axis=1)
        inside = np.flatnonzero((w >= -1e-9).all(axis=1))
        first.append(inside[0]), last.append(inside[-1])
        bary_first.append(w[inside[0]]), bary_last.append(w[inside[-1]])
    first, last = np.array(first, np.int32), np.array(last, np.int32)
    ties = int((first != last).sum())
    assert ties > 0  # the boundary vertices of the fine sheet lie on coarse edges

    def write(path: Path, parent: np.ndarray, bary: np.ndarray) -> None:
        w = SessionWriter(str(path))
        w.write("couture/x/mesh/coarse", encode(mesh_to_msg(coarse, generation=1)), 1)
        msg = mesh_to_msg(fine, generation=1, fine_parent_tri=parent, fine_bary=np.array(bary))
        w.write("couture/x/mesh/fine", encode(msg), 2)
        w.close()

    write(tmp_path / "g.mcap", first, bary_first)
    write(tmp_path / "a.mcap", last, bary_last)
    rep = compare(str(tmp_path / "g.mcap"), str(tmp_path / "a.mcap"), rtol=0.0, atol=1e-12)
    assert rep.ok, rep.text()
    moved = np.array(bary_last)
    k = int(np.flatnonzero(first != last)[0])
    moved[k] = moved[k][[1, 2, 0]]  # another point of the same triangle
    write(tmp_path / "m.mcap", last, moved)
    rep = compare(str(tmp_path / "g.mcap"), str(tmp_path / "m.mcap"), rtol=0.0, atol=1e-6)
    assert not rep.ok
    assert any(
        f"fine_parent_tri/fine_bary[{k}]: the point on the coarse mesh" in f for f in rep.topics["mesh/fine"].failures
    )


def _wait_for(cond, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def _gens(path: Path, **kw) -> list[int]:
    return [decode(m.data).generation for m in read_session(str(path), ["pattern"], **kw)]


def _publish_patterns(pub, gens) -> None:
    for g in gens:
        pub.put(PatternMsg(generation=g, source="test"))


def _replay_collect(paths: list[Path], endpoint: str, expect: int, *extra: str) -> tuple[list[bytes], str]:
    """`couture replay PATHS` into a fresh session; the raw payloads that
    arrive on its pattern key, and replay's stderr."""
    s = f"p{uuid.uuid4().hex[:8]}"
    got: list[bytes] = []
    with open_session(BusConfig(session=s, listen=[endpoint])) as bus:
        bus.subscribe_raw(bus.key("pattern"), lambda _k, data, _t: got.append(data))
        r = subprocess.run(
            [*CLI, "replay", *map(str, paths), *extra, "--rate", "0", "--session", s, "--connect", endpoint],
            capture_output=True,
            text=True,
            timeout=30,
        )
        assert r.returncode == 0, r.stderr
        _wait_for(lambda: len(got) >= expect, 10, f"{expect} replayed patterns (have {len(got)})")
        time.sleep(0.3)  # anything more would be a wrong answer: give it a chance to show
    return got, r.stderr


def test_recorder_killed_and_restarted_by_supervisor_writes_a_numbered_part(tmp_path):
    """kill -9 of the recorder under `couture up`'s supervisor: the file it had
    open keeps every message flushed before the kill, byte for byte; the
    restarted recorder writes session.1.mcap; the set reads, recovers and
    replays as one recording, in order."""
    out, log = tmp_path / "session.mcap", tmp_path / "nodes.log"
    s = f"r{uuid.uuid4().hex[:8]}"
    nodes = supervisor.default_nodes(ui=False, record=str(out))
    nodes = [n for n in nodes if n.name == "recorder"]
    nodes[0].args += ["--flush-interval", "0.2"]
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=s, listen=[f"tcp/127.0.0.1:{free_port()}"]),
        nodes=nodes,
        backoff_initial_s=0.2,
        child_log=str(log),
    )
    first, second = list(range(1, 31)), list(range(1001, 1021))
    with supervisor.Supervisor(cfg) as sup, open_session(sup.child_bus) as bus:
        events: list[tuple[str, bool]] = []
        bus.watch_nodes(lambda node, alive: events.append((node, alive)))
        assert bus.wait_nodes(["recorder"], 30) == [], log.read_text()
        pub = bus.publisher("pattern", PatternMsg)
        assert pub.wait_matching(10)
        _publish_patterns(pub, first)
        # past a flush: all of them in closed chunks on disk
        _wait_for(lambda: _gens(out, parts=False) == first, 15, "the first batch on disk")
        pid = sup.pids()["recorder"]
        os.kill(pid, signal.SIGKILL)
        _wait_for(lambda: sup.pids().get("recorder", pid) != pid, 15, "the supervisor to restart the recorder")
        killed = out.read_bytes()
        # the restarted recorder's token comes after the old one went away, once it has subscribed
        _wait_for(lambda: ("recorder", True) in events[events.index(("recorder", False)) :], 30, "recorder back")
        _publish_patterns(pub, second)
        part1 = tmp_path / "session.1.mcap"
        _wait_for(lambda: part1.exists() and _gens(part1, parts=False) == second, 15, "the second batch on disk")
    # (the supervisor stopped the restarted recorder with SIGTERM: part 1 is finalized)

    assert out.read_bytes() == killed  # never reopened for writing
    assert not _has_summary(out) and _has_summary(part1)
    assert sorted(p.name for p in tmp_path.glob("session*.mcap")) == ["session.1.mcap", "session.mcap"]
    assert _gens(out, parts=False) == first  # every message sent before the last flush, exactly
    assert _gens(part1, parts=False) == second
    assert expand(out) == [out, part1]
    assert _gens(out) == first + second  # the set, in order
    assert "part 1 of the recording that starts at" in log.read_text()

    fixed = tmp_path / "fixed.mcap"
    r = subprocess.run([*CLI, "recover", str(out), str(fixed)], capture_output=True, text=True, timeout=30)
    assert r.returncode == 0, r.stderr
    assert _has_summary(fixed) and _gens(fixed) == first + second
    r = subprocess.run([*CLI, "recover", str(out), str(fixed)], capture_output=True, text=True, timeout=30)
    assert r.returncode == 1 and "never written over" in r.stderr

    got, _ = _replay_collect([out], f"tcp/127.0.0.1:{free_port()}", len(first + second))
    assert [decode(d).generation for d in got] == first + second


GARBAGE_KINDS = {
    "not msgpack": (b"\xc1\xc1 not a couture message", "unknown schema"),
    "unknown schema": (msgspec.msgpack.encode({"schema": "couture/nope/v1", "version": 1}), "unknown schema"),
    "unknown version": (None, "version 7 not accepted"),
    "wrong type": (None, "expected couture/pattern/v1"),
    "bad field": (None, "`$.generation`"),
}


def _garbage() -> dict[str, tuple[bytes, str]]:
    pat = msgspec.msgpack.decode(encode(PatternMsg(generation=9)))
    v7 = dict(pat, schema="couture/pattern/v7", version=7)
    bad = dict(pat, generation="nine")
    edit = encode(EditMsg(edit_id="e", d=np.zeros(2)))
    made = {"unknown version": msgspec.msgpack.encode(v7), "wrong type": edit, "bad field": msgspec.msgpack.encode(bad)}
    return {k: (made.get(k, data) or b"", why) for k, (data, why) in GARBAGE_KINDS.items()}


def test_garbage_is_recorded_apart_counted_and_never_replayed(tmp_path):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    s = f"g{uuid.uuid4().hex[:8]}"
    out = tmp_path / "garbage.mcap"
    out.write_bytes(b"someone's file")  # the recorder must not write over it
    garbage = _garbage()
    valid = [1, 2, 3, 4, 5]
    statuses: list[StatusMsg] = []
    with open_session(BusConfig(session=s, listen=[endpoint])) as bus:
        bus.subscribe("status/recorder", statuses.append, StatusMsg)
        rec = _start_recorder(out, s, endpoint, "--flush-interval", "0.2")
        _wait_recorder(bus, rec)
        pub = bus.publisher("pattern", PatternMsg)
        assert pub.wait_matching(10)
        _publish_patterns(pub, valid[:2])
        for data, _ in garbage.values():
            bus.zenoh.put(bus.key("pattern"), data)
        _publish_patterns(pub, valid[2:])
        _wait_for(
            lambda: any(st.counters.get("rejected") == len(garbage) for st in statuses),
            15,
            f"the recorder's status to count {len(garbage)} rejected",
        )
        rec.send_signal(signal.SIGTERM)
        _, err = rec.communicate(timeout=15)
        assert rec.returncode == 0, err
    assert out.read_bytes() == b"someone's file"
    part = tmp_path / "garbage.1.mcap"
    assert f"{out} exists (another recording; never written over): recording to {part}" in err
    assert f"[record] finalized {part}:" in err and f"({len(garbage)} rejected, recorded apart)" in err
    assert f"rejected a payload on couture/{s}/pattern" in err

    # valid traffic reads as before; the garbage sits apart, byte for byte, each with its reason
    assert _gens(part) == valid
    rejected = list(read_session(str(part), which="rejected"))
    assert sorted(r.data for r in rejected) == sorted(d for d, _ in garbage.values())
    for kind, (data, why) in garbage.items():
        (r,) = [r for r in rejected if r.data == data]
        assert r.topic == "pattern" and why in r.rejected, (kind, r.rejected)
    with open(part, "rb") as f:
        channels = make_reader(f).get_summary().channels.values()
    apart = [c for c in channels if c.topic == f"rejected/couture/{s}/pattern"]
    assert len(apart) == 1 and apart[0].message_encoding == "application/octet-stream" and apart[0].schema_id == 0

    # replay sends the valid patterns only; a recording from before the check
    # (garbage among the valid traffic) is read after it and its garbage skipped
    old = tmp_path / "old.mcap"
    w = SessionWriter(str(old))
    w.write("couture/x/pattern", encode(PatternMsg(generation=50)), 1)
    w.write("couture/x/pattern", garbage["bad field"][0], 2)
    w.close()
    got, err = _replay_collect([part, old], endpoint, len(valid) + 1)
    assert [decode(d).generation for d in got] == [*valid, 50]
    assert "1 invalid payloads skipped (never sent)" in err


def _part(base: Path, run: str, writes: list[tuple[str, bytes, bool]]) -> Path:
    f, path, n = create_part(base)
    w = SessionWriter(f)
    w.add_metadata(INFO_NAME, {"run_id": run, "part": str(n), "session": "x"})
    for i, (topic, data, good) in enumerate(writes):
        if good:
            w.write(f"couture/x/{topic}", data, i + 1)
        else:
            w.write_rejected(f"couture/x/{topic}", data, i + 1, "test garbage")
    w.close()
    return path


def test_compare_reads_parts_and_leaves_rejected_out(tmp_path):
    mesh = encode(mesh_to_msg(grid_sheet(0.3, 0.3, 4, 4), generation=1))
    drape = encode(DrapeMsg(level="coarse", x=np.zeros((2, 3)), generation=1))
    g = tmp_path / "golden.mcap"
    _part(g, "A", [("mesh/fine", mesh, True)])
    _part(g, "B", [("drape/coarse", drape, True)])  # another recording's part: not in A's set
    _part(g, "A", [("drape/coarse", drape, True), ("drape/coarse", b"\x00junk", False)])
    assert [p.name for p in expand(g)] == ["golden.mcap", "golden.2.mcap"]
    a = tmp_path / "actual.mcap"
    _part(a, "C", [("mesh/fine", mesh, True), ("drape/coarse", drape, True)])
    rep = compare(str(g), str(a))
    assert rep.ok, rep.text()
    assert rep.rejected == {"golden": 1, "actual": 0} and "not compared): golden 1" in rep.text()
    assert rep.golden == f"{g} (+ golden.2.mcap)"
    rep = compare(str(a), str(tmp_path / "golden.1.mcap"))  # the other recording alone: no mesh
    assert not rep.ok and rep.topics["mesh/fine"].missing == ["mesh/fine gen=1"] and rep.topics["drape/coarse"].ok


def _legacy_mesh(mesh_generation: int, edit_id: str = "", unchanged: bool = False, seed: int = 0) -> bytes:
    """A couture/mesh/v1 payload as the remesher wrote it before Ψ had its own topic."""
    msg = mesh_to_msg(grid_sheet(0.4, 0.3, 4, 3), generation=2, mesh_generation=mesh_generation, design_id="d1")
    raw = msgspec.msgpack.decode(encode(msg))
    psi = np.random.default_rng(seed).normal(size=(raw["X"]["shape"][0], 2, 2)) if edit_id else None
    raw |= {
        "psi": None if psi is None else msgspec.msgpack.decode(msgspec.msgpack.encode(Array.from_numpy(psi))),
        "psi_edit_id": edit_id,
        "unchanged": unchanged,
        "seq": 7,
        "stamp_ns": 123,
    }
    return msgspec.msgpack.encode(raw)


LEGACY_FIELDS = {"psi", "psi_edit_id", "unchanged"}


def test_legacy_meshes_with_psi_read_back_as_mesh_and_psi_messages(tmp_path):
    """Recordings made when Ψ rode on the meshes (``psi``, ``psi_edit_id``,
    ``unchanged``) read back as today's messages: a plain mesh as it is, a mesh
    that carried Ψ as the mesh plus a psi message, an ``unchanged`` re-send as
    the psi message alone; a topic filter on psi/* still finds them."""
    path = tmp_path / "legacy.mcap"
    with contextlib.closing(SessionWriter(str(path))) as w:
        w.write("couture/s1/mesh/fine", _legacy_mesh(1), 1)
        w.write("couture/s1/mesh/fine", _legacy_mesh(2, "e1", seed=1), 2)
        w.write("couture/s1/mesh/fine", _legacy_mesh(2, "e2", unchanged=True, seed=2), 3)
    recs = list(read_session(str(path)))
    assert [r.topic for r in recs] == ["mesh/fine", "mesh/fine", "psi/fine", "psi/fine"]
    assert [r.schema for r in recs] == ["couture/mesh/v1"] * 2 + ["couture/psi/v1"] * 2
    assert recs[0].data == _legacy_mesh(1)  # nothing to migrate: byte for byte (its stale fields are ignored)
    assert not LEGACY_FIELDS & set(msgspec.msgpack.decode(recs[1].data))
    assert [decode(r.data, MeshMsg).mesh_generation for r in recs[:2]] == [1, 2]
    psis = [decode(r.data, PsiMsg) for r in recs[2:]]
    assert [(p.edit_id, p.mesh_generation, p.level, p.design_id, p.generation, p.seq, p.stamp_ns) for p in psis] == [
        ("e1", 2, "fine", "d1", 2, 7, 123),
        ("e2", 2, "fine", "d1", 2, 7, 123),
    ]
    np.testing.assert_array_equal(psis[1].psi.numpy(), np.random.default_rng(2).normal(size=psis[1].psi.numpy().shape))
    assert psis[1].psi.numpy().shape[0] == decode(recs[1].data, MeshMsg).X.shape[0]
    assert [r.log_time for r in recs[2:]] == [2, 3] and recs[2].key == "couture/s1/psi/fine"
    assert [r.topic for r in read_session(str(path), ["psi/*"])] == ["psi/fine", "psi/fine"]
    assert [r.topic for r in read_session(str(path), ["mesh/*"])] == ["mesh/fine", "mesh/fine"]


@pytest.mark.parametrize("case", ["pattern_drag_and_tug", "solver_killed_mid_drag"])
def test_checked_in_goldens_read_back_with_psi_apart(case):
    """The goldens in recordings/ predate the psi topics: each press's Ψ reads
    back on psi/coarse and psi/fine, on a mesh of the recording, and no mesh
    twice (the re-sends that carried Ψ are gone)."""
    path = Path(__file__).resolve().parents[1] / "recordings" / f"{case}.mcap"
    edits = [decode(r.data, EditMsg) for r in read_session(str(path), ["edit"])]
    presses = {e.edit_id for e in edits if e.phase == "press"}
    psis = [decode(r.data, PsiMsg) for r in read_session(str(path), ["psi/*"])]
    assert psis and {p.edit_id for p in psis} <= presses
    for level in ("coarse", "fine"):
        assert sorted(p.edit_id for p in psis if p.level == level) == sorted({p.edit_id for p in psis})
    meshes = [decode(r.data, MeshMsg) for r in read_session(str(path), ["mesh/*"])]
    keys = [(m.level, m.mesh_generation) for m in meshes]
    assert len(keys) == len(set(keys)), "a re-send that carried Ψ read back as a mesh"
    for p in psis:
        mesh = next(m for m in meshes if (m.level, m.mesh_generation) == (p.level, p.mesh_generation))
        assert p.psi.numpy().shape == (mesh.X.shape[0], 2, 2) and np.any(p.psi.numpy())

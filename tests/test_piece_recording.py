"""A session with an imported design (``Design.pieces``) and an edit of a
piece's corner, recorded to MCAP by a real recorder process, replayed by
``couture replay`` into a fresh session (recorded again): the designs the
replay publishes, and those the second recording holds, equal the recorded
ones, the edited piece point included."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

from couture.bus import BusConfig, free_port, open_session
from couture.pattern import apply_edit
from couture.pattern.imported import read_pattern
from couture.pattern.sewing import build_design
from couture.recording import read_session
from schemas import EditMsg, PatternMsg, decode

pytestmark = pytest.mark.timeout(120)

CLI = [sys.executable, "-m", "couture.cli"]
PENELOPE = Path(__file__).parent / "data" / "imported" / "freesewing" / "penelope_cisFemaleAdult34.svg"


def _recorder(path: Path, session: str, endpoint: str, bus) -> subprocess.Popen:
    proc = subprocess.Popen(
        [*CLI, "record", str(path), "--session", session, "--connect", endpoint, "--quiet"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    if bus.wait_nodes(["recorder"], 20):
        proc.kill()
        raise AssertionError(f"recorder did not come up: {proc.communicate()[1][-2000:]}")
    return proc


def _stop(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(15) == 0, proc.communicate()[1][-2000:]


def _designs(path: Path) -> list:
    return [decode(m.data, PatternMsg).design for m in read_session(str(path), ["pattern"])]


def test_imported_design_and_piece_edit_record_and_replay(tmp_path):
    golden, again = tmp_path / "golden.mcap", tmp_path / "again.mcap"
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    design, _ = build_design(read_pattern(PENELOPE))
    pc = next(p for p in design.pieces if p.name == "front")
    element, d = f"pt:front:{pc.corners[1]}", np.array([0.012, -0.008])
    edited = apply_edit(design, element, d)

    sa = f"a{uuid.uuid4().hex[:8]}"
    with open_session(BusConfig(session=sa, listen=[endpoint])) as bus:
        rec = _recorder(golden, sa, endpoint, bus)
        pat, edit = bus.publisher("pattern", PatternMsg), bus.publisher("edit", EditMsg)
        assert pat.wait_matching(10) and edit.wait_matching(10)
        pat.put(PatternMsg(design=design, generation=1, source="ui"))
        for phase, f in (("press", 0.0), ("drag", 0.5), ("release", 1.0)):
            edit.put(EditMsg(edit_id="e1", phase=phase, element=element, d=f * d, generation=1))
            time.sleep(0.05)
        pat.put(PatternMsg(design=edited, generation=2, source="ui"))
        time.sleep(0.5)
        _stop(rec)
    recorded = _designs(golden)
    assert recorded == [design, edited]
    moved = np.asarray(next(p for p in recorded[1].pieces if p.name == "front").outline)[pc.corners[1]]
    assert np.allclose(moved - np.asarray(pc.outline)[pc.corners[1]], d)
    edits = [decode(m.data, EditMsg) for m in read_session(str(golden), ["edit"])]
    assert [(e.phase, e.element) for e in edits] == [(p, element) for p in ("press", "drag", "release")]

    sb = f"b{uuid.uuid4().hex[:8]}"
    with open_session(BusConfig(session=sb, listen=[endpoint])) as bus:
        seen: list = []
        got = threading.Event()

        def on_pattern(msg: PatternMsg) -> None:
            seen.append(msg.design)
            if len(seen) == 2:
                got.set()

        bus.subscribe("pattern", on_pattern)
        rec = _recorder(again, sb, endpoint, bus)
        r = subprocess.run(
            [*CLI, "replay", str(golden), "--rate", "0", "--session", sb, "--connect", endpoint]
            + ["--wait-nodes", "recorder"],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert r.returncode == 0, r.stderr[-2000:]
        assert got.wait(10), f"the replay published {len(seen)} designs"
        time.sleep(0.3)
        _stop(rec)
    assert seen == recorded
    assert _designs(again) == recorded

"""`couture drape` end to end, real nodes over Zenoh on a small skirt: the
exit status says whether the fine drape converged (0), stopped short (3, the
drape written and the diagnosis printed) or the design was bad (4, within
seconds, naming the element); the default output carries no log chatter."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from couture.cli import DrapeExit

pytestmark = pytest.mark.timeout(120)

SMALL = {"sloper": {"kind": "skirt", "params": {}}, "resolution": {"coarse_vertices": 300, "fine_vertices": 900}}


def _drape(tmp_path: Path, design: dict, *extra: str,
           timeout: float = 100.0) -> tuple[subprocess.CompletedProcess, float]:
    pattern = tmp_path / "p.json"
    pattern.write_text(json.dumps(design))
    # a session of its own, so parallel runs never see each other's drapes
    cmd = [sys.executable, "-m", "couture.cli", "drape", str(pattern), "--out", str(tmp_path / "out"),
           "--session", f"t{uuid.uuid4().hex[:8]}", *extra]
    t0 = time.monotonic()
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=dict(os.environ))
    return r, time.monotonic() - t0


def test_converged_drape_exits_0_and_keeps_logs_out_of_the_default_output(tmp_path):
    r, _ = _drape(tmp_path, SMALL)
    assert r.returncode == DrapeExit.CONVERGED, r.stderr[-3000:]
    meta = json.loads((tmp_path / "out" / "drape.json").read_text())
    assert meta["converged"] is True and meta["residual"] <= meta["tolerance"]
    assert (tmp_path / "out" / "drape.obj").stat().st_size > 0
    out = r.stdout + r.stderr
    assert "[drape] fine: converged" in out
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
    assert "solver-kinetic" in last and meta["diagnosis"] in last


def test_rejected_design_exits_4_fast_naming_the_element(tmp_path):
    bad = {**SMALL, "sloper": {"kind": "skirt", "params": {"length": -1.0}}}
    r, seconds = _drape(tmp_path, bad, "--timeout", "90")
    assert r.returncode == DrapeExit.BAD_DESIGN, r.stderr[-3000:]
    assert "rejected pattern generation 1: param:length" in r.stderr
    assert seconds < 45, f"took {seconds:.0f} s: the rejection was not noticed, the wait ran on"
    assert not (tmp_path / "out" / "drape.obj").exists()

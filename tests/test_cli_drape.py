"""`couture drape` end to end, real nodes over Zenoh on a small skirt: the
exit status says whether the fine drape converged (0), stopped short (3, the
drape written and the diagnosis printed) or the design was bad (4, within
seconds, naming the element); the default output carries no log chatter.
The progress lines and the client's wait are also checked without a bus."""

from __future__ import annotations

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
from schemas import DrapeMsg, StatusMsg

pytestmark = pytest.mark.timeout(120)

SMALL = {"sloper": {"kind": "skirt", "params": {}}, "resolution": {"coarse_vertices": 300, "fine_vertices": 900}}


def _drape(
    tmp_path: Path, design: dict, *extra: str, timeout: float = 100.0
) -> tuple[subprocess.CompletedProcess, float]:
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
        f"t{uuid.uuid4().hex[:8]}",
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
    client._on_status(
        StatusMsg(node="remesher", kind="remesher", last_error=f"pattern generation 2 rejected: {reason}")
    )
    assert client.rejection(3) is None  # another generation's rejection says nothing about 3
    threading.Timer(
        0.2,
        lambda: client._on_status(
            StatusMsg(node="remesher", kind="remesher", last_error=f"pattern generation 3 rejected: {reason}")
        ),
    ).start()
    t0 = time.monotonic()
    with pytest.raises(PatternRejected) as e:
        client.follow_drape(3, timeout=10)
    assert time.monotonic() - t0 < 5 and e.value.reason == reason and e.value.generation == 3

"""`couture up` as a real process tree: nodes come up, a killed node is
restarted with a new pid, Ctrl-C leaves no orphans and frees the port."""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import threading
import time
import uuid

import psutil
import pytest

from couture.bus import BusConfig, free_port, open_session

pytestmark = pytest.mark.timeout(90)

NODES = ["remesher", "solver-kinetic", "sensitivity"]


def test_up_restarts_killed_node_and_ctrl_c_leaves_no_orphans():
    session = f"s{uuid.uuid4().hex[:8]}"
    port = free_port()
    sup = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "couture.cli",
            "up",
            "--no-ui",
            "--session",
            session,
            "--listen",
            f"tcp/127.0.0.1:{port}",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    seen_pids: set[int] = set()
    try:
        with open_session(BusConfig(session=session, connect=[f"tcp/127.0.0.1:{port}"])) as bus:
            pids: dict[str, int] = {}
            lock = threading.Lock()

            def on_status(msg) -> None:
                with lock:
                    pids[msg.node] = msg.pid

            bus.subscribe("status/*", on_status)
            assert bus.wait_nodes(NODES, 30) == []
            deadline = time.monotonic() + 10
            while not all(n in pids for n in NODES) and time.monotonic() < deadline:
                time.sleep(0.05)
            children = {p.pid for p in psutil.Process(sup.pid).children(recursive=True)}
            seen_pids |= children
            old = pids["solver-kinetic"]
            assert old in children

            psutil.Process(old).kill()
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline:
                with lock:
                    new = pids.get("solver-kinetic")
                if new != old and "solver-kinetic" in bus.live_nodes(timeout=0.3):
                    break
                time.sleep(0.1)
            assert new != old, "solver was not restarted"
            assert psutil.pid_exists(new)
            seen_pids |= {p.pid for p in psutil.Process(sup.pid).children(recursive=True)}

        sup.send_signal(signal.SIGINT)
        out, err = sup.communicate(timeout=30)
        assert sup.returncode == 0, err[-3000:]
        assert "UI:" not in out  # --no-ui
        assert f"node solver-kinetic (pid {old}) exited with code -9; restarting" in err
        alive = [p for p in seen_pids if psutil.pid_exists(p) and psutil.Process(p).status() != psutil.STATUS_ZOMBIE]
        assert alive == [], f"orphans left: {alive}"
        with socket.socket() as s:  # nobody listens on the supervisor's port any more (TIME_WAIT is fine)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            s.bind(("127.0.0.1", port))
            s.listen()
    finally:
        if sup.poll() is None:
            sup.kill()
        for p in seen_pids:
            try:
                psutil.Process(p).kill()
            except psutil.NoSuchProcess:
                pass


def test_drape_fails_clearly_when_nothing_answers(tmp_path):
    """`couture drape` joining a bus where no remesher/solver runs must time out
    naming what never answered, and write no result."""
    pattern = tmp_path / "p.json"
    pattern.write_text('{"sloper": {"kind": "skirt", "params": {}}}')
    session, port = f"d{uuid.uuid4().hex[:8]}", free_port()
    with open_session(BusConfig(session=session, listen=[f"tcp/127.0.0.1:{port}"])):
        r = subprocess.run(
            [
                sys.executable,
                "-m",
                "couture.cli",
                "drape",
                str(pattern),
                "--out",
                str(tmp_path / "out"),
                "--timeout",
                "1.5",
                "--session",
                session,
                "--connect",
                f"tcp/127.0.0.1:{port}",
            ],
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert r.returncode == 5  # couture.cli.DrapeExit.TIMEOUT
    assert "no drape/fine for generation >= 1" in r.stderr
    assert "remesher never answered (remesher is not live)" in r.stderr and "no solver-* node is live" in r.stderr
    assert not (tmp_path / "out" / "drape.obj").exists()

    bad = tmp_path / "bad.json"
    bad.write_text('{"sloper": {"kind": 3}}')
    r = subprocess.run(
        [sys.executable, "-m", "couture.cli", "drape", str(bad), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert (
        r.returncode == 4 and "not a couture/design/v1 pattern" in r.stderr
    )  # DrapeExit.BAD_DESIGN and "$.sloper.kind" in r.stderr

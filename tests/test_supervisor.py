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

NODES = ["remesher", "solver-newton", "sensitivity", "adjust"]


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
            old = pids["solver-newton"]
            assert old in children

            psutil.Process(old).kill()
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline:
                with lock:
                    new = pids.get("solver-newton")
                if new != old and "solver-newton" in bus.live_nodes(timeout=0.3):
                    break
                time.sleep(0.1)
            assert new != old, "solver was not restarted"
            assert psutil.pid_exists(new)
            seen_pids |= {p.pid for p in psutil.Process(sup.pid).children(recursive=True)}

        sup.send_signal(signal.SIGINT)
        try:  # the supervisor stops its children within 2 x term_timeout_s (5 s) and closes its bus
            out, err = sup.communicate(timeout=45)
        except subprocess.TimeoutExpired:
            sup.kill()
            out, err = sup.communicate()
            raise AssertionError(f"`couture up` did not exit within 45 s of Ctrl-C; its log:\n{err[-4000:]}") from None
        assert sup.returncode == 0, err[-3000:]
        assert "UI:" not in out  # --no-ui
        assert f"node solver-newton (pid {old}) exited with code -9; restarting" in err
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
    # the message names the design waited for by its identity: the remesher never numbered it
    assert "no drape/fine for this client's design " in r.stderr
    assert "(asked for generation 1, not numbered yet: no mesh of it arrived)" in r.stderr
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


def _read_url(proc: subprocess.Popen, deadline: float) -> str:
    """The first 'couture UI: URL' line a UI node prints."""
    assert proc.stdout is not None
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        if line.startswith("couture UI: "):
            return line.split("couture UI: ", 1)[1].strip()
    raise AssertionError(f"no URL printed (exit code {proc.poll()})")


def test_two_uis_on_one_port_each_serve_and_print_their_own_url():
    """Two UI nodes (two sessions) asked for the same port: the second takes the
    next free one and prints it, neither exits (no crash loop under `couture up`),
    and each URL serves its own page."""
    import urllib.request

    port = free_port()
    procs = []
    try:
        urls = []
        for k in range(2):
            session = f"ui{k}{uuid.uuid4().hex[:6]}"
            procs.append(
                subprocess.Popen(
                    [sys.executable, "-m", "nodes.ui", "--session", session, "--port", str(port)],
                    stdout=subprocess.PIPE,
                    stderr=subprocess.DEVNULL,
                    text=True,
                )
            )
            urls.append(_read_url(procs[-1], time.monotonic() + 60))
        assert urls[0] == f"http://127.0.0.1:{port}/" and urls[1] != urls[0], urls
        for url, proc in zip(urls, procs, strict=True):
            assert proc.poll() is None, "a UI node exited"
            with urllib.request.urlopen(url, timeout=10) as page:
                assert page.status == 200 and b'id="view3d"' in page.read()
    finally:
        for proc in procs:
            proc.send_signal(signal.SIGINT)
        for proc in procs:
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def test_up_picks_a_free_ui_port_or_fails_clearly_on_an_explicit_taken_one():
    from couture.bus.ports import free_port_block, port_is_free
    from couture.cli import ui_port_for

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as held:
        held.bind(("127.0.0.1", 0))
        held.listen()
        taken = held.getsockname()[1]
        block = free_port_block(taken, 3)
        assert block != taken and all(port_is_free(block + i) for i in range(3))
        with pytest.raises(RuntimeError, match=f"--ui-port {taken}: port {taken} on 127.0.0.1 is already in use"):
            ui_port_for("127.0.0.1", taken)
        # the command line: an error before any node starts
        r = subprocess.run(
            [sys.executable, "-m", "couture.cli", "up", "--ui-port", str(taken), "--session", "porttest"],
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert r.returncode == 1 and f"couture up: error: --ui-port {taken}: port {taken}" in r.stderr, r.stderr
    assert "started remesher" not in r.stderr


def test_up_only_picks_nodes_by_kind_and_names_what_it_cannot_pick():
    from couture.supervisor import default_nodes, only_nodes

    every = default_nodes(solvers=["kinetic", "newton"], ui=True, record="s.mcap")
    assert [n.name for n in only_nodes(every, None)] == [n.name for n in every]
    assert [n.name for n in only_nodes(every, ["solver"])] == ["solver-kinetic", "solver-newton"]
    assert [n.name for n in only_nodes(every, ["remesher", "sensitivity", "ui"])] == ["remesher", "sensitivity", "ui"]
    with pytest.raises(ValueError, match="solvers: not a node kind"):
        only_nodes(every, ["solvers"])
    with pytest.raises(ValueError, match=r"recorder: no such node here \(the recorder needs --record FILE\)"):
        only_nodes(default_nodes(ui=False), ["recorder"])
    # on the command line: exit 2 with the reason, before any node starts
    r = subprocess.run(
        [sys.executable, "-m", "couture", "up", "--only", "ui", "--no-ui"], capture_output=True, text=True, timeout=60
    )
    assert r.returncode == 2 and "--only ui: no such node here (not with --no-ui)" in r.stderr, r.stderr


def test_up_passes_its_zenoh_config_file_to_every_node(tmp_path):
    """``couture up --config FILE``: each node it starts joins with the same
    Zenoh config file (before, only the supervisor's router read it); the
    file's settings apply, the endpoints given on the command line win."""
    conf = tmp_path / "zenoh.json5"
    conf.write_text("{ transport: { unicast: { max_links: 1 } }, scouting: { delay: 150 } }\n")
    session = f"s{uuid.uuid4().hex[:8]}"
    port = free_port()
    sup = subprocess.Popen(
        [sys.executable, "-m", "couture.cli", "up", "--no-ui", "--no-adjust", "--only", "remesher", "sensitivity"]
        + ["--session", session, "--listen", f"tcp/127.0.0.1:{port}", "--config", str(conf)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        with open_session(BusConfig(session=session, connect=[f"tcp/127.0.0.1:{port}"])) as bus:
            assert bus.wait_nodes(["remesher", "sensitivity"], 60) == []
        children = psutil.Process(sup.pid).children(recursive=True)
        lines = [c.cmdline() for c in children]
        nodes = [cl for cl in lines if "--name" in cl]
        assert len(nodes) == 2, lines
        for cl in nodes:
            i = cl.index("--config")
            assert cl[i + 1] == str(conf), cl
    finally:
        sup.send_signal(signal.SIGINT)
        try:
            sup.wait(30)
        except subprocess.TimeoutExpired:
            sup.kill()

"""Several machines: the nodes on separate addresses, through one router.

The test makes its own network namespaces (and removes them, whatever
happens): a router namespace forwarding between three subnets, and three
"machines" each on its own veth pair to it:

    A 10.77.1.1  couture up --graph tests/graphs/two_machines.toml --machine a
    B 10.77.2.1  couture up --graph tests/graphs/two_machines.toml --machine b
    C 10.77.3.1  the scripted client (tests/netns_driver.py), a Zenoh client of A's router

The graph places the remesher and the sensitivity node on A, whose router
listens on tcp/10.77.1.1:7447, and the Newton solver on B, whose router
connects there (its [machines] tables). A design published on C is meshed
on A, draped on B, and its drape arrives on C; a press and drag on C gets the
sensitivity node's prediction from A; the edited design's fine drape follows.
Then B's link goes down (its router-side veth, as a pulled cable): A and C see
the solver go once the Zenoh lease runs out, a design published meanwhile is
meshed on A, and once the link is back up B's router reconnects by itself and
the solver drapes that design (the mesh it missed is in A's history). The
lease is 1 s here (a config file given to both `couture up`, to keep the test
short); the default is 10 s.

Needs root (CAP_NET_ADMIN) and iproute2: skipped, saying why, only when
``ip netns add`` is refused.
"""

from __future__ import annotations

import json
import os
import select
import shutil
import signal
import subprocess
import sys
import time
import uuid
from contextlib import ExitStack
from pathlib import Path

import pytest

from couture.graph import load_graph

pytestmark = [pytest.mark.timeout(240), pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
GRAPH = ROOT / "tests" / "graphs" / "two_machines.toml"
SUBNET = "10.77"
MACHINES = ("a", "b", "c")
LEASE = "{transport: {link: {tx: {lease: 1000, keep_alive: 4}}}}"
"""Zenoh's lease (ms): a silent link is given up after this (default 10000)"""


def ip(*args: str) -> None:
    r = subprocess.run(["ip", *args], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {r.stderr.strip() or r.returncode}")


class Net:
    """A router namespace and one namespace per machine, each on its own subnet
    (``10.77.<i>.0/24``, the machine at .1, the router at .254)."""

    def __init__(self) -> None:
        self.prefix = f"cn{os.getpid() % 100000}{uuid.uuid4().hex[:2]}"  # veth names <= 15 chars
        self.router = f"{self.prefix}r"
        self.made: list[str] = []

    def ns(self, m: str) -> str:
        return f"{self.prefix}{m}"

    def addr(self, m: str) -> str:
        return f"{SUBNET}.{MACHINES.index(m) + 1}.1"

    def router_side(self, m: str) -> str:
        """The router's end of machine ``m``'s veth pair (down: ``m`` is cut off)."""
        return f"{self.prefix}{m}r"

    def up(self) -> None:
        ip("netns", "add", self.router)
        self.made.append(self.router)
        ip("-n", self.router, "link", "set", "lo", "up")
        subprocess.run(
            ["ip", "netns", "exec", self.router, "sysctl", "-qw", "net.ipv4.ip_forward=1"], check=True, timeout=10
        )
        for i, m in enumerate(MACHINES, start=1):
            ns, dev, rdev = self.ns(m), f"{self.prefix}{m}", self.router_side(m)
            ip("netns", "add", ns)
            self.made.append(ns)
            ip("-n", ns, "link", "set", "lo", "up")
            ip("link", "add", dev, "netns", ns, "type", "veth", "peer", "name", rdev, "netns", self.router)
            ip("-n", ns, "addr", "add", f"{SUBNET}.{i}.1/24", "dev", dev)
            ip("-n", self.router, "addr", "add", f"{SUBNET}.{i}.254/24", "dev", rdev)
            ip("-n", ns, "link", "set", dev, "up")
            ip("-n", self.router, "link", "set", rdev, "up")
            ip("-n", ns, "route", "add", "default", "via", f"{SUBNET}.{i}.254")

    def pids(self, m: str) -> set[int]:
        r = subprocess.run(["ip", "netns", "pids", self.ns(m)], capture_output=True, text=True)
        return {int(p) for p in r.stdout.split()}

    def exec(self, m: str, args: list[str], log: Path, **kw) -> subprocess.Popen:
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        with open(log, "ab") as out:
            return subprocess.Popen(
                ["ip", "netns", "exec", self.ns(m), *args], env=env, stderr=out, start_new_session=True, **kw
            )

    def down(self) -> None:
        """Kill what still runs in the namespaces (only what this test started
        there), then delete them (their veths go with them)."""
        for ns in self.made:
            if ns == self.router:
                continue
            r = subprocess.run(["ip", "netns", "pids", ns], capture_output=True, text=True)
            for pid in r.stdout.split():
                try:
                    os.kill(int(pid), signal.SIGKILL)
                except ProcessLookupError:
                    pass
        for ns in reversed(self.made):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)
        self.made.clear()


@pytest.fixture
def net():
    if shutil.which("ip") is None:
        pytest.skip("iproute2's `ip` is not installed: cannot make network namespaces")
    probe = f"cnprobe{os.getpid()}"
    r = subprocess.run(["ip", "netns", "add", probe], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"`ip netns add` is not permitted here (needs root / CAP_NET_ADMIN): {r.stderr.strip()}")
    subprocess.run(["ip", "netns", "del", probe], capture_output=True)
    n = Net()
    try:
        n.up()
        yield n
    finally:
        n.down()
        left = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
        assert n.prefix not in left, f"namespaces left behind: {left}"


class Driver:
    """The client process on machine C: one JSON command in, one JSON answer out."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.proc = proc
        self.ask_timeout = 0.0

    def read(self, timeout: float) -> dict:
        assert self.proc.stdout is not None
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
        if not ready:
            raise AssertionError(f"the client on machine C did not answer within {timeout:g} s")
        line = self.proc.stdout.readline()
        if not line:
            raise AssertionError(f"the client on machine C exited ({self.proc.wait(5)})")
        return json.loads(line)

    def __call__(self, op: str, timeout: float = 60.0, **kw) -> dict:
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps({"op": op, "timeout": timeout, **kw}) + "\n")
        self.proc.stdin.flush()
        out = self.read(timeout + 15)
        assert "error" not in out, f"{op}: {out['error']}"
        return out


def stop(proc: subprocess.Popen) -> None:
    """SIGINT (couture up stops its nodes), SIGKILL if it lingers."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def test_nodes_on_three_machines_through_a_router_survive_a_partition(net: Net, tmp_path: Path) -> None:
    session = f"n{uuid.uuid4().hex[:8]}"
    conf = tmp_path / "lease.json5"
    conf.write_text(LEASE)
    endpoint = f"tcp/{net.addr('a')}:7447"
    graph = load_graph(GRAPH)
    assert graph.machines["a"].listen == [endpoint] and graph.machines["b"].connect == [endpoint]
    where = {n.name: n.machine for n in graph.nodes}
    assert where == {"remesher": "a", "sensitivity": "a", "solver-newton": "b"}
    up = [sys.executable, "-m", "couture", "up", "--session", session, "--config", str(conf), "--graph", str(GRAPH)]
    logs = {m: tmp_path / f"{m}.log" for m in MACHINES}
    t0 = time.monotonic()
    with ExitStack() as stack:
        a = net.exec("a", [*up, "--machine", "a"], logs["a"])
        stack.callback(stop, a)
        # a Zenoh client gives up at once when nothing listens: C starts once A's router does
        deadline = time.monotonic() + 30
        while "[up] session" not in logs["a"].read_text(errors="replace"):
            assert a.poll() is None, f"couture up on machine A exited: {logs['a'].read_text()[-3000:]}"
            assert time.monotonic() < deadline, f"couture up on machine A not up: {logs['a'].read_text()[-3000:]}"
            time.sleep(0.1)
        b = net.exec("b", [*up, "--machine", "b"], logs["b"])
        stack.callback(stop, b)
        c = net.exec(
            "c",
            [sys.executable, str(ROOT / "tests" / "netns_driver.py"), "--connect", endpoint, "--session", session],
            logs["c"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        stack.callback(stop, c)
        try:
            client = Driver(c)
            assert client.read(30).get("ok")
            client("wait_nodes", nodes=["remesher", "sensitivity", "solver-newton"], timeout=60)
            # each node runs on the machine the graph places it on
            deadline = time.monotonic() + 10  # (a node's status goes out once a second)
            while not set(where) <= set(pids := client("pids", timeout=5)["pids"]):
                assert time.monotonic() < deadline, f"no status from {sorted(set(where) - set(pids))}"
                time.sleep(0.2)
            for node, m in where.items():
                assert pids[node] in net.pids(m), f"{node} (pid {pids[node]}) is not on machine {m}"

            # --- edit -> prediction -> fine drape, across the router
            first = client("drape", length=0.5, timeout=120)
            assert first["solver"] == "solver-newton" and first["converged"], first
            client("ready", generation=first["generation"], timeout=30)
            pred = client("predict", length=0.05, timeout=30)
            assert pred["generation"] == first["generation"] and pred["n"] == first["n"]
            assert pred["y_min"] < first["y_min"]  # a longer skirt: the predicted hem is lower
            edited = client("drape", length=0.55, timeout=90)
            assert edited["generation"] > first["generation"] and edited["converged"], edited
            assert edited["solver"] == "solver-newton"
            t_path = time.monotonic() - t0

            # --- partition: B's cable pulled; A and C go on without the solver
            ip("-n", net.router, "link", "set", net.router_side("b"), "down")
            t_cut = time.monotonic()
            deadline = t_cut + 20
            while "solver-newton" in client("live", timeout=5)["live"]:
                assert time.monotonic() < deadline, "the solver still looks live 20 s after its link went down"
                time.sleep(0.2)
            during = client("publish", length=0.6, timeout=30)  # meshed on A while B is cut off
            assert during["generation"] > edited["generation"]
            assert "solver-newton" not in client("live", timeout=5)["live"]
            # --- heal: B's router reconnects by itself, the solver drapes what it missed
            ip("-n", net.router, "link", "set", net.router_side("b"), "up")
            t_heal = time.monotonic()
            client("wait_nodes", nodes=["solver-newton"], timeout=30)
            healed = client("follow", asked=during["asked"], timeout=90)
            assert healed["generation"] == during["generation"] and healed["solver"] == "solver-newton"
            assert healed["converged"], healed
            # and the session goes on as before
            after = client("drape", length=0.52, timeout=90)
            assert after["generation"] > healed["generation"] and after["converged"], after
            print(
                f"\n[netns] path {t_path:.1f} s, solver gone {t_heal - t_cut:.1f} s after the cut, "
                f"healed drape +{time.monotonic() - t_heal:.1f} s, total {time.monotonic() - t0:.1f} s"
            )
        except BaseException:
            for m, log in logs.items():
                text = log.read_text(errors="replace") if log.exists() else ""
                print(f"--- machine {m} ({log.name}), last lines:\n{text[-3000:]}")
            raise

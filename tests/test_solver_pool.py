"""A pool of solver nodes shared by design sessions (``--serve-session``):
two sessions, each with its own remesher, two pool members serving both.
Each session's designs are draped by one member (shared out, not solved
twice); when a member is killed its session passes to the other, which
drapes that session's next design; `couture bench load` runs on it."""

from __future__ import annotations

import json
import os
import signal
import time
import uuid
from dataclasses import replace

import msgspec
import pytest

from bench import load
from couture import supervisor
from couture.bus import BusConfig, free_port
from couture.client import Client
from schemas.design import Sloper

pytestmark = [pytest.mark.timeout(240), pytest.mark.slow]


def test_two_sessions_share_a_pool_and_a_dead_member_hands_over(tmp_path):
    tag = uuid.uuid4().hex[:6]
    sessions = [f"pa{tag}", f"pb{tag}"]
    specs = [n for n in load.nodes_for(sessions, 2, "newton") if not n.name.startswith("sensitivity")]
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=f"pool{tag}", listen=[f"tcp/127.0.0.1:{free_port()}"]),
        nodes=specs,
        backoff_initial_s=30.0,  # the killed member stays down for the rest of the test
        child_log=str(tmp_path / "nodes.log"),
    )
    members = ["solver-pool0", "solver-pool1"]
    with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as pool:
        clients = [Client(bus=replace(sup.child_bus, session=s)).__enter__() for s in sessions]
        try:
            pool.wait_nodes(members, timeout=90)
            for c in clients:
                c.wait_nodes(["remesher", *members], timeout=90)
            gens = [c.publish_pattern(load.DESIGN, name="pool") for c in clients]
            drapes = [c.follow_drape(g, timeout=150) for c, g in zip(clients, gens, strict=True)]
            # session i is draped by member i, and only by it
            assert [d.solver for d in drapes] == members
            for c, m in zip(clients, members, strict=True):
                assert {d.solver for d in c.drapes("fine") + c.drapes("coarse")} == {m}

            sup.children["solver-pool1"].spec.restart = False
            pid = sup.pids()["solver-pool1"]
            os.kill(pid, signal.SIGKILL)
            deadline = time.monotonic() + 30
            while "solver-pool1" in pool.live_nodes(timeout=0.3):
                assert time.monotonic() < deadline, "the killed member stayed live"
            # the second session's next design is draped by the member left
            changed = msgspec.structs.replace(load.DESIGN, sloper=Sloper(kind="skirt", params={"length": 0.5}))
            gen = clients[1].publish_pattern(changed, name="after-kill")
            d = clients[1].follow_drape(gen, timeout=150)
            assert d.solver == "solver-pool0" and d.final
            st = pool.status["solver-pool0"]
            assert st.counters.get("bad_messages", 0) == 0 and st.counters.get("callback_errors", 0) == 0
        finally:
            for c in clients:
                c.__exit__(None, None, None)


def test_bench_load_runs_and_loses_nothing(tmp_path, capsys):
    assert load.main(["--sessions", "2", "--rounds", "1", "--drags", "5", "--out", str(tmp_path)]) == 0
    out = json.loads((tmp_path / "load.json").read_text())
    (row,) = out["rows"]
    assert row["sessions"] == 2 and row["lost_total"] == 0 and row["designs"] == 2
    assert row["answered"] >= 1 and row["level_solves"] >= 2
    assert "solves/min" in capsys.readouterr().out

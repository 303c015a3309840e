"""Load: N design sessions at once sharing one pool of solver nodes.

Each design session is a couture session of its own (keys under
``couture/<session>/``) with its own remesher and sensitivity node: the
design numbering and the factorization at the drape are per design. The
solvers are a pool (``python -m nodes.solver --serve-session S ...``): every
member serves every session, the members find each other by liveliness in
the pool's own session and share the sessions out (session i to member
i mod k, passed on when a member dies); one member solves one thing at a
time. All of it runs under one supervisor, each node its own process.

Per N (default 1, 2, 4, 8; ``--pool`` members, default 2): every session
drapes a small skirt, then all sessions at once run ``--rounds`` rounds of a
designer: press ``param:length``, drag at ``--hz`` for ``--drags`` events,
release, publish the skirt 1 cm longer or back and wait for its final fine
drape. Measured from the bus, on this machine's clock:

* edit-to-prediction latency: a drag's send time to its prediction's arrival
  (drags the sensitivity node coalesced have none: counted ``coalesced``);
* pattern-to-fine: publishing a change to its final fine drape;
* solves per minute: level solves the pool finished (its ``solves/*``
  counters) and designs draped per minute of the rounds;
* nothing dropped: every gesture's last drag is predicted, every design gets
  its final fine drape, and every node's status counts no bad message, no
  callback error and no expired gesture (``lost`` sums them; it must be 0).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import threading
import time
import uuid
from dataclasses import replace
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from bench import add_out_arg, source_commit, write_results
from couture import supervisor
from couture.bus import BusConfig, free_port
from couture.client import Client
from couture.solvers import SOLVERS
from schemas import DrapeMsg
from schemas.design import Design, Resolution, Sloper

DESIGN = Design(sloper=Sloper(kind="skirt"), resolution=Resolution(coarse_vertices=200, fine_vertices=500))
LENGTH0_M = 0.55
LENGTH_STEP_M = 0.01
LOSS_COUNTERS = ("bad_messages", "callback_errors", "gestures_expired")
"""status counters that mean something was dropped or lost"""


def nodes_for(sessions: list[str], pool: int, solver: str) -> list[supervisor.NodeSpec]:
    """A remesher and a sensitivity node per session, ``pool`` solver nodes serving them all."""
    specs = []
    for s in sessions:
        specs.append(supervisor.NodeSpec(f"remesher-{s}", "nodes.remesher", ["--session", s, "--name", "remesher"]))
        specs.append(
            supervisor.NodeSpec(f"sensitivity-{s}", "nodes.sensitivity", ["--session", s, "--name", "sensitivity"])
        )
    serve = [a for s in sessions for a in ("--serve-session", s)]
    for k in range(pool):
        specs.append(supervisor.NodeSpec(f"solver-pool{k}", "nodes.solver", ["--solver", solver, *serve]))
    return specs


class Designer:
    """One design session's client and what it measured."""

    def __init__(self, client: Client) -> None:
        self.client = client
        self.lock = threading.Lock()
        self.recv: dict[tuple[str, float], int] = {}
        self.latency_ms: list[float] = []
        self.fine_s: list[float] = []
        self.drags = 0
        self.unanswered_last = 0
        self.lost_designs = 0
        self.designs = 0
        client.bus.subscribe("drape/predicted", self._on_pred, DrapeMsg)

    def _on_pred(self, msg: DrapeMsg) -> None:
        t = time.perf_counter_ns()
        if msg.d is not None:
            with self.lock:
                self.recv.setdefault((msg.edit_id, round(float(msg.d.numpy()[0]), 9)), t)

    def counter(self, name: str) -> int:
        st = self.client.status.get("sensitivity")
        return int(st.counters.get(name, 0)) if st is not None else 0

    def round(self, k: int, drags: int, hz: float, timeout: float) -> None:
        c = self.client
        c.wait_predictions_ready(timeout, generation=c.current_generation)
        columns = self.counter("press_columns")
        press = c.send_edit("param:length", [0.0, 0.0], phase="press")
        deadline = time.monotonic() + timeout
        while self.counter("press_columns") <= columns and time.monotonic() < deadline:
            time.sleep(0.02)
        sent: dict[float, int] = {}
        next_t = time.perf_counter()
        for j in range(1, drags + 1):
            d = round(1e-4 * j, 9)
            sent[d] = time.perf_counter_ns()
            c.send_edit("param:length", [d, 0.0], phase="drag", edit_id=press.edit_id)
            next_t += 1.0 / hz
            time.sleep(max(0.0, next_t - time.perf_counter()))
        last = round(1e-4 * drags, 9)
        deadline = time.monotonic() + 10.0
        while (press.edit_id, last) not in self.recv and time.monotonic() < deadline:
            time.sleep(0.01)
        c.send_edit("param:length", [last, 0.0], phase="release", edit_id=press.edit_id)
        with self.lock:
            self.latency_ms += [
                (self.recv[(press.edit_id, d)] - t) / 1e6 for d, t in sent.items() if (press.edit_id, d) in self.recv
            ]
            self.drags += drags
            self.unanswered_last += (press.edit_id, last) not in self.recv
        length = LENGTH0_M + (LENGTH_STEP_M if k % 2 == 0 else 0.0)
        t0 = time.perf_counter()
        gen = c.publish_pattern(msgspec.structs.replace(DESIGN, sloper=Sloper(kind="skirt", params={"length": length})))
        self.designs += 1
        try:
            c.follow_drape(gen, timeout=timeout)
            self.fine_s.append(time.perf_counter() - t0)
        except TimeoutError:
            self.lost_designs += 1


def _pct(v: list[float], q: float) -> float | None:
    return float(np.percentile(v, q)) if v else None


def run(n: int, *, pool: int, rounds: int, drags: int, hz: float, solver: str, timeout: float) -> dict[str, Any]:
    tag = uuid.uuid4().hex[:6]
    sessions = [f"load{tag}-{i}" for i in range(n)]
    log_path = Path(tempfile.gettempdir()) / f"couture-load-{tag}.log"
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=f"pool{tag}", listen=[f"tcp/127.0.0.1:{free_port()}"]),
        nodes=nodes_for(sessions, pool, solver),
        child_log=str(log_path),
    )
    t_start = time.perf_counter()
    with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as pool_client:
        clients = [Client(bus=replace(sup.child_bus, session=s)).__enter__() for s in sessions]
        try:
            members = [f"solver-pool{k}" for k in range(pool)]
            pool_client.wait_nodes(members, timeout=timeout)
            for c in clients:
                c.wait_nodes(["remesher", "sensitivity", *members], timeout=timeout)
            designers = [Designer(c) for c in clients]
            gens = [c.publish_pattern(DESIGN, name="load") for c in clients]
            for c, g in zip(clients, gens, strict=True):
                c.follow_drape(g, timeout=timeout)
            t_up = time.perf_counter() - t_start
            solves0 = _pool_solves(pool_client, members)
            t0 = time.perf_counter()
            threads = [
                threading.Thread(target=lambda d=d: [d.round(k, drags, hz, timeout) for k in range(rounds)])
                for d in designers
            ]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            minutes = (time.perf_counter() - t0) / 60.0
            time.sleep(1.5)  # one more status period: the counters of the last round
            solves = _pool_solves(pool_client, members) - solves0
            per_member = {m: _pool_solves(pool_client, [m]) for m in members}
            loss = {name: 0 for name in LOSS_COUNTERS}
            for c in [pool_client, *clients]:
                for node, st in c.status.items():
                    if node.startswith(("remesher", "sensitivity", "solver")):
                        for name in LOSS_COUNTERS:
                            loss[name] += int(st.counters.get(name, 0))
        finally:
            for c in clients:
                c.__exit__(None, None, None)
    lat = [x for d in designers for x in d.latency_ms]
    fine = [x for d in designers for x in d.fine_s]
    n_drags = sum(d.drags for d in designers)
    lost_last = sum(d.unanswered_last for d in designers)
    lost_designs = sum(d.lost_designs for d in designers)
    designs = sum(d.designs for d in designers)
    return {
        "sessions": n,
        "pool": pool,
        "startup_and_first_drapes_s": t_up,
        "drags": n_drags,
        "answered": len(lat),
        "coalesced": n_drags - len(lat),
        "latency_ms": {"p50": _pct(lat, 50), "p90": _pct(lat, 90), "p99": _pct(lat, 99), "max": max(lat, default=None)},
        "pattern_to_fine_s": {"p50": _pct(fine, 50), "p90": _pct(fine, 90)},
        "designs": designs,
        "designs_per_min": (designs - lost_designs) / minutes,
        "level_solves": solves,
        "solves_per_min": solves / minutes,
        "solves_by_member_incl_first_drapes": per_member,
        "minutes": minutes,
        "lost": {"last_drag_unpredicted": lost_last, "designs_without_fine_drape": lost_designs, **loss},
        "lost_total": lost_last + lost_designs + sum(loss.values()),
        "node_log": str(log_path),
    }


def _pool_solves(client: Client, members: list[str]) -> int:
    total = 0
    for m in members:
        st = client.status.get(m)
        if st is not None:
            total += sum(v for k, v in st.counters.items() if k.startswith("solves/"))
    return total


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench load", description=__doc__.split("\n\n")[0])
    ap.add_argument("--sessions", default="1,2,4,8", help="numbers of concurrent design sessions")
    ap.add_argument("--pool", type=int, default=2, help="solver nodes in the pool")
    ap.add_argument("--rounds", type=int, default=3, help="drag + design change rounds per session")
    ap.add_argument("--drags", type=int, default=30, help="drag events per gesture")
    ap.add_argument("--hz", type=float, default=30.0, help="drag rate per session")
    ap.add_argument("--solver", default="newton", choices=list(SOLVERS))
    ap.add_argument("--timeout", type=float, default=180.0, help="[s] any single wait")
    add_out_arg(ap)
    a = ap.parse_args(argv)
    rows = []
    for n in (int(s) for s in a.sessions.split(",")):
        r = run(n, pool=a.pool, rounds=a.rounds, drags=a.drags, hz=a.hz, solver=a.solver, timeout=a.timeout)
        rows.append(r)
        print(
            f"[load] N={n}: p50 {r['latency_ms']['p50']} ms, {r['solves_per_min']:.1f} solves/min, lost {r['lost_total']}",
            file=sys.stderr,
            flush=True,
        )

    def f(v: float | None, fmt: str = "8.1f") -> str:
        return format(v, fmt) if v is not None else f"{'-':>8}"

    print(
        f"{'N':>3} {'drags':>6} {'answered':>8} {'p50 ms':>8} {'p90 ms':>8} {'p99 ms':>8} "
        f"{'fine p50 s':>10} {'solves/min':>10} {'designs/min':>11} {'lost':>5}"
    )
    for r in rows:
        lat = r["latency_ms"]
        print(
            f"{r['sessions']:>3} {r['drags']:>6} {r['answered']:>8} {f(lat['p50'])} {f(lat['p90'])} {f(lat['p99'])} "
            f"{f(r['pattern_to_fine_s']['p50'], '10.2f')} {r['solves_per_min']:10.1f} {r['designs_per_min']:11.1f} "
            f"{r['lost_total']:>5}"
        )
    out = {
        "bench": "load",
        "commit": source_commit(),
        "machine": {
            "platform": platform.platform(),
            "cpus": os.cpu_count(),
            "load_average_at_end": list(os.getloadavg()),
        },
        "design": {
            "sloper": "skirt",
            "coarse_vertices": DESIGN.resolution.coarse_vertices,
            "fine_vertices": DESIGN.resolution.fine_vertices,
        },
        "settings": {"pool": a.pool, "rounds": a.rounds, "drags": a.drags, "hz": a.hz, "solver": a.solver},
        "rows": rows,
        "nothing_lost": all(r["lost_total"] == 0 for r in rows),
    }
    print(f"wrote {write_results(a.out, 'load', out)}")
    return 0 if out["nothing_lost"] else 1


if __name__ == "__main__":
    raise SystemExit(main())

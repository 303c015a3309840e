"""End-to-end edit latency over Zenoh: ``edit`` (drag) -> ``drape/predicted``.

Starts the real nodes (remesher, a solver, sensitivity; each its own process),
drapes a skirt once, presses ``param:length`` and drags at ``--hz`` for
``--drags`` events. For each drag whose design point comes back in a
prediction, latency = receive time of that prediction - send time of the
drag, both on this machine's clock (one process sends and receives). Drags
the sensitivity node coalesced (a newer one arrived before it finished) have
no prediction of their own and are counted as ``coalesced``.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import threading
import time
import uuid

import numpy as np

from couture import supervisor
from couture.bench import add_out_arg, write_results
from couture.bus import BusConfig, free_port
from couture.client import Client
from schemas import DrapeMsg
from schemas.design import Design, Resolution, Sloper


def _wait_counter(client: Client, counter: str, timeout: float, poll: float) -> None:
    """Wait (at most ``timeout`` s) until the sensitivity node's status counts
    at least one ``counter``; the bench goes on either way."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        st = client.status.get("sensitivity")
        if st is not None and st.counters.get(counter, 0) >= 1:
            return
        time.sleep(poll)


def run(fine_vertices: int, drags: int, hz: float, solver: str = "newton", timeout: float = 300.0) -> dict:
    nodes = supervisor.default_nodes(solvers=[solver], ui=False)
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=f"e2e{uuid.uuid4().hex[:6]}", listen=[f"tcp/127.0.0.1:{free_port()}"]), nodes=nodes)
    design = Design(sloper=Sloper(kind="skirt"),
                    resolution=Resolution(coarse_vertices=min(1600, fine_vertices // 2), fine_vertices=fine_vertices))
    with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as client:
        client.wait_nodes(["remesher", f"solver-{solver}", "sensitivity"], timeout=90)
        gen = client.publish_pattern(design, name="e2e")
        t0 = time.monotonic()
        drape = client.wait_drape("fine", generation=gen, timeout=timeout, final=True)
        print(f"[e2e] {fine_vertices}: first fine drape after {time.monotonic() - t0:.1f} s "
              f"(residual {drape.residual:.2e})", file=sys.stderr)
        # the sensitivity node refactors at that drape in idle time
        _wait_counter(client, "refactors", timeout=120, poll=0.2)
        recv: dict[float, int] = {}
        lock = threading.Lock()

        def on_pred(msg: DrapeMsg) -> None:
            t = time.perf_counter_ns()
            if msg.d is not None and msg.error_estimate is None:
                with lock:
                    recv.setdefault(round(float(msg.d.numpy()[0]), 9), t)

        client.bus.subscribe("drape/predicted", on_pred, DrapeMsg)
        press = client.send_edit("param:length", [0.0, 0.0], phase="press")
        _wait_counter(client, "press_columns", timeout=60, poll=0.05)
        sent: dict[float, int] = {}
        period = 1.0 / hz
        next_t = time.perf_counter()
        for k in range(1, drags + 1):
            dk = round(1e-4 * k, 9)
            sent[dk] = time.perf_counter_ns()
            client.send_edit("param:length", [dk, 0.0], phase="drag", edit_id=press.edit_id)
            next_t += period
            time.sleep(max(0.0, next_t - time.perf_counter()))
        time.sleep(1.0)
        client.send_edit("param:length", [1e-4 * drags, 0.0], phase="release", edit_id=press.edit_id)
        with lock:
            lat = np.array([(recv[d] - t) / 1e6 for d, t in sent.items() if d in recv])
        mesh = client.latest_mesh("fine")
    return {
        "fine_vertices": int(mesh.X.shape[0]) if mesh is not None else fine_vertices,
        "drags": drags, "hz": hz, "answered": int(len(lat)), "coalesced": int(drags - len(lat)),
        "p50_ms": float(np.median(lat)) if len(lat) else None,
        "p90_ms": float(np.percentile(lat, 90)) if len(lat) else None,
        "p99_ms": float(np.percentile(lat, 99)) if len(lat) else None,
        "max_ms": float(lat.max()) if len(lat) else None,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench edit", description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1600,10000", help="fine vertex targets")
    ap.add_argument("--drags", type=int, default=180)
    ap.add_argument("--hz", type=float, default=60.0)
    add_out_arg(ap)
    a = ap.parse_args(argv)
    rows = [run(int(s), a.drags, a.hz) for s in a.sizes.split(",")]
    print(f"{'vertices':>9} {'answered':>9} {'coalesced':>9} {'p50 ms':>8} {'p90 ms':>8} {'p99 ms':>8}")
    for r in rows:
        print(f"{r['fine_vertices']:>9} {r['answered']:>9} {r['coalesced']:>9} {r['p50_ms'] or float('nan'):8.2f} "
              f"{r['p90_ms'] or float('nan'):8.2f} {r['p99_ms'] or float('nan'):8.2f}")
    big = max(rows, key=lambda r: r["fine_vertices"])
    goal = {"p50_ms": 16.0, "measured": big["p50_ms"], "met": big["p50_ms"] is not None and big["p50_ms"] <= 16.0}
    print(f"goal: edit-to-prediction p50 <= 16 ms at {big['fine_vertices']} vertices: "
          f"{big['p50_ms']} ms -> {'met' if goal['met'] else 'NOT met'}")
    out = {"bench": "edit", "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                                        "load_average_at_end": list(os.getloadavg())},
           "rows": rows, "goal": goal}
    print(f"wrote {write_results(a.out, 'edit', out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

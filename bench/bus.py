"""``couture bench bus``: latency and throughput of the bus and the recorder.

Two OS processes on loopback: this process listens and subscribes, a child
publishes 10,000-vertex drapes (x float32, ~120 KB payload).

- latency: 60 Hz for ``--seconds``; one-way publish-to-callback latency =
  receive time (after decode + validation) - the message's stamp_ns, both
  ``time.time_ns()`` on the same machine (same clock, so no round trip needed).
- throughput: publish as fast as possible (BLOCK, reliable) for 3 s;
  messages/s received and whether any was lost.
- recorder: a ``couture record`` process records 100 drapes/s for
  ``--seconds``; the MCAP must hold every message sent; MB/s written.
  Then as fast as possible, to find the recorder's ceiling.

Prints a table and writes ``bus.json`` to the results folder (``--out``, default bench/results/).
"""

from __future__ import annotations

import argparse
import os
import platform
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from bench import RESULTS_DIR, add_out_arg, child_env, module_command, write_results

N_VERTICES = 10_000


def _publisher(args: argparse.Namespace) -> None:
    """Child: publish drapes at ``rate`` Hz (0: as fast as possible) for ``seconds``."""
    from couture.bus import BusConfig, open_session
    from schemas.arrays import Array
    from schemas.messages import DrapeMsg

    x = np.random.default_rng(0).normal(size=(N_VERTICES, 3)).astype(np.float32)
    with open_session(BusConfig(session=args.session, connect=[args.connect])) as bus:
        pub = bus.publisher("drape/fine", DrapeMsg)
        if not pub.wait_matching(10.0):
            raise SystemExit("bench publisher: no subscriber")
        time.sleep(0.3)  # let every subscriber (recorder included) finish declaring
        t0 = time.perf_counter()
        n = 0
        while time.perf_counter() - t0 < args.seconds:
            if args.rate > 0:
                due = t0 + n / args.rate
                while (d := due - time.perf_counter()) > 0:
                    time.sleep(d if d > 0.002 else 0)
            pub.put(
                DrapeMsg(level="fine", x=Array.from_numpy(x), generation=1, residual=1e-4, iterations=n, solver="bench")
            )
            n += 1
        bus.zenoh.put(bus.key("bench/done"), str(n).encode())
        time.sleep(0.5)
    print(n, flush=True)


def _spawn_pub(session: str, endpoint: str, rate: float, seconds: float) -> subprocess.Popen:
    return subprocess.Popen(
        module_command(
            "bus",
            "--role",
            "pub",
            "--session",
            session,
            "--connect",
            endpoint,
            "--rate",
            str(rate),
            "--seconds",
            str(seconds),
        ),
        stdout=subprocess.PIPE,
        text=True,
        env=child_env(),
    )


def run(seconds: float = 5.0, out: Path | str | None = RESULTS_DIR) -> dict:
    """Measure; ``out``: results folder for bus.json (None: write nothing)."""
    from couture.bus import BusConfig, free_port, open_session

    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    session = f"bench{os.getpid()}"
    results: dict = {
        "machine": f"{platform.node()} ({os.cpu_count()} cpus)",
        "n_vertices": N_VERTICES,
        "latency_method": "one-way: receive time.time_ns() after decode+validate minus sender stamp_ns (same host clock)",
    }
    with open_session(BusConfig(session=session, listen=[endpoint])) as bus:
        lat: list[float] = []
        count = [0, 0.0, 0.0]  # received, first t, last t
        size = [0]
        lock = threading.Lock()
        done = threading.Event()

        def on_drape(msg) -> None:
            t = time.time_ns()
            with lock:
                lat.append((t - msg.stamp_ns) / 1e6)
                if count[0] == 0:
                    count[1] = time.perf_counter()
                count[0] += 1
                count[2] = time.perf_counter()

        bus.subscribe("drape/fine", on_drape)
        bus.subscribe_raw(bus.key("bench/done"), lambda k, d, t: done.set())

        def sub_raw_size(k, d, t):
            size[0] = len(d)

        probe = bus.subscribe_raw(bus.key("drape/fine"), sub_raw_size)

        # 1. latency at 60 Hz
        p = _spawn_pub(session, endpoint, 60, seconds)
        sent = int(p.communicate(timeout=seconds + 60)[0].split()[-1])
        done.wait(5)
        time.sleep(0.2)
        a = np.array(lat[5:])  # first few include connection warm-up
        results["latency_60hz"] = {
            "sent": sent,
            "received": count[0],
            "payload_bytes": size[0],
            "p50_ms": float(np.percentile(a, 50)),
            "p99_ms": float(np.percentile(a, 99)),
            "max_ms": float(a.max()),
        }
        probe.undeclare()

        # 2. throughput
        lat.clear()
        count[:] = [0, 0.0, 0.0]
        done.clear()
        p = _spawn_pub(session, endpoint, 0, 3.0)
        sent = int(p.communicate(timeout=60)[0].split()[-1])
        done.wait(5)
        time.sleep(0.3)
        dt = max(count[2] - count[1], 1e-9)
        results["throughput"] = {
            "sent": sent,
            "received": count[0],
            "msgs_per_s": count[0] / dt,
            "MB_per_s": count[0] * size[0] / dt / 1e6,
            "lost": sent - count[0],
        }

        # 3. recorder at 100 Hz, then flat out
        for label, rate, secs in (("recorder_100hz", 100, seconds), ("recorder_max", 0, 3.0)):
            with tempfile.TemporaryDirectory() as tmp:
                path = os.path.join(tmp, "bench.mcap")
                rec = subprocess.Popen(
                    [
                        sys.executable,
                        "-m",
                        "couture.recording",
                        path,
                        "--session",
                        session,
                        "--connect",
                        endpoint,
                        "--quiet",
                    ]
                )
                try:
                    if bus.wait_nodes(["recorder"], 15.0):
                        raise RuntimeError("recorder did not come up")
                    t0 = time.perf_counter()
                    p = _spawn_pub(session, endpoint, rate, secs)
                    sent = int(p.communicate(timeout=120)[0].split()[-1])
                    t_sent = time.perf_counter()
                    rec.send_signal(signal.SIGTERM)
                    rec.wait(60)
                    t_done = time.perf_counter()
                finally:
                    if rec.poll() is None:
                        rec.kill()
                from couture.recording import read_session

                msgs = [m for m in read_session(path, ["drape/fine"])]
                nbytes = sum(len(m.data) for m in msgs)
                span = (msgs[-1].log_time - msgs[0].log_time) / 1e9 if len(msgs) > 1 else 1e-9
                results[label] = {
                    "sent": sent,
                    "recorded": len(msgs),
                    "lost": sent - len(msgs),
                    "MB_per_s": nbytes / span / 1e6,
                    "msgs_per_s": len(msgs) / span,
                    "file_MB": os.path.getsize(path) / 1e6,
                    "publish_s": t_sent - t0,
                    "finalize_s": t_done - t_sent,
                }
    lt = results["latency_60hz"]
    results["goals"] = {
        "p50<=1ms": lt["p50_ms"] <= 1.0,
        "p99<=3ms": lt["p99_ms"] <= 3.0,
        "recorder keeps 100 drapes/s": results["recorder_100hz"]["lost"] == 0,
    }
    if out:
        write_results(out, "bus", results)
    return results


def table(r: dict) -> str:
    lt, th, r1, rm = r["latency_60hz"], r["throughput"], r["recorder_100hz"], r["recorder_max"]
    return "\n".join(
        [
            f"bus bench: {r['n_vertices']}-vertex drape, {lt['payload_bytes'] / 1e3:.0f} KB payload, {r['machine']}",
            f"{'measure':<36} {'value':>12}  goal",
            f"{'latency p50 @60 Hz (one-way)':<36} {lt['p50_ms']:>9.3f} ms  <= 1 ms",
            f"{'latency p99 @60 Hz (one-way)':<36} {lt['p99_ms']:>9.3f} ms  <= 3 ms",
            f"{'latency max @60 Hz':<36} {lt['max_ms']:>9.3f} ms",
            f"{'throughput (as fast as possible)':<36} {th['msgs_per_s']:>7.0f} msg/s  ({th['MB_per_s']:.0f} MB/s, lost {th['lost']})",
            f"{'recorder @100 Hz':<36} {r1['MB_per_s']:>7.1f} MB/s  recorded {r1['recorded']}/{r1['sent']} (lost {r1['lost']})",
            f"{'recorder flat out':<36} {rm['MB_per_s']:>7.1f} MB/s  recorded {rm['recorded']}/{rm['sent']} ({rm['msgs_per_s']:.0f} msg/s)",
            "goals: " + ", ".join(f"{k}: {'met' if v else 'MISSED'}" for k, v in r["goals"].items()),
        ]
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="couture bench bus")
    p.add_argument("--role", choices=["bench", "pub"], default="bench", help=argparse.SUPPRESS)
    p.add_argument("--session", default="bench")
    p.add_argument("--connect", default="")
    p.add_argument("--rate", type=float, default=60.0)
    p.add_argument("--seconds", type=float, default=5.0)
    add_out_arg(p)
    a = p.parse_args(argv)
    if a.role == "pub":
        _publisher(a)
        return 0
    r = run(a.seconds, a.out)
    print(table(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())

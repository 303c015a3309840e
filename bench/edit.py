"""End-to-end edit latency over Zenoh: ``edit`` (drag) -> ``drape/predicted``,
and ``pattern`` (a change) -> ``drape/coarse``, ``drape/fine`` (``--case pattern``).

Drag case (the default): starts the real nodes (remesher, a solver, sensitivity; each its own process),
drapes a skirt once, presses ``param:length`` and drags at ``--hz`` for
``--drags`` events. For each drag whose design point comes back in a
prediction, latency = receive time of that prediction - send time of the
drag, both on this machine's clock (one process sends and receives). Drags
the sensitivity node coalesced (a newer one arrived before it finished) have
no prediction of their own and are counted as ``coalesced``.

Then, on the same nodes, ``--presses`` presses of ``param:length``, each
followed at once by one drag: press -> first prediction = receive time of the
gesture's first ``drape/predicted`` - send time of the press. Every other
press emulates the path before Ψ had its own topic, when the remesher
re-sent both meshes (with Ψ inside) after computing Ψ, and the sensitivity
node decoded the fine one before its columns: the bench encodes and
publishes the remesher's latest coarse and fine meshes again on
``mesh/coarse`` and ``mesh/fine`` (the bytes the old path added per press),
waits until a second session of its own has received and decoded the fine
one (across the router, as the sensitivity node did), and only then sends
the press; its latency counts from before the meshes. The mesh cost is so
paid in series with the new path, as it was; the order differs (before Ψ,
not after), and the nodes also decode the re-sends (and drop them as
repeats) while the remesher computes Ψ.

Pattern case: starts the same nodes (the solver that ``couture up`` runs
unless ``--solver`` says otherwise), drapes the default skirt until its fine
level converges, then publishes ``--changes`` pattern changes, each the skirt
with its length option 2 cm longer or back (what a slider move sends), each
after the previous change's fine drape is final. Per change, from the bus:
seconds from publishing the pattern to the first final drape/coarse of that
generation and to its final drape/fine (converged or not, which is reported);
medians against the goals (coarse <= 2 s, converged fine <= 10 s).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import threading
import time
import uuid
from typing import Any

import msgspec
import numpy as np

from bench import add_out_arg, write_results
from couture import supervisor
from couture.bus import BusConfig, free_port
from couture.client import Client
from schemas import DrapeMsg, MeshMsg
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


def _press_latency(client: Client, probe: Client, presses: int, timeout: float = 30.0) -> dict[str, Any]:
    """Press -> first prediction [ms], alternating today's path ('new') and the
    mesh re-send per press emulated ('old_emulated'); see the module docstring."""
    first: dict[str, int] = {}
    lock = threading.Lock()

    def on_pred(msg: DrapeMsg) -> None:
        t = time.perf_counter_ns()
        with lock:
            first.setdefault(msg.edit_id, t)

    client.bus.subscribe("drape/predicted", on_pred, DrapeMsg)
    pubs = {lv: client.bus.publisher(f"mesh/{lv}", MeshMsg) for lv in ("coarse", "fine")}
    resend = {}
    for lv in pubs:
        m = client.latest_mesh(lv)
        assert m is not None, f"no mesh/{lv} seen"
        resend[lv] = m
    lat: dict[str, list[float]] = {"new": [], "old_emulated": []}
    missed: dict[str, int] = {"new": 0, "old_emulated": 0}
    for k in range(presses):
        mode = "old_emulated" if k % 2 else "new"
        time.sleep(1.0)  # the previous gesture's release settles
        t0 = time.perf_counter_ns()
        if mode == "old_emulated":
            sent_ns = time.time_ns()
            for lv in ("coarse", "fine"):
                pubs[lv].put(msgspec.structs.replace(resend[lv], seq=0, stamp_ns=0))  # stamped anew at each put
            deadline = time.monotonic() + timeout
            while not ((m := probe.latest_mesh("fine")) is not None and m.stamp_ns >= sent_ns):
                if time.monotonic() > deadline:
                    raise TimeoutError("the re-sent fine mesh never reached the probe session")
                time.sleep(0.0005)
        press = client.send_edit("param:length", [0.0, 0.0], phase="press")
        client.send_edit("param:length", [1e-3, 0.0], phase="drag", edit_id=press.edit_id)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with lock:
                t1 = first.get(press.edit_id)
            if t1 is not None:
                lat[mode].append((t1 - t0) / 1e6)
                break
            time.sleep(0.002)
        else:
            missed[mode] += 1
        client.send_edit("param:length", [0.0, 0.0], phase="release", edit_id=press.edit_id)
    mesh_bytes = sum(len(msgspec.msgpack.encode(m)) for m in resend.values())
    out: dict[str, Any] = {"mesh_bytes_per_press_old": mesh_bytes}
    for mode, v in lat.items():
        a = np.array(v)
        out[mode] = {
            "presses": len(v) + missed[mode],
            "answered": len(v),
            "p50_ms": float(np.median(a)) if len(a) else None,
            "max_ms": float(a.max()) if len(a) else None,
            "all_ms": [round(x, 2) for x in v],
        }
    return out


def run(
    fine_vertices: int, drags: int, hz: float, solver: str = "newton", timeout: float = 300.0, presses: int = 10
) -> dict:
    nodes = supervisor.default_nodes(solvers=[solver], ui=False)
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=f"e2e{uuid.uuid4().hex[:6]}", listen=[f"tcp/127.0.0.1:{free_port()}"]), nodes=nodes
    )
    design = Design(
        sloper=Sloper(kind="skirt"),
        resolution=Resolution(coarse_vertices=min(1600, fine_vertices // 2), fine_vertices=fine_vertices),
    )
    with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as client:
        client.wait_nodes(["remesher", f"solver-{solver}", "sensitivity"], timeout=90)
        gen = client.publish_pattern(design, name="e2e")
        t0 = time.monotonic()
        drape = client.wait_drape("fine", generation=gen, timeout=timeout, final=True)
        print(
            f"[e2e] {fine_vertices}: first fine drape after {time.monotonic() - t0:.1f} s "
            f"(residual {drape.residual:.2e})",
            file=sys.stderr,
        )
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
        press_ms = None
        if presses:
            with Client(bus=sup.child_bus) as probe:
                press_ms = _press_latency(client, probe, presses)
    return {
        "fine_vertices": int(mesh.X.shape[0]) if mesh is not None else fine_vertices,
        "drags": drags,
        "hz": hz,
        "answered": int(len(lat)),
        "coalesced": int(drags - len(lat)),
        "p50_ms": float(np.median(lat)) if len(lat) else None,
        "p90_ms": float(np.percentile(lat, 90)) if len(lat) else None,
        "p99_ms": float(np.percentile(lat, 99)) if len(lat) else None,
        "max_ms": float(lat.max()) if len(lat) else None,
        "press_to_first_prediction": press_ms,
    }


PATTERN_GOALS_S = {"coarse": 2.0, "fine": 10.0}
"""[s] from a pattern change to its coarse drape and to its converged fine drape"""
LENGTH_STEP_M = 0.02
"""[m] each change lengthens the skirt by this much, or takes it back"""


def run_pattern_changes(
    changes: int, solver: str = "newton", timeout: float = 300.0, fine_vertices: int | None = None
) -> dict:
    """Latency of pattern changes on the live nodes, measured from the bus (see the module docstring).

    ``fine_vertices`` overrides the default skirt's fine level (None: as
    shipped); ``timeout`` [s] bounds each wait for a final fine drape."""
    nodes = supervisor.default_nodes(solvers=[solver], ui=False)
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=f"pat{uuid.uuid4().hex[:6]}", listen=[f"tcp/127.0.0.1:{free_port()}"]), nodes=nodes
    )
    design = Design(sloper=Sloper(kind="skirt"))
    if fine_vertices is not None:
        design = msgspec.structs.replace(
            design,
            resolution=msgspec.structs.replace(
                design.resolution, fine_vertices=fine_vertices, coarse_vertices=min(1600, fine_vertices // 2)
            ),
        )
    from couture.pattern.slopers import SLOPERS

    length0 = next(o.default for o in SLOPERS["skirt"].options if o.name == "length")
    arrivals: dict[tuple[int, str], tuple[float, DrapeMsg]] = {}
    lock = threading.Lock()

    def on_drape(msg: DrapeMsg) -> None:
        t = time.perf_counter()
        if msg.final and msg.level in ("coarse", "fine"):
            with lock:  # the first final per generation and level (a later one would be a re-solve)
                arrivals.setdefault((msg.generation, msg.level), (t, msg))

    rows: list[dict[str, Any]] = []  # one JSON row per change
    with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as client:
        client.wait_nodes(["remesher", f"solver-{solver}", "sensitivity"], timeout=90)
        client.bus.subscribe("drape/*", on_drape, DrapeMsg)
        gen = client.publish_pattern(design, name="pattern-latency")
        t0 = time.perf_counter()
        first = client.follow_drape(gen, timeout=timeout)
        print(
            f"[pattern] first drape: fine final after {time.perf_counter() - t0:.1f} s, residual "
            f"{first.residual:.2e}, converged {first.converged}",
            file=sys.stderr,
            flush=True,
        )
        for k in range(1, changes + 1):
            time.sleep(1.0)  # a designer looks before the next move; the sensitivity node refactors meanwhile
            length = length0 + (LENGTH_STEP_M if k % 2 else 0.0)
            changed = msgspec.structs.replace(design, sloper=Sloper(kind="skirt", params={"length": length}))
            t_pub = time.perf_counter()
            gen = client.publish_pattern(changed, name=f"pattern-latency-{k}")
            try:
                fine = client.follow_drape(gen, timeout=timeout)
            except TimeoutError as e:
                rows.append({"change": k, "generation": gen, "length_m": length, "error": str(e)})
                continue
            with lock:  # by the number the remesher gave the design (the drape's)
                coarse = arrivals.get((fine.generation, "coarse"))
                t_fine = arrivals.get((fine.generation, "fine"), (time.perf_counter(), fine))[0]
            row = {
                "change": k,
                "generation": fine.generation,
                "length_m": length,
                "coarse_s": None if coarse is None else coarse[0] - t_pub,
                "coarse_residual": None if coarse is None else coarse[1].residual,
                "fine_s": t_fine - t_pub,
                "fine_converged": fine.converged,
                "fine_residual": fine.residual,
                "fine_iterations": fine.iterations,
                "fine_diagnosis": fine.diagnosis,
            }
            rows.append(row)
            coarse_txt = "-" if row["coarse_s"] is None else f"{row['coarse_s']:.2f}"
            print(
                f"[pattern] change {k}: coarse {coarse_txt} s, "
                f"fine {row['fine_s']:.2f} s (residual {fine.residual:.2e}, converged {fine.converged})",
                file=sys.stderr,
                flush=True,
            )
        mesh = client.latest_mesh("fine")
    ok = [r for r in rows if "error" not in r]
    coarse_t = [r["coarse_s"] for r in ok if r["coarse_s"] is not None]
    fine_t = [r["fine_s"] for r in ok if r["fine_converged"]]
    med = {
        "coarse_s": float(np.median(coarse_t)) if coarse_t else None,
        "converged_fine_s": float(np.median(fine_t)) if fine_t else None,
    }
    goal = {
        "coarse_s": PATTERN_GOALS_S["coarse"],
        "fine_s": PATTERN_GOALS_S["fine"],
        "coarse_met": med["coarse_s"] is not None and med["coarse_s"] <= PATTERN_GOALS_S["coarse"],
        # every change must converge for the fine goal to count as met
        "fine_met": (
            med["converged_fine_s"] is not None
            and len(fine_t) == len(rows)
            and med["converged_fine_s"] <= PATTERN_GOALS_S["fine"]
        ),
    }
    return {
        "solver": solver,
        "fine_vertices": int(mesh.X.shape[0]) if mesh is not None else None,
        "changes": rows,
        "median": med,
        "converged_changes": len(fine_t),
        "goal": goal,
    }


def main_pattern(a: argparse.Namespace) -> int:
    res = run_pattern_changes(a.changes, solver=a.solver or "newton", timeout=a.timeout, fine_vertices=a.fine_vertices)
    med, goal = res["median"], res["goal"]
    print(f"{'change':>6} {'coarse s':>9} {'fine s':>8} {'converged':>9} {'residual':>9}")
    for r in res["changes"]:
        if "error" in r:
            print(f"{r['change']:>6} {r['error']}")
            continue
        print(
            f"{r['change']:>6} {r['coarse_s'] if r['coarse_s'] is not None else float('nan'):9.2f} "
            f"{r['fine_s']:8.2f} {str(r['fine_converged']):>9} {r['fine_residual']:9.2e}"
        )

    def s(v: float | None) -> str:
        return "-" if v is None else f"{v:.2f}"

    print(
        f"goal: pattern change -> coarse drape <= {goal['coarse_s']:g} s (median {s(med['coarse_s'])} s): "
        f"{'met' if goal['coarse_met'] else 'NOT met'}; -> converged fine drape <= {goal['fine_s']:g} s "
        f"(median {s(med['converged_fine_s'])} s, {res['converged_changes']}/{len(res['changes'])} converged): "
        f"{'met' if goal['fine_met'] else 'NOT met'}"
    )
    out = {
        "bench": "edit_pattern",
        "machine": {
            "platform": platform.platform(),
            "cpus": os.cpu_count(),
            "load_average_at_end": list(os.getloadavg()),
        },
        **res,
    }
    print(f"wrote {write_results(a.out, 'edit_pattern', out)}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench edit", description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1600,10000", help="fine vertex targets")
    ap.add_argument("--drags", type=int, default=180)
    ap.add_argument("--hz", type=float, default=60.0)
    ap.add_argument(
        "--presses",
        type=int,
        default=10,
        help="press -> first prediction: presses, alternately today's path and the mesh re-send per press emulated",
    )
    add_out_arg(ap)
    ap.add_argument(
        "--case",
        choices=["drag", "pattern"],
        default="drag",
        help="drag: edit -> prediction latency; pattern: pattern change -> coarse and fine drape "
        "(writes edit_pattern.json in the --out folder)",
    )
    ap.add_argument("--changes", type=int, default=5, help="pattern case: number of pattern changes")
    ap.add_argument(
        "--solver",
        default=None,
        help="solver node (default: newton, as `couture up` runs)",
    )
    ap.add_argument("--timeout", type=float, default=300.0, help="[s] pattern case: wait per fine drape")
    ap.add_argument(
        "--fine-vertices",
        type=int,
        default=None,
        help="pattern case: the skirt's fine-level vertex target (default: as shipped)",
    )
    a = ap.parse_args(argv)
    if a.case == "pattern":
        return main_pattern(a)
    rows = [run(int(s), a.drags, a.hz, solver=a.solver or "newton", presses=a.presses) for s in a.sizes.split(",")]
    print(f"{'vertices':>9} {'answered':>9} {'coalesced':>9} {'p50 ms':>8} {'p90 ms':>8} {'p99 ms':>8}")
    for r in rows:
        print(
            f"{r['fine_vertices']:>9} {r['answered']:>9} {r['coalesced']:>9} {r['p50_ms'] or float('nan'):8.2f} "
            f"{r['p90_ms'] or float('nan'):8.2f} {r['p99_ms'] or float('nan'):8.2f}"
        )
    print("press -> first prediction (old: both meshes re-sent and decoded per press, emulated)")
    print(f"{'vertices':>9} {'MB/press':>9} {'new p50 ms':>11} {'old p50 ms':>11} {'new max':>8} {'old max':>8}")

    def ms(v: float | None) -> float:
        return float("nan") if v is None else v

    for r in rows:
        p = r["press_to_first_prediction"]
        if p is not None:
            new, old = p["new"], p["old_emulated"]
            print(
                f"{r['fine_vertices']:>9} {p['mesh_bytes_per_press_old'] / 1e6:9.2f} {ms(new['p50_ms']):11.1f} "
                f"{ms(old['p50_ms']):11.1f} {ms(new['max_ms']):8.1f} {ms(old['max_ms']):8.1f}"
            )
    big = max(rows, key=lambda r: r["fine_vertices"])
    goal = {"p50_ms": 16.0, "measured": big["p50_ms"], "met": big["p50_ms"] is not None and big["p50_ms"] <= 16.0}
    print(
        f"goal: edit-to-prediction p50 <= 16 ms at {big['fine_vertices']} vertices: "
        f"{big['p50_ms']} ms -> {'met' if goal['met'] else 'NOT met'}"
    )
    out = {
        "bench": "edit",
        "machine": {
            "platform": platform.platform(),
            "cpus": os.cpu_count(),
            "load_average_at_end": list(os.getloadavg()),
        },
        "rows": rows,
        "goal": goal,
    }
    print(f"wrote {write_results(a.out, 'edit', out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

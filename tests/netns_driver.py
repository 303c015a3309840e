"""The scripted client of tests/test_netns.py, run on its own "machine" (a
network namespace): ``python tests/netns_driver.py --connect ENDPOINT --session S``.

It joins the bus as a Zenoh *client* of the router it connects to, reads one
JSON command per line on stdin and answers one JSON line on stdout (errors as
``{"error": ...}``); logs go to stderr. The commands are the steps a user's
script takes: wait for nodes, publish a design and follow it to its final fine
drape, press and drag a sloper option until the sensitivity node's prediction
arrives, list the live nodes and their pids.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
import traceback

from couture.bus import BusConfig
from couture.client import Client
from schemas.design import Design, Resolution, Sloper


def skirt(length: float) -> Design:
    """The default skirt on the mannequin, a few hundred vertices."""
    return Design(
        sloper=Sloper(kind="skirt", params={"length": length}),
        resolution=Resolution(coarse_vertices=150, fine_vertices=400),
    )


def drape_summary(d) -> dict:
    x = d.x.numpy()
    return {
        "generation": d.generation,
        "solver": d.solver,
        "converged": bool(d.converged),
        "residual": float(d.residual),
        "n": int(x.shape[0]),
        "y_min": float(x[:, 1].min()),
    }


def predict(c: Client, length: float, timeout: float) -> dict:
    """Press on the skirt's length, drag until a prediction arrives, release."""
    kw = dict(param="length", dofs=["length"])
    edit = c.send_edit("param:length", [0.0, 0.0], phase="press", **kw)
    deadline = time.monotonic() + timeout
    mine: list = []
    k = 0
    while not mine and time.monotonic() < deadline:
        k += 1
        c.send_edit("param:length", [min(0.002 * k, length), 0.0], phase="drag", edit_id=edit.edit_id, **kw)
        time.sleep(0.1)
        mine = [d for d in c.drapes("predicted") if d.edit_id == edit.edit_id]
    c.send_edit("param:length", [length, 0.0], phase="release", edit_id=edit.edit_id, **kw)
    if not mine:
        raise TimeoutError(f"no prediction for press {edit.edit_id} within {timeout:g} s")
    out = drape_summary(mine[-1])
    out["method"] = mine[-1].method
    return out


def handle(c: Client, cmd: dict) -> dict:
    op = cmd["op"]
    timeout = float(cmd.get("timeout", 60.0))
    if op == "wait_nodes":
        c.wait_nodes(cmd["nodes"], timeout=timeout)
        return {"ok": True}
    if op == "live":
        return {"live": c.live_nodes(timeout=1.0)}
    if op == "pids":
        return {"pids": {name: st.pid for name, st in c.status.items()}}
    if op == "drape":  # publish and follow to the final fine drape
        asked = c.publish_pattern(skirt(float(cmd["length"])), name=f"netns-{cmd['length']}")
        return drape_summary(c.follow_drape(asked, timeout=timeout))
    if op == "publish":  # publish and wait until the remesher numbered (meshed) it
        asked = c.publish_pattern(skirt(float(cmd["length"])), name=f"netns-{cmd['length']}")
        return {"asked": asked, "generation": c.generation_of(asked, timeout=timeout)}
    if op == "follow":
        return drape_summary(c.follow_drape(int(cmd["asked"]), timeout=timeout))
    if op == "ready":
        st = c.wait_predictions_ready(timeout=timeout, generation=int(cmd["generation"]))
        return {"ready_generation": st.ready_generation}
    if op == "predict":
        return predict(c, float(cmd["length"]), timeout)
    raise ValueError(f"unknown op {op!r}")


def main() -> int:
    p = argparse.ArgumentParser(prog="netns_driver")
    p.add_argument("--connect", required=True)
    p.add_argument("--session", required=True)
    a = p.parse_args()
    logging.basicConfig(level=logging.INFO, stream=sys.stderr, format="%(asctime)s driver %(levelname)s %(message)s")
    with Client(bus=BusConfig(session=a.session, connect=[a.connect], mode="client"), name="netns-driver") as c:
        print(json.dumps({"ok": True, "hello": c.name}), flush=True)
        for line in sys.stdin:
            if not line.strip():
                continue
            try:
                out = handle(c, json.loads(line))
            except Exception as e:
                traceback.print_exc()
                out = {"error": f"{type(e).__name__}: {e}"}
            print(json.dumps(out), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

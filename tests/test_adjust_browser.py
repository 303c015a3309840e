"""The UI's adjust tool and ``couture adjust`` compute the same adjustment.

One held case: the small default skirt (200 coarse vertices), hem -10 cm.
Real nodes on a real Zenoh bus (remesher, Newton solver, adjust node with
``--vertices 200``, as tests/test_adjust_node.py starts them), the UI in a
headless chromium (tests/test_ui_browser.py's): the change typed in the
Adjust pattern folder and its button -> ``couture/adjust/v1`` -> the adjust
node -> the adjusted design published on ``pattern``, adopted by the UI, the
verdict shown in the folder. Then ``couture adjust`` on the design the UI
sent, the same edit and vertices, its solves on the same solver node.

Both report the same adjusted pattern: Hausdorff distance, mean stretch,
re-simulated patterns, verdict and the fitted design's options. Not
bitwise: every solve stops at the solver's tolerance, and the fixed point's
best iterate, a gradient step's acceptance and the fit's corrections act on
those drapes; the bounds below (0.1 % of height = 1.7 mm, stretch 0.005,
options and the achieved change 5 mm, one re-simulated pattern) are what
round-off could move without a different method, and well under what the
edit moves (the skirt's length by 10 cm).
"""

from __future__ import annotations

import json
import os
import re
import sys
import threading
import time
import uuid

import numpy as np
import pytest
from browser.chromium import ARTIFACTS, available, browser_page, wait_camera, wait_until

from schemas import AdjustMsg, AdjustStatusMsg, PatternMsg
from schemas.design import Design, Resolution, Sloper

pytestmark = [
    pytest.mark.browser,
    pytest.mark.slow,
    pytest.mark.timeout(300),
    pytest.mark.skipif(
        not available() and not os.environ.get("CI"),
        reason="needs /usr/bin/chromium + playwright (scripts/setup.sh --test installs them; never skipped in CI)",
    ),
]

VERTICES = 200
HEM_CM = -10.0
SMALL = Design(sloper=Sloper(kind="skirt"), resolution=Resolution(coarse_vertices=VERTICES, fine_vertices=300))
NODES = ["remesher", "solver-newton", "adjust"]

H_TOL_PCT = 0.1
"""[% of mannequin height] Hausdorff distances of the two runs agree within this (1.7 mm)"""
STRETCH_TOL = 0.005
OPTION_TOL = 0.005
"""[m] (the skirt's options are lengths) the two fitted designs' options agree within this"""
ACHIEVED_TOL = 0.005
"""[m] what the two fitted designs' drapes achieve agrees within this"""


class Bus:
    """What crosses the bus: adjust requests, their status, published patterns."""

    def __init__(self, client):
        self.cond = threading.Condition()
        self.requests: list[AdjustMsg] = []
        self.status: list[AdjustStatusMsg] = []
        self.patterns: list[PatternMsg] = []
        for key, into in (("adjust", self.requests), ("adjust/status", self.status), ("pattern", self.patterns)):
            client.bus.subscribe(key, self._keep(into))

    def _keep(self, into: list):
        def on(msg) -> None:
            with self.cond:
                into.append(msg)
                self.cond.notify_all()

        return on

    def wait(self, cond, timeout: float, what: str):
        with self.cond:
            if not self.cond.wait_for(cond, timeout):
                raise AssertionError(f"{what} not seen in {timeout} s: {[(s.state, s.text) for s in self.status]}")
            return cond()


def option_values(design: Design) -> dict[str, float]:
    """Every option of the design's sloper: its value, or the sloper's default where unset."""
    from couture.pattern.draft import sloper_of

    return {o.name: float(design.sloper.params.get(o.name, o.default)) for o in sloper_of(design).options}


@pytest.fixture(scope="module")
def system(tmp_path_factory):
    from couture import supervisor
    from couture.bus import BusConfig, Node, free_port
    from couture.client import Client
    from couture.ui import CoutureUI, UIConfig
    from nodes.ui.main import UIAdapter

    session = f"b{uuid.uuid4().hex[:8]}"
    nodes = [n for n in supervisor.default_nodes(solvers=["newton"], ui=False, adjust=True) if n.name != "sensitivity"]
    for n in nodes:
        if n.name == "adjust":
            n.args = [*n.args, "--vertices", str(VERTICES)]
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=session, listen=[f"tcp/127.0.0.1:{free_port()}"]), nodes=nodes
    )
    tmp = tmp_path_factory.mktemp("adjust_browser")
    ui = CoutureUI(UIConfig(port=free_port(), export_dir=tmp / "exports", show_body=False, draft_locally=False))
    with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as client:
        client.wait_nodes(NODES, timeout=90)
        bus = Bus(client)
        gen = client.publish_pattern(SMALL, name="small")
        client.wait_drape("coarse", generation=gen, timeout=120, final=True)
        ui.start()
        try:
            with Node("ui", sup.child_bus, kind="ui", install_signals=False) as node:
                adapter = UIAdapter(node, ui, "ui")
                yield {"sup": sup, "client": client, "bus": bus, "ui": ui, "adapter": adapter, "tmp": tmp}
        finally:
            ui.stop()


def test_ui_adjust_tool_and_couture_adjust_give_the_same_adjusted_pattern(system, capfd):
    from couture.adjust.pipeline import garment_mesh
    from couture.cli import main
    from couture.pattern.io import load_design, save_design

    ui, bus, adapter, tmp = system["ui"], system["bus"], system["adapter"], system["tmp"]
    sup = system["sup"]
    # the UI shows the session's design and its drape, and knows the adjust node is live
    wait_until(lambda: ui.design.sloper.kind == "skirt" and ui.view3d.x is not None, 60)
    wait_until(lambda: adapter.live.get("adjust"), 30)
    n_patterns = len(bus.patterns)
    with browser_page() as page:
        page.goto(ui.page_url)
        wait_camera(ui.server3d, page=page)
        f3 = page.frame_locator("#view3d")
        # the page has drawn its controls (a loaded machine: tens of seconds); the drape
        # they act on is the UI's own (asserted above): the page's frame marker is not
        # waited for (it stayed at 0 for 90 s in 2 of 7 runs here, cause not found)
        f3.get_by_text("Adjust pattern", exact=True).first.click(timeout=90_000)
        button = f3.get_by_role("button", name="Adjust pattern")
        button.wait_for(timeout=30_000)
        box = f3.get_by_label("change [cm]")
        box.fill(f"{HEM_CM:g}")
        box.press("Enter")
        wait_until(lambda: float(ui.adjust.amount_cm.value) == HEM_CM, 30, page)
        button.click()
        req = bus.wait(lambda: bus.requests[-1] if bus.requests else None, 30, "the UI's adjust request")
        t_req = time.monotonic()
        # the request names no settings: the node's, which are the command's
        assert (req.edit, req.amount, req.vertices, req.max_iters) == ("hem", pytest.approx(HEM_CM / 100), 0, None)
        done = bus.wait(
            lambda: next(
                (s for s in bus.status if s.request_id == req.request_id and s.state in ("done", "failed")), None
            ),
            150,
            "the adjust node's outcome",
        )
        assert done.state == "done", done.error
        ui_s = time.monotonic() - t_req
        # the verdict reached the folder, in the browser
        wait_until(lambda: "**done**, **goal" in ui.adjust.progress.content, 30, page)
        f3.get_by_text(re.compile(r"^goal (met|NOT met)$")).first.wait_for(timeout=30_000)
        assert done.goal_met is not None and (done.goal_met or done.reasons)
        assert ("goal met" if done.goal_met else "goal NOT met") in ui.adjust.progress.content
        # the adjusted design was published and the UI adopted it
        published = bus.wait(
            lambda: next((p for p in bus.patterns[n_patterns:] if p.design_id == done.design_id), None),
            30,
            "the adjusted design on `pattern`",
        )
        assert published.source == "adjust"
        wait_until(lambda: option_values(ui.design) == option_values(published.design), 30, page)
        page.screenshot(path=str(ARTIFACTS / "ui_adjust_verdict.png"))

    # the command, for the design the UI sent, the same edit and vertices, on the same solver node
    design_file = tmp / "design_sent.json"
    save_design(req.design, design_file)
    out = tmp / "cmd"
    bus_args = ["--connect", sup.child_bus.connect[0], "--session", sup.child_bus.session]
    t1 = time.monotonic()
    rc = main(
        ["adjust", str(design_file), "--hem", f"{req.amount!r}", "--out", str(out), "--vertices", str(VERTICES)]
        + ["--solver", "newton", *bus_args]
    )
    cmd_s = time.monotonic() - t1
    err = capfd.readouterr().err
    print(err[-3000:], file=sys.stderr)  # the command's report, kept in the test's output
    assert rc in (0, 3), err[-3000:]
    s = json.loads((out / "adjust.json").read_text())
    v, fit = s["verdict"], s["design_fit"]
    assert s["start"]["pattern"] == "source"  # the shipped default: the start from the source pattern
    fitted = load_design(out / "design.json")
    assert rc == (0 if v["met"] else 3)

    node_opts, cmd_opts = option_values(published.design), option_values(fitted)
    print(
        f"\nUI -> node: {ui_s:.1f} s from the request to done, H {done.hausdorff_pct:.3f} %, S {done.stretch:.4f}, {done.solves} solves, "
        f"met {done.goal_met}, achieved {100 * done.achieved_m:+.2f} cm, options {done.options}"
        f"\ncommand:    {cmd_s:.1f} s in all, H {v['hausdorff_pct']:.3f} %, S {v['stretch']:.4f}, {v['solves']} solves, "
        f"met {v['met']}, achieved {100 * fit['achieved_m']:+.2f} cm, options "
        f"{ {k: b for k, (_, b) in fit['options'].items()} }"
    )
    assert s["vertices"] == garment_mesh(req.design, VERTICES).n_vertices  # the node's mesh, the same size asked
    assert abs(done.hausdorff_pct - v["hausdorff_pct"]) <= H_TOL_PCT
    assert abs(done.stretch - v["stretch"]) <= STRETCH_TOL
    assert abs(done.solves - v["solves"]) <= 1  # a gradient trial more or less, at most
    if min(abs(h - 1.0) for h in (done.hausdorff_pct, v["hausdorff_pct"])) > H_TOL_PCT:
        assert done.goal_met == v["met"]  # away from the goal's edge, the same verdict
    assert abs(done.achieved_m - fit["achieved_m"]) <= ACHIEVED_TOL
    diff = {k: node_opts[k] - cmd_opts[k] for k in node_opts}
    assert max(abs(d) for d in diff.values()) <= OPTION_TOL, diff
    # the shortening is in both, and in the same option
    assert node_opts["length"] < option_values(req.design)["length"] - 0.05
    assert np.isfinite([done.hausdorff_pct, done.stretch]).all()

"""The adjust node in a running system (real processes on a real Zenoh bus):
an ``adjust`` request shortens the hem of the design on screen, the adjusted
design crosses the bus as a new ``pattern`` and its drape's hem rises toward
the target; malformed and impossible requests get clear errors, publish
nothing, and every node keeps running."""

from __future__ import annotations

import threading
import time
import uuid

import msgspec
import numpy as np
import pytest

from couture import supervisor
from couture.bus import BusConfig, free_port
from couture.client import Client
from schemas import AdjustMsg, AdjustStatusMsg, PatternMsg
from schemas.design import Design, Resolution, Sloper

pytestmark = [pytest.mark.timeout(180), pytest.mark.slow]

SMALL = Design(sloper=Sloper(kind="skirt"), resolution=Resolution(coarse_vertices=200, fine_vertices=300))
NODES = ["remesher", "solver-newton", "adjust"]


class Listener:
    """The adjust node's status messages and every published pattern, as they arrive."""

    def __init__(self, client: Client):
        self.cond = threading.Condition()
        self.status: list[AdjustStatusMsg] = []
        self.patterns: list[PatternMsg] = []
        client.bus.subscribe("adjust/status", self._status)
        client.bus.subscribe("pattern", self._pattern)

    def _status(self, msg: AdjustStatusMsg) -> None:
        with self.cond:
            self.status.append(msg)
            self.cond.notify_all()

    def _pattern(self, msg: PatternMsg) -> None:
        with self.cond:
            self.patterns.append(msg)
            self.cond.notify_all()

    def final(self, request_id: str, timeout: float) -> AdjustStatusMsg:
        with self.cond:
            ok = self.cond.wait_for(
                lambda: any(s.request_id == request_id and s.state in ("done", "failed") for s in self.status),
                timeout,
            )
            assert ok, f"no outcome for {request_id} in {timeout} s: {[(s.state, s.text) for s in self.status]}"
            return next(s for s in self.status if s.request_id == request_id and s.state in ("done", "failed"))


@pytest.fixture(scope="module")
def system():
    session = f"a{uuid.uuid4().hex[:8]}"
    nodes = [n for n in supervisor.default_nodes(solvers=["newton"], ui=False, adjust=True) if n.name != "sensitivity"]
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=session, listen=[f"tcp/127.0.0.1:{free_port()}"]), nodes=nodes
    )
    with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as client:
        client.wait_nodes(NODES, timeout=60)
        listen = Listener(client)
        gen = client.publish_pattern(SMALL, name="small")
        drape = client.wait_drape("coarse", generation=gen, timeout=90, final=True)
        yield sup, client, listen, gen, drape


def _coarse_drape_of(client: Client, design_id: str, timeout: float):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        mesh = client.latest_mesh("coarse")
        if mesh is not None and mesh.design_id == design_id:
            final = [d for d in client.drapes("coarse") if d.generation == mesh.generation and d.final]
            if final:
                return mesh, final[-1]
        time.sleep(0.1)
    raise AssertionError(f"no final coarse drape of the adjusted design {design_id} in {timeout} s")


def test_malformed_and_impossible_requests_get_clear_errors_and_nothing_stops(system):
    sup, client, listen, gen, _ = system
    pids = sup.pids()
    key = client.bus.key("adjust")
    # malformed: a field of the wrong type, a version this node does not know, not even a map
    raw = {"schema": "couture/adjust/v1", "version": 1, "edit": "hem", "amount": "short", "request_id": "m1"}
    bad = [
        (msgspec.msgpack.encode(raw), ("couture/adjust/v1", "$.amount")),
        (msgspec.msgpack.encode({**raw, "schema": "couture/adjust/v9", "amount": -0.1}), ("couture/adjust/v9",)),
        (b"\x93not an adjust request", ("Expected `object`, got `array`",)),
    ]
    for payload, words in bad:
        client.bus.zenoh.put(key, payload)
        deadline = time.monotonic() + 15
        err = ""
        while time.monotonic() < deadline and not all(w in err for w in words):
            st = client.status.get("adjust")
            err = st.last_error if st is not None else ""
            time.sleep(0.05)
        assert err.startswith("bad message on") and all(w in err for w in words), (words, err)
    # well formed but impossible: shortening by 0.5 m leaves nothing of a 0.6 m skirt
    n_patterns = len(listen.patterns)
    rid = uuid.uuid4().hex[:8]
    client.bus.publisher("adjust", AdjustMsg).put(
        AdjustMsg(request_id=rid, edit="hem", amount=-0.5, design=SMALL, vertices=200, max_iters=1, generation=gen)
    )
    out = listen.final(rid, timeout=60)
    assert out.state == "failed" and "shortening by 0.500 m leaves nothing" in out.error, out.error
    assert "design is unchanged" in out.text
    time.sleep(0.5)
    assert len(listen.patterns) == n_patterns  # nothing published: the current design stays
    client.wait_nodes(NODES, timeout=5)
    assert sup.pids() == pids  # no node restarted


def test_hem_request_over_the_bus_moves_the_drapes_hem_toward_the_target(system):
    _, client, listen, gen, drape = system
    x_src = drape.x.numpy()
    hem_src = float(x_src[:, 1].min())
    rid = uuid.uuid4().hex[:8]
    t0 = time.monotonic()
    client.bus.publisher("adjust", AdjustMsg).put(
        AdjustMsg(request_id=rid, edit="hem", amount=-0.15, design=SMALL, vertices=200, max_iters=1, generation=gen)
    )
    out = listen.final(rid, timeout=120)
    assert out.state == "done", out.error
    steps = [s for s in listen.status if s.request_id == rid]
    # progress crossed the bus as it happened: started, each re-simulated pattern, done
    assert steps[0].state == "running"
    assert [s.iteration for s in steps if s.state == "iteration"] == [0, 1]
    assert out.options["length"] < 0.6 - 0.05  # the skirt got shorter in its own option
    assert out.fit_rms_m < 0.03
    # the node measured the published design's own drape: most of the 15 cm
    assert -0.2 < out.achieved_m < -0.08, out.achieved_m
    # the pattern and the done status travel on two topics: the pattern may land second
    deadline = time.monotonic() + 15
    while not (published := [p for p in listen.patterns if p.design_id == out.design_id]):
        assert time.monotonic() < deadline, "the adjusted design was never published"
        time.sleep(0.05)
    assert published[0].source == "adjust"
    assert published[0].design.resolution == SMALL.resolution  # the design on screen, not the adjustment's mesh
    mesh, adj = _coarse_drape_of(client, out.design_id, timeout=60)
    x_adj = adj.x.numpy()
    assert adj.converged and np.isfinite(x_adj).all()
    rise = float(x_adj[:, 1].min()) - hem_src
    # the target's hem is 0.15 m above the source's: the re-drape's hem rose most of the way
    assert 0.08 < rise < 0.2, rise
    # and the waist stayed about where it was (the garment was cut, not pulled up): it
    # moves much less than the hem. How much it settles is the friction equilibrium's,
    # which round-off picks (issue 27): 2.09 cm on one machine where 2 cm was the bound
    waist = abs(float(x_adj[:, 1].max()) - float(x_src[:, 1].max()))
    assert waist < 0.25 * rise, (waist, rise)
    print(f"adjust request to re-draped hem: {time.monotonic() - t0:.1f} s, hem rise {rise:.3f} m")


def test_ui_adjust_folder_request_shows_progress_adopts_the_adjusted_design_and_undoes(system, tmp_path):
    """The ui node's adapter (a real CoutureUI on the same bus): the Adjust
    pattern folder's request runs on the adjust node, its progress reaches
    the folder, the adjusted design becomes the UI's design, and undo
    publishes the design before it."""
    from couture.bus import Node
    from couture.ui import CoutureUI, UIConfig
    from nodes.ui.main import UIAdapter

    sup, client, listen, _, _ = system
    ui = CoutureUI(UIConfig(port=free_port(), export_dir=tmp_path, show_body=False, draft_locally=False))
    ui.start()
    try:
        with Node("ui", sup.child_bus, kind="ui", install_signals=False) as node:
            UIAdapter(node, ui, "ui")
            # the session's newest design (the history of `pattern`) is adopted
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and not (ui.design.sloper.params and ui.view3d.x is not None):
                time.sleep(0.1)
            before = ui.design
            length0 = before.sloper.params.get("length", 0.6)
            assert ui.view3d.x is not None, "no drape reached the ui"
            panel = ui.adjust
            panel.loop.value = "hem"
            panel.amount_cm.value = -5.0
            deadline = time.monotonic() + 10  # the adapter has seen the adjust node's liveliness
            while time.monotonic() < deadline and not node.bus.live_nodes(0.2).count("adjust"):
                time.sleep(0.1)
            assert panel.request() == ("hem", -0.05), panel.progress.content
            seen: set[str] = set()
            deadline = time.monotonic() + 90
            while time.monotonic() < deadline and "**done**" not in panel.progress.content:
                seen.add(panel.progress.content.split(":")[0])
                assert "failed" not in panel.progress.content, panel.progress.content
                time.sleep(0.05)
            assert "**done**" in panel.progress.content, panel.progress.content
            assert "iteration 1" in seen or "iteration 0" in seen, seen  # progress per iteration reached the folder
            # the adjusted design (published by the adjust node) became the UI's design
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and ui.design.sloper.params.get("length", 0.6) > length0 - 0.02:
                time.sleep(0.1)
            assert ui.design.sloper.params["length"] < length0 - 0.02
            assert not panel.undo.disabled
            n = len(listen.patterns)
            assert panel.undo_last() is before and ui.design is before
            with listen.cond:
                assert listen.cond.wait_for(
                    lambda: any(p.source == "ui" and p.design == before for p in listen.patterns[n:]), 10
                )
    finally:
        ui.stop()

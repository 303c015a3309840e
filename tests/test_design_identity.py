"""Design identity: the remesher numbers a session's designs, every message
is judged against that number, and a publisher learns its design's number
from the meshes that name it.

Bus-free first (the pieces each node adapter calls), then real processes
(remesher and a newton solver node over Zenoh, body-free designs of a few
hundred vertices, each level's solve capped at 0.5 s: identity, not physics,
is under test): two clients one after the other each get their own drape, a
`couture drape --connect` killed mid-session and run again writes its own
design's drape, a rejected design does not reject the next client's, and a
hostile publisher's numbers (patterns, a drape, edits) are rejected, logged
and counted while a normal design still gets its own drape.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import msgspec
import numpy as np
import pytest

from couture.client import Client, PatternRejected
from couture.designs import GENERATION_LIMIT, OwnDesigns, ShownDesign, judge
from couture.mesh import grid_sheet
from couture.solvers.service import IncomingMesh, SolveService
from schemas.convert import mesh_to_msg
from schemas.design import Design, Resolution, SceneFlags, Sloper
from schemas.messages import DrapeMsg, EditMsg, PatternMsg, PsiMsg, RejectedMsg

# -- bus-free ---------------------------------------------------------------------


def skirt(length: float = 0.6, fine: int = 240, coarse: int = 120) -> Design:
    """A body-free skirt (no body to build, a few hundred vertices)."""
    return Design(
        sloper=Sloper(kind="skirt", params={"length": length}),
        resolution=Resolution(coarse_vertices=coarse, fine_vertices=fine),
        scene=SceneFlags(body=False, friction=False),
    )


def test_judge_names_stale_and_foreign():
    assert judge(5, 5) == "current"
    assert judge(4, 5) == "stale"
    assert judge(6, 5) == "foreign" and judge(2**62, 5) == "foreign"
    assert judge(0, -1) == "foreign"  # nothing held yet: every number is foreign


def test_remesher_edits_must_be_made_on_its_current_design():
    from couture.remesh.service import RemeshService

    s = RemeshService()
    assert s.judge_edit(0) == "foreign"  # no design yet
    s.set_design(skirt(), s.next_generation(1), "a")
    s.set_design(skirt(0.62), s.next_generation(2), "b")
    assert (s.judge_edit(2), s.judge_edit(1), s.judge_edit(1000)) == ("current", "stale", "foreign")


def test_solver_judges_edits_against_the_newest_design_it_matched():
    s = SolveService(method="newton")
    sheet = grid_sheet(0.2, 0.2, 3, 3)
    assert s.judge_edit(1) == "foreign"
    s.offer_design(1, skirt(), "a")  # the publisher asked for 1 ...
    out = s.offer_mesh("fine", 4, 1, IncomingMesh(sheet), "a")  # ... the remesher gave 4
    assert out.matched is not None and s.generation == 4
    assert (s.judge_edit(4), s.judge_edit(1), s.judge_edit(5)) == ("current", "stale", "foreign")


def test_own_designs_keep_the_first_number_given():
    own = OwnDesigns()
    own.add("mine", 3)
    assert own.design_of(3) == "mine" and own.given(3) is None
    assert own.meshed("mine", 7) and own.given(3) == 7
    assert own.meshed("mine", 7)  # the same mesh again (Ψ re-send): still ours
    assert not own.meshed("mine", 9) and own.given(3) == 7  # re-sent or forged under our id: not ours


def test_shown_design_learns_numbers_and_adopts_only_numbered_newer_designs():
    v = ShownDesign()
    assert v.request() == 1
    v.committed("ui-1")
    assert v.shown_generation is None and v.edit_generation() == 0  # not numbered yet
    assert v.meshed("ui-1", 3) == (True, None)  # the remesher gave 3: the UI's edits carry 3
    assert v.shown_generation == 3 and v.edit_generation() == 3 and v.request() == 4
    # another publisher's design: shown once numbered (a rejected one never is) ...
    assert v.pattern("script", skirt(0.5)) is None
    assert v.pattern("rejected", skirt(5.0)) is None
    accepted, adopt = v.meshed("script", 5)
    assert accepted and adopt is not None and adopt.sloper.params["length"] == 0.5
    assert v.shown_id == "script" and v.edit_generation() == 5
    # ... and only when newer than what is shown
    v.pattern("late", skirt(0.55))
    assert v.meshed("late", 4) == (True, None) and v.shown_id == "script"
    # an own commit after another publisher's pattern arrived wins over it
    v.pattern("older", skirt(0.57))
    v.request()
    v.committed("ui-2")
    assert v.meshed("older", 6) == (True, None) and v.shown_id == "ui-2"
    # a mesh numbered past what any remesher gives is foreign: it moves nothing
    assert v.meshed("rogue", GENERATION_LIMIT) == (False, None) and v.top == 6


def small_mesh_msg(generation: int, design_id: str, n: int = 3):
    m = grid_sheet(0.1, 0.1, n, n)
    m.level, m.generation = "fine", generation
    return mesh_to_msg(m, generation=generation, mesh_generation=generation, design_id=design_id)


def drape_msg(generation: int, n: int, *, final: bool = True) -> DrapeMsg:
    return DrapeMsg(level="fine", x=np.zeros((n, 3)), generation=generation, final=final, solver="s", method="m")


def test_client_follows_exactly_its_own_design_whatever_number_it_asked_for():
    """Bus-free (messages fed to the callbacks as the bus would): the client
    asked for 2; an older design's drape numbered 2 is not its own, a drape
    that comes before the mesh naming its design is kept until it does."""
    client = Client(name="t")
    client._own.add("mine", 2)
    client._on_mesh(small_mesh_msg(2, "someone-else"))
    client._on_drape(drape_msg(2, 9))  # the other design's drape, under the number asked for
    got: list[DrapeMsg] = []

    def feed() -> None:
        time.sleep(0.2)
        client._on_drape(drape_msg(3, 16, final=False))  # ours, before its mesh
        client._on_drape(drape_msg(3, 16))
        time.sleep(0.2)
        client._on_mesh(small_mesh_msg(3, "mine", n=4))

    threading.Thread(target=feed, daemon=True).start()
    d = client.follow_drape(2, timeout=10, on_drape=got.append)
    assert d.generation == 3 and d.x.shape[0] == 16 and [m.final for m in got] == [False, True]
    assert client.generation_of(2, timeout=0) == 3 and client.mesh_of(3).design_id == "mine"
    assert client.wait_drape("fine", generation=2, timeout=1).generation == 3


def test_client_takes_no_other_design_s_rejection_for_its_own():
    client = Client(name="t")
    client._own.add("mine", 4)
    reason = "param:length: value 5 m is outside [0.38, 1] m"
    # another client's design asked for 4 too and was rejected
    client._on_rejected(RejectedMsg(node="remesher", generation=4, design_id="theirs", reason=reason))
    assert client.rejection(4) is None
    client._on_rejected(
        RejectedMsg(node="remesher", generation=4, design_id="mine", element="param:length", reason=reason)
    )
    rej = client.rejection(4)
    assert isinstance(rej, PatternRejected) and rej.reason == reason and rej.design_id == "mine"
    assert "(design mine)" in str(rej)

    # numbered after all (a forged re-send under our id was what the remesher rejected)
    other = Client(name="t2")
    other._own.add("ours", 4)
    other._on_rejected(RejectedMsg(node="remesher", generation=4, design_id="ours", reason=reason))
    other._on_mesh(small_mesh_msg(5, "ours"))
    assert other.rejection(4) is None
    # a solver's rejection of the mesh the remesher numbered for our design is ours
    other._on_rejected(
        RejectedMsg(node="solver-newton", generation=5, design_id="ours", element="fabric.area_density", reason="y")
    )
    rej = other.rejection(4)
    assert rej is not None and rej.node == "solver-newton" and rej.generation == 5


# -- real processes -----------------------------------------------------------------

ROOT = Path(__file__).resolve().parents[1]
A = skirt(0.50, fine=240, coarse=120)
B = skirt(0.55, fine=400, coarse=160)


def wait_for(fn, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if v := fn():
            return v
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def counters(client: Client, node: str) -> dict[str, int]:
    st = client.status.get(node)
    return dict(st.counters) if st is not None else {}


@pytest.fixture(scope="module")
def session():
    from couture import supervisor
    from couture.bus import BusConfig, free_port

    nodes = [n for n in supervisor.default_nodes(solvers=["newton"], ui=False) if n.name != "sensitivity"]
    for n in nodes:
        if n.module == "nodes.solver":
            n.args += ["--max-seconds", "0.5"]
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=f"id{uuid.uuid4().hex[:8]}", listen=[f"tcp/127.0.0.1:{free_port()}"]), nodes=nodes
    )
    with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as tap:
        tap.wait_nodes(["remesher", "solver-newton"], timeout=90)
        yield sup, tap


def own_drape(client: Client, design: Design, name: str) -> tuple[DrapeMsg, int, str]:
    """Publish, follow to the final fine drape; (drape, vertices of the design's own mesh, design_id)."""
    asked = client.publish_pattern(design, name=name)
    d = client.follow_drape(asked, timeout=90)
    mesh = client.mesh_of(d.generation)
    assert mesh is not None and mesh.design_id == client.design_id_of(asked)
    assert d.generation == client.generation_of(asked, timeout=0) and d.mesh_generation == mesh.mesh_generation
    assert d.x.shape[0] == mesh.X.shape[0]
    return d, mesh.X.shape[0], mesh.design_id


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_clients_one_after_the_other_each_get_their_own_drape(session, tmp_path):
    sup, tap = session
    with Client(bus=sup.child_bus) as a:
        da, na, ida = own_drape(a, A, "a")
    # a rejected design first: the next client, asking for the same number, is not told its design was rejected
    with Client(bus=sup.child_bus) as bad:
        asked = bad.publish_pattern(msgspec.structs.replace(A, sloper=Sloper(kind="skirt", params={"length": 5.0})))
        with pytest.raises(PatternRejected, match="length"):
            bad.follow_drape(asked, timeout=30)
    with Client(bus=sup.child_bus) as b:
        db, nb, idb = own_drape(b, B, "b")
    assert db.generation > da.generation and idb != ida
    assert (na, nb) == (da.x.shape[0], db.x.shape[0]) and na != nb  # each its own design's mesh

    # `couture drape --connect`, killed while its design is under way, then run again on another design
    def cli(design: Design, out: Path) -> subprocess.Popen:
        p = out.with_suffix(".json")
        p.write_text(msgspec.json.encode(design).decode())
        args = [sys.executable, "-m", "couture.cli", "drape", str(p), "--out", str(out), "--timeout", "90"]
        args += ["--session", sup.child_bus.session, *[f"--connect={e}" for e in sup.child_bus.connect]]
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        return subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)

    top = tap.current_generation
    first = cli(A, tmp_path / "first")
    wait_for(lambda: tap.current_generation > top or first.poll() is not None, 60, "the first run's design meshed")
    first.send_signal(signal.SIGKILL)
    first.wait()
    second = cli(B, tmp_path / "second")
    out, err = second.communicate(timeout=120)
    assert second.returncode in (0, 3), err[-3000:]  # converged or capped: a drape either way
    meta = json.loads((tmp_path / "second" / "drape.json").read_text())
    mesh = wait_for(lambda: tap.mesh_of(meta["generation"]), 5, "the second run's mesh on the tap")
    assert meta["generation"] > top + 1 and meta["design_id"] == mesh.design_id
    vertices = sum(1 for line in (tmp_path / "second" / "drape.obj").open() if line.startswith("v "))
    assert vertices == mesh.X.shape[0] != na  # design B's mesh, not the killed run's design A
    assert msgspec.json.decode((tmp_path / "second" / "pattern.json").read_bytes(), type=Design) == B


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_hostile_numbers_are_rejected_and_counted_and_designs_still_get_their_drapes(session):
    sup, tap = session
    before = counters(tap, "remesher")
    with Client(bus=sup.child_bus) as rogue:
        top = tap.current_generation  # (the tap has seen every mesh; a fresh client may not have yet)
        pat = rogue.bus.publisher("pattern", PatternMsg)
        pat.wait_matching(5.0)
        for g in (1000, 2**62):
            pat.put(PatternMsg(design=A, generation=g, design_id=f"hostile-{g}", source="rogue"))
            # numbered as the next design, whatever it asked for
            m = wait_for(lambda t=top + 1: tap.mesh_of(t), 60, f"the design that asked for {g} meshed")
            assert m.design_id == f"hostile-{g}"
            top += 1
        drape_pub = rogue.bus.publisher("drape/fine", DrapeMsg)
        drape_pub.wait_matching(5.0)
        drape_pub.put(DrapeMsg(level="fine", x=np.zeros((3, 3)), generation=2**62, solver="rogue", final=True))
    with Client(bus=sup.child_bus) as c:
        d, n, _ = own_drape(c, B, "after-the-rogue")
        assert d.generation == top + 1
        # edits on another design than the current one: no Ψ, no abort, counted by remesher and solver
        edit = c.bus.publisher("edit", EditMsg)
        edit.wait_matching(5.0)
        psis: list[PsiMsg] = []
        c.bus.subscribe("psi/*", psis.append, PsiMsg)
        for g in (d.generation - 1, 2**62):
            edit.put(EditMsg(edit_id=f"e{g}", phase="press", element="param:length", generation=g))
        st = wait_for(
            lambda: (
                (k := counters(c, "remesher")).get("stale_edits", 0) >= 1
                and k.get("foreign_edits", 0) >= 1
                and k.get("foreign_generations", 0) >= before.get("foreign_generations", 0) + 3
                and k
            ),
            15,
            "the remesher's counts of the rejected numbers",
        )
        assert st.get("renumbered_patterns", 0) >= before.get("renumbered_patterns", 0) + 2
        solver = wait_for(
            lambda: (k := counters(c, "solver-newton")).get("stale_edits", 0) >= 1 and k.get("foreign_edits") and k,
            15,
            "the solver's counts of the rejected presses",
        )
        assert solver["foreign_edits"] >= 1
        assert not [m for m in psis if m.edit_id in (f"e{d.generation - 1}", f"e{2**62}")]
        # and the session goes on: the next design gets its own drape too
        d2, n2, _ = own_drape(c, A, "after-the-edits")
        assert d2.generation == d.generation + 1 and n2 != n

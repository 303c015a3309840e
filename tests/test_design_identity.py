"""Design identity across processes: the remesher numbers designs, so two
clients one after the other, a client restarted mid-session and a hostile
generation number never make a client take another design's mesh or drape
(remesher node only: meshes carry the identity the drapes then copy)."""

from __future__ import annotations

import time
import uuid

import pytest

from couture import supervisor
from couture.bus import BusConfig, free_port
from couture.client import Client
from schemas.design import Design, Resolution, SceneFlags, Sloper
from schemas.messages import PatternMsg

pytestmark = [pytest.mark.timeout(180), pytest.mark.slow]


def skirt(length: float) -> Design:
    return Design(
        sloper=Sloper(kind="skirt", params={"length": length}),
        resolution=Resolution(coarse_vertices=120, fine_vertices=240),
        scene=SceneFlags(body=False, friction=False),
    )


def given_mesh(client: Client, requested: int, timeout: float = 60.0) -> int:
    """The generation the remesher gave the client's design, checked on the mesh it holds."""
    gen = client.generation_of(requested, timeout)
    deadline = time.monotonic() + 5
    while (m := client.latest_mesh("fine")) is None or m.generation < gen:
        assert time.monotonic() < deadline
        time.sleep(0.05)
    return gen


def test_two_clients_a_restarted_client_and_a_hostile_generation():
    session = f"id{uuid.uuid4().hex[:8]}"
    nodes = [n for n in supervisor.default_nodes(solvers=["newton"], ui=False) if n.name == "remesher"]
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=session, listen=[f"tcp/127.0.0.1:{free_port()}"]), nodes=nodes
    )
    with supervisor.Supervisor(cfg) as sup:
        with Client(bus=sup.child_bus) as a:
            a.wait_nodes(["remesher"], timeout=60)
            ga = given_mesh(a, a.publish_pattern(skirt(0.50), name="a"))
        # a second client after the first (or the first one restarted): it may
        # ask for a number already used; the remesher gives it a new one
        with Client(bus=sup.child_bus) as b:
            b.wait_nodes(["remesher"], timeout=30)
            gb = given_mesh(b, b.publish_pattern(skirt(0.55), name="b"))
            assert gb > ga
            # the same client restarted mid-session: its counter starts from scratch
            b._seen_generation = 0
            gb2 = given_mesh(b, b.publish_pattern(skirt(0.56), name="b-again"))
            assert gb2 > gb
        # a hostile number: taken once, it does not make later designs vanish
        with Client(bus=sup.child_bus) as h:
            h.wait_nodes(["remesher"], timeout=30)
            pub = h.bus.publisher("pattern", PatternMsg)
            pub.wait_matching(5.0)
            pub.put(PatternMsg(design=skirt(0.60), generation=1000, design_id="hostile", source="hostile"))
            deadline = time.monotonic() + 60
            while (m := h.latest_mesh("fine")) is None or m.design_id != "hostile":
                assert time.monotonic() < deadline, "the remesher never meshed the hostile design"
                time.sleep(0.05)
            assert m.generation == 1000
        with Client(bus=sup.child_bus) as c:
            c.wait_nodes(["remesher"], timeout=30)
            requested = c.publish_pattern(skirt(0.65), name="c")
            gc = given_mesh(c, requested)
            assert gc == 1001
            m = c.latest_mesh("fine")
            assert m.generation == gc and m.design_id
            # every renumbering is counted in the remesher's status
            deadline = time.monotonic() + 5
            while (st := c.status.get("remesher")) is None or st.counters.get("renumbered_patterns", 0) < 1:
                assert time.monotonic() < deadline, st
                time.sleep(0.1)

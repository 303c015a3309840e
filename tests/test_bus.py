"""The bus over real Zenoh sessions on loopback: typed pub/sub between two
processes, bad messages dropped and counted, liveliness, solve request/reply
mirrored as messages, clean SIGTERM."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import threading
import time
import uuid

import numpy as np
import pytest
import zenoh

from couture.bus import BusConfig, Node, free_port, open_session
from schemas import DrapeMsg, EditMsg, SolveRequestMsg, SolveResultMsg, StatusMsg

pytestmark = pytest.mark.timeout(60)

ECHO_NODE = textwrap.dedent("""
    import sys, numpy as np
    from couture.bus import BusConfig, Node
    from schemas import DrapeMsg, EditMsg
    session, endpoint = sys.argv[1], sys.argv[2]
    with Node("echo", BusConfig(session=session, connect=[endpoint]), status_period_s=0.2) as node:
        pub = node.bus.publisher("drape/fine", DrapeMsg)
        def on_edit(msg):
            if msg.element == "boom":
                raise RuntimeError("callback failure on purpose")
            d = msg.d.numpy()
            pub.put(DrapeMsg(level="fine", generation=msg.generation, x=np.tile([d[0], d[1], 0.0], (3, 1)),
                             solver="echo", edit_id=msg.edit_id))
        node.bus.subscribe("edit", on_edit)
        node.run()
    print("closed cleanly", flush=True)
""")


class Collector:
    def __init__(self) -> None:
        self.items: list = []
        self.cond = threading.Condition()

    def __call__(self, *args) -> None:
        with self.cond:
            self.items.append(args[0] if len(args) == 1 else args)
            self.cond.notify_all()

    def wait(self, pred, timeout: float = 10.0):
        deadline = time.monotonic() + timeout
        with self.cond:
            while True:
                hits = [i for i in self.items if pred(i)]
                if hits:
                    return hits[-1]
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"nothing matched; got {self.items[-5:]}")
                self.cond.wait(left)


@pytest.fixture
def session_name() -> str:
    return f"t{uuid.uuid4().hex[:10]}"


def test_two_processes_typed_messages_bad_message_and_sigterm(session_name):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with open_session(BusConfig(session=session_name, listen=[endpoint])) as bus:
        drapes, statuses, presence = Collector(), Collector(), Collector()
        bus.subscribe("drape/fine", drapes)
        bus.subscribe("status/echo", statuses)
        bus.watch_nodes(presence)
        child = subprocess.Popen(
            [sys.executable, "-c", ECHO_NODE, session_name, endpoint],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            presence.wait(lambda e: e == ("echo", True))
            assert "echo" in bus.live_nodes()
            edits = bus.publisher("edit", EditMsg)
            assert edits.wait_matching(10)
            edits.put(EditMsg(edit_id="g1", element="curve1", d=np.array([0.01, -0.02]), generation=5))
            got = drapes.wait(lambda m: m.edit_id == "g1")
            assert isinstance(got, DrapeMsg) and got.generation == 5 and got.seq >= 1 and got.stamp_ns > 0
            np.testing.assert_allclose(got.x.numpy()[2], [0.01, -0.02, 0.0])

            # malformed payloads on a subscribed key, and a callback that raises: logged, counted, dropped
            bus.zenoh.put(bus.key("edit"), b"\x93\x01\x02")  # msgpack array, not a message
            bus.zenoh.put(bus.key("edit"), b"not msgpack \xc1\xff")
            edits.put(EditMsg(edit_id="boom", element="boom", d=np.zeros(2)))
            st = statuses.wait(
                lambda s: s.counters.get("bad_messages", 0) >= 2 and s.counters.get("callback_errors", 0) >= 1
            )
            assert isinstance(st, StatusMsg) and st.pid == child.pid and st.node == "echo"
            assert "boom" in st.last_error or "callback" in st.last_error

            # still running after all that
            edits.put(EditMsg(edit_id="g2", element="curve1", d=np.array([0.5, 0.5]), generation=6))
            assert drapes.wait(lambda m: m.edit_id == "g2").generation == 6

            child.send_signal(signal.SIGTERM)
            out, err = child.communicate(timeout=10)
            assert child.returncode == 0, err
            assert "closed cleanly" in out
            assert "dropped bad message on couture/" in err and f"{session_name}/edit" in err
            presence.wait(lambda e: e == ("echo", False))
            assert "echo" not in bus.live_nodes()
        finally:
            if child.poll() is None:
                child.kill()


def test_solve_request_reply_is_mirrored_as_messages(session_name):
    port = free_port()
    server_cfg = BusConfig(session=session_name, listen=[f"tcp/127.0.0.1:{port}"])
    client_cfg = BusConfig(session=session_name, connect=[f"tcp/127.0.0.1:{port}"])
    with open_session(server_cfg) as server, open_session(client_cfg) as client, open_session(client_cfg) as spy:
        seen = Collector()
        spy.subscribe("solve/**", seen, with_topic=True)

        def handler(req: SolveRequestMsg) -> SolveResultMsg:
            if req.tol < 0:
                raise ValueError("negative tolerance")
            return SolveResultMsg(x=req.x_warm.numpy() + 1.0, residual=1e-6, converged=True, method="fake")

        server.serve_solve("fake", handler)
        time.sleep(0.3)
        res = client.solve(SolveRequestMsg(x_warm=np.zeros((2, 3)), tol=1e-5), solver="fake", timeout=10)
        assert res.solver == "fake" and res.converged and res.request_id
        np.testing.assert_allclose(res.x.numpy(), 1.0)
        req_seen = seen.wait(lambda t: t[0] == "solve/request")
        res_seen = seen.wait(lambda t: t[0] == "solve/result/fake")
        assert req_seen[1].request_id == res.request_id == res_seen[1].request_id

        bad = client.solve(SolveRequestMsg(x_warm=np.zeros((2, 3)), tol=-1.0), timeout=10)  # '' = any solver
        assert "negative tolerance" in bad.error and bad.x is None
        with pytest.raises(TimeoutError, match="no solver answered on .*solve/newton"):
            client.solve(SolveRequestMsg(), solver="newton", timeout=1.0)
        assert server.stats.snapshot().get("callback_errors") == 1


def test_callback_exception_does_not_stop_delivery_and_qos(session_name):
    port = free_port()
    with (
        open_session(BusConfig(session=session_name, listen=[f"tcp/127.0.0.1:{port}"])) as a,
        open_session(BusConfig(session=session_name, connect=[f"tcp/127.0.0.1:{port}"])) as b,
    ):
        got = Collector()

        def flaky(msg):
            got(msg)
            if msg.generation == 1:
                raise RuntimeError("first one fails")

        b.subscribe("drape/*", flaky)
        pred = a.publisher("drape/predicted", DrapeMsg)
        fine = a.publisher("drape/fine", DrapeMsg)
        assert pred._pub.congestion_control == zenoh.CongestionControl.DROP
        assert fine._pub.congestion_control == zenoh.CongestionControl.BLOCK
        assert a.publisher("edit", EditMsg)._pub.congestion_control == zenoh.CongestionControl.BLOCK
        assert fine.wait_matching(10)
        fine.put(DrapeMsg(x=np.zeros((1, 3)), generation=1))
        fine.put(DrapeMsg(x=np.zeros((1, 3)), generation=2))
        got.wait(lambda m: m.generation == 2)
        assert b.stats.snapshot()["callback_errors"] == 1
        with pytest.raises(TypeError):
            fine.put(EditMsg())  # type: ignore[arg-type]


def test_node_in_process_publishes_status_and_token(session_name):
    port = free_port()
    with open_session(BusConfig(session=session_name, listen=[f"tcp/127.0.0.1:{port}"])) as obs:
        statuses = Collector()
        obs.subscribe("status/*", statuses)
        node = Node(
            "n1",
            BusConfig(session=session_name, connect=[f"tcp/127.0.0.1:{port}"]),
            kind="test",
            status_period_s=0.1,
            install_signals=False,
        )
        with node:
            node.count("widgets", 3)
            st = statuses.wait(lambda s: s.counters.get("widgets") == 3)
            assert st.kind == "test" and st.state == "running"
            assert obs.wait_nodes(["n1"], 5) == []
            threading.Timer(0.2, node.stop).start()
            t = time.monotonic()
            node.run()
            assert time.monotonic() - t < 5
        statuses.wait(lambda s: s.state == "stopping")
        assert obs.live_nodes(timeout=0.5) == []


def test_client_waits_for_exactly_its_own_design(session_name):
    """A drape of someone else's design under the number this client asks for
    is not taken: the client waits for the generation the remesher gave its
    design (a fake remesher that numbers it 7)."""
    from couture.client import Client
    from couture.mesh import grid_sheet
    from schemas import Design, MeshMsg, PatternMsg
    from schemas.convert import mesh_to_msg

    port = free_port()
    with open_session(BusConfig(session=session_name, listen=[f"tcp/127.0.0.1:{port}"])) as bus:
        drape_pub = bus.publisher("drape/fine", DrapeMsg)
        mesh_pub = bus.publisher("mesh/fine", MeshMsg)
        tiny = grid_sheet(0.1, 0.1, 2, 2)

        def answer(p: PatternMsg) -> None:
            mesh_pub.put(mesh_to_msg(tiny, generation=7, design_id=p.design_id))
            drape_pub.put(DrapeMsg(level="fine", generation=7, x=np.zeros((3, 3)), solver="mine", converged=True))

        bus.subscribe("pattern", answer, PatternMsg)
        with Client(session=session_name, connect=[f"tcp/127.0.0.1:{port}"]) as c:
            drape_pub.wait_matching(5.0)
            drape_pub.put(DrapeMsg(level="fine", generation=1, x=np.zeros((3, 3)), solver="foreign", converged=True))
            deadline = time.monotonic() + 5
            while not c.drapes("fine"):
                assert time.monotonic() < deadline
                time.sleep(0.02)
            g = c.publish_pattern(Design())
            assert g == 1  # the number the foreign drape carries
            d = c.wait_drape("fine", generation=g, timeout=10)
            assert d.solver == "mine" and d.generation == 7 and c.generation_of(g, timeout=1) == 7


def test_client_pattern_drape_and_solve(session_name):
    from couture.client import Client
    from couture.mesh import grid_sheet
    from schemas import Design, MeshMsg, PatternMsg
    from schemas.convert import mesh_to_msg

    port = free_port()
    with open_session(BusConfig(session=session_name, listen=[f"tcp/127.0.0.1:{port}"])) as solver_bus:
        # a fake remesher + solver: a mesh naming the design (with the generation
        # the remesher gives), then its drape
        drape_pub = solver_bus.publisher("drape/fine", DrapeMsg)
        mesh_pub = solver_bus.publisher("mesh/fine", MeshMsg)
        tiny = grid_sheet(0.1, 0.1, 2, 2)

        def answer(p: PatternMsg) -> None:
            mesh_pub.put(mesh_to_msg(tiny, generation=p.generation, design_id=p.design_id))
            drape_pub.put(
                DrapeMsg(level="fine", generation=p.generation, x=np.zeros((3, 3)), solver="fake", converged=True)
            )

        solver_bus.subscribe("pattern", answer, PatternMsg)
        solver_bus.serve_solve("fake", lambda req: SolveResultMsg(x=req.mesh.x0.numpy() * 2, converged=True))
        with Client(session=session_name, connect=[f"tcp/127.0.0.1:{port}"]) as c:
            g1 = c.publish_pattern(Design())
            g2 = c.publish_pattern(Design())
            assert (g1, g2) == (1, 2)
            d = c.wait_drape("fine", generation=g2, timeout=10)
            assert d.generation == 2 and d.solver == "fake"
            with pytest.raises(TimeoutError, match="no drape/predicted .* live nodes"):
                c.wait_drape("predicted", timeout=0.3)
            mesh = grid_sheet(0.2, 0.2, 3, 3)
            res = c.solve(mesh, solver="fake", timeout=10)
            np.testing.assert_allclose(res.x.numpy(), mesh.x0 * 2)
            assert c.name in c.live_nodes()

"""Faults as tests, on the real process tree (`couture up`'s supervisor with
remesher, a newton solver, sensitivity, the ui node and the recorder, each its
own process, on a small skirt):

* a flood of malformed payloads on every topic of the table: random bytes,
  msgpack of the wrong shape, another message type, an unknown schema
  version, payloads above the topic's size limit (hypothesis, derandomized),
  edits on a stale design, and garbage solve queries. No node crashes (no
  restart, same pids, no callback error), every receiver counts what it
  dropped in its status (``bad/<topic>``; the recorder records it apart and
  counts it ``rejected``), and a valid design drapes afterwards.
* kill -9 of each node in the middle of a drag: the ui keeps its last drape
  on screen and lists the node dead while it is down (its status says what
  it shows and which nodes it sees), the supervisor restarts it, and the
  session resumes (a new drag is predicted, a new design drapes, the new ui
  shows it, the new recorder records).

Sizes are cut by ``$COUTURE_MAX_MESSAGE_BYTES`` (1 MiB for every topic) so
an oversized payload is cheap to send; the limits themselves come from the
topic table as shipped. Every wait is on bus state, never a fixed sleep.
"""

from __future__ import annotations

import os
import signal
import time
import uuid
from collections import Counter
from typing import Any, Callable

import msgspec
import numpy as np
import psutil
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from msg_examples import minimal

from couture import supervisor
from couture.bus import BusConfig, free_port, open_session
from couture.client import Client
from schemas import topics
from schemas.design import Design, Resolution, Sloper
from schemas.messages import MESSAGE_TYPES, DrapeMsg, EditMsg, Message, StatusMsg, encode

pytestmark = [pytest.mark.timeout(300), pytest.mark.slow]

SMALL = Design(sloper=Sloper(kind="skirt"), resolution=Resolution(coarse_vertices=120, fine_vertices=300))
CAP_BYTES = 1 << 20
NODES = ["remesher", "solver-newton", "sensitivity", "ui", "recorder"]
RESTART_DELAY_S = 3.0
"""the supervisor's first backoff: a killed node stays down at least this long"""
RECOVERY: dict[str, dict[str, float]] = {}
"""node -> seconds from the kill to each recovery step (printed, never asserted)"""


def _ui_port() -> int:
    from couture.bus.ports import port_is_free

    for _ in range(50):
        p = free_port()
        if p < 65000 and port_is_free(p + 1) and port_is_free(p + 2):
            return p
    raise RuntimeError("no three consecutive free ports")


def wait_for(what: str, cond: Callable[[], Any], timeout: float) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = cond()
        if v:
            return v
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("faults")
    design_file = tmp / "small.json"
    design_file.write_bytes(msgspec.json.encode(SMALL))
    port = _ui_port()
    nodes = supervisor.default_nodes(solvers=["newton"], ui=True, ui_port=port, record=str(tmp / "faults.mcap"))
    for n in nodes:
        if n.name == "ui":
            n.args += ["--design", str(design_file), "--export-dir", str(tmp / "x"), "--record-dir", str(tmp / "r")]
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=f"f{uuid.uuid4().hex[:8]}", listen=[f"tcp/127.0.0.1:{free_port()}"]),
        nodes=nodes,
        backoff_initial_s=RESTART_DELAY_S,
        child_log=str(tmp / "nodes.log"),
    )
    old_cap = os.environ.get(topics.MAX_BYTES_ENV)
    os.environ[topics.MAX_BYTES_ENV] = str(CAP_BYTES)  # the children (and their restarts) inherit it
    try:
        with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as client:
            client.wait_nodes(NODES, timeout=120)
            for length in (0.6, 0.55):  # two designs: the first one's generation is stale
                d = msgspec.structs.replace(SMALL, sloper=Sloper(kind="skirt", params={"length": length}))
                gen = client.publish_pattern(d, name="faults")
                client.wait_drape("fine", generation=gen, final=True, timeout=150)
            client.wait_predictions_ready(90, generation=gen)
            yield {"sup": sup, "client": client, "tmp": tmp}
            if RECOVERY:
                print("\nrecovery after kill -9 [s from the kill]:")
                for node, steps in RECOVERY.items():
                    print(f"  {node:<14} " + ", ".join(f"{k} {v:.1f}" for k, v in steps.items()))
    finally:
        if old_cap is None:
            os.environ.pop(topics.MAX_BYTES_ENV, None)
        else:
            os.environ[topics.MAX_BYTES_ENV] = old_cap


def counters(client: Client) -> dict[str, Counter]:
    return {n: Counter(st.counters) for n, st in client.status.items() if n in NODES}


def fresh_status(client: Client, node: str, after_ns: int, timeout: float = 30.0) -> StatusMsg:
    """A status of ``node`` sent after ``after_ns``."""
    return wait_for(
        f"a status of {node}",
        lambda: (s := client.status.get(node)) is not None and s.stamp_ns > after_ns and s,
        timeout,
    )


# -- the flood ------------------------------------------------------------------


def concrete(key: str) -> str:
    """A publishable key of a table row ('status/*' -> 'status/fuzz')."""
    return key.replace("*", "fuzz")


def templates(client: Client) -> dict[str, Message]:
    """One valid message of every table row's type: the live session's own mesh
    and drape, the schema's minimal message (msg_examples.minimal) of every
    other registered type."""
    mesh = client.latest_mesh("fine")
    drape = client.wait_drape("fine", final=True, timeout=5)
    assert mesh is not None
    live: dict[type, Message] = {type(mesh): mesh, DrapeMsg: drape}
    by_type = {cls: live.get(cls) or minimal(cls) for cls in MESSAGE_TYPES}
    return {t.key: by_type[t.msg_type] for t in topics.TOPICS}


def as_dict(msg: Message) -> dict:
    return msgspec.msgpack.decode(encode(msg))


msgpack_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**63), 2**64 - 1)
    | st.floats()
    | st.text(max_size=20)
    | st.binary(max_size=20),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=8), inner, max_size=5),
    max_leaves=20,
)

GARBAGE = st.one_of(
    st.tuples(st.just("random bytes"), st.binary(max_size=300)),
    st.tuples(st.just("msgpack of another shape"), msgpack_values),
    st.tuples(
        st.just("header of the type, bad fields"), st.dictionaries(st.text(max_size=8), msgpack_values, max_size=4)
    ),
    st.tuples(st.just("unknown version"), st.integers(2, 2**31)),
    st.tuples(st.just("another message type"), st.sampled_from([t.key for t in topics.TOPICS])),
    st.tuples(st.just("oversized"), st.integers(1, 4096)),
)


def garbage_payload(kind: str, arg: Any, key: str, tmpl: dict[str, Message]) -> bytes:
    """One payload that every receiver on ``key`` must drop."""
    base = tmpl[key]
    if kind == "random bytes":
        return bytes(arg)
    if kind == "msgpack of another shape":
        return msgspec.msgpack.encode(arg)
    if kind == "header of the type, bad fields":
        # the topic's own schema name, a field of the wrong type (never a valid message by chance)
        return msgspec.msgpack.encode({**arg, "schema": base.TYPE, "version": 1, "seq": "not a number"})
    if kind == "unknown version":
        d = as_dict(base)
        name = base.TYPE.rsplit("/v", 1)[0]
        return msgspec.msgpack.encode({**d, "schema": f"{name}/v{arg}", "version": arg})
    if kind == "another message type":
        other = tmpl[arg]
        if other.TYPE == base.TYPE:  # the same type is not garbage: take the next row's
            other = next(m for m in tmpl.values() if m.TYPE != base.TYPE)
        return encode(other)
    if kind == "oversized":
        # a valid message padded just past the limit (an unknown field msgspec would skip): only the size is wrong
        d = as_dict(base)
        limit = topics.max_bytes_for(concrete(key))
        data = msgspec.msgpack.encode({**d, "pad": b""})
        return msgspec.msgpack.encode({**d, "pad": b"\0" * (limit - len(data) + arg + 8)})
    raise ValueError(kind)


BAD_QUERIES = (b"", b"\xc1", msgspec.msgpack.encode({"schema": "couture/solve_request/v7", "version": 7}))


def test_flood_of_garbage_on_every_topic_crashes_nothing(live):
    sup, client = live["sup"], live["client"]
    pids0 = sup.pids()
    assert set(pids0) == set(NODES)
    restarts0 = {n: c.restarts for n, c in sup.children.items()}
    t0 = time.time_ns()
    before = {n: fresh_status(client, n, t0) for n in NODES}
    c0 = {n: Counter(s.counters) for n, s in before.items()}
    tmpl = templates(client)
    keys = [t.key for t in topics.TOPICS]
    sent: Counter = Counter()
    kinds: Counter = Counter()
    current = client.current_generation
    assert current >= 2  # generation 1 is stale

    with open_session(sup.child_bus, name="fuzzer") as bus:
        # the fuzzer blocks rather than drops (previews travel DROP): every payload arrives and is counted
        pubs = {k: bus.publisher(concrete(k), topics.topic_spec(concrete(k)).msg_type, drop=False) for k in keys}  # type: ignore[union-attr]
        for k, p in pubs.items():
            assert p.wait_matching(10), f"nobody subscribes {k} (the recorder should)"

        @settings(
            max_examples=30,
            derandomize=True,
            deadline=None,
            database=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
        )
        @given(GARBAGE)
        def flood(case: tuple[str, Any]) -> None:
            kind, arg = case
            kinds[kind] += 1
            for k in keys:
                pubs[k].put_raw(garbage_payload(kind, arg, k, tmpl))
                sent[k] += 1

        flood()
        # edits on a stale design: valid messages, refused (no Ψ, no prediction, the solve goes on)
        stale = 0
        for i in range(5):
            eid = f"stale{i}"
            for phase in ("press", "drag", "release"):
                pubs["edit"].put(
                    EditMsg(edit_id=eid, phase=phase, element="param:length", d=np.array([0.01 * i, 0.0]), generation=1)
                )
            stale += 1
        # garbage solve queries: each answered with an error naming the problem
        for payload in BAD_QUERIES:
            replies = list(bus.zenoh.get(bus.key("solve/solver-newton"), payload=payload, timeout=10))
            assert replies and all(r.err is not None for r in replies), "a garbage solve query was not refused"
            why = replies[0].err.payload.to_bytes().decode()
            assert "schema" in why or "solve_request" in why, why
        total = sum(sent.values())
        assert set(kinds) == {
            "random bytes",
            "msgpack of another shape",
            "header of the type, bad fields",
            "unknown version",
            "another message type",
            "oversized",
        }
        print(
            f"\nflood: {total} garbage payloads on {len(keys)} topics ({dict(kinds)} examples), {stale} stale gestures"
        )

        # the recorder sees every key: it records each payload apart and counts it
        def recorded_all() -> StatusMsg | None:
            s = client.status.get("recorder")
            return s if s is not None and s.counters.get("rejected", 0) - c0["recorder"]["rejected"] >= total else None

        rec = wait_for(f"the recorder to count {total} rejected", recorded_all, 60)
        assert rec.counters["rejected"] - c0["recorder"]["rejected"] == total  # none lost, none twice
        # every other receiver counts exactly what it dropped, per topic
        after = {n: fresh_status(client, n, time.time_ns()) for n in NODES}
        for node in ("remesher", "solver-newton", "sensitivity", "ui"):
            c1 = Counter(after[node].counters)

            def delta(name: str, node: str = node, c1: Counter = c1) -> int:
                return c1[name] - c0[node][name]

            for k in keys:
                got = delta(f"bad/{k}")
                assert got in (0, sent[k]), f"{node} counted {got} bad payloads on {k}, {sent[k]} were sent"
            queries = delta(f"bad/solve/{node}")  # the solve queryable's
            assert queries == (len(BAD_QUERIES) if node == "solver-newton" else 0)
            assert delta("bad_messages") == sum(delta(f"bad/{k}") for k in keys) + queries
            assert delta("callback_errors") == 0, (node, after[node].last_error)
        ui = Counter(after["ui"].counters)
        # every topic but the solve mirrors, which only the recorder hears, the try-on
        # ops and adjust requests, which the ui sends and the solver / adjust node hears,
        # and Ψ, which the sensitivity node alone takes
        for k in [k for k in keys if not k.startswith(("solve/", "psi/")) and k not in ("tryon", "adjust")]:
            assert ui[f"bad/{k}"] - c0["ui"][f"bad/{k}"] == sent[k], k  # the ui listens to all of these
        for node in ("remesher", "solver-newton"):  # both judge every press
            assert after[node].counters.get("stale_edits", 0) - c0[node]["stale_edits"] == stale, node

    # nothing crashed: same processes, no restart
    assert sup.pids() == pids0
    assert {n: c.restarts for n, c in sup.children.items()} == restarts0
    assert all(psutil.pid_exists(p) for p in pids0.values())
    # and the session still works: a new design drapes
    gen = client.publish_pattern(
        msgspec.structs.replace(SMALL, sloper=Sloper(kind="skirt", params={"length": 0.52})), name="after-flood"
    )
    drape = client.wait_drape("fine", generation=gen, final=True, timeout=150)
    assert np.isfinite(drape.x.numpy()).all()


# -- kill -9 mid-drag -------------------------------------------------------------


def predicted(client: Client, edit_id: str, d0: float | None = None) -> DrapeMsg | None:
    for m in reversed(client.drapes("predicted")):
        if m.edit_id == edit_id and (d0 is None or (m.d is not None and abs(float(m.d.numpy()[0]) - d0) < 1e-12)):
            return m
    return None


def drag(client: Client, timeout: float = 60.0) -> tuple[EditMsg, float]:
    """Press and drag ``param:length`` until a prediction of this gesture arrives; (press, last d)."""
    client.wait_predictions_ready(timeout, generation=client.current_generation)
    press = client.send_edit("param:length", [0.0, 0.0], phase="press")
    d = 0.0
    deadline = time.monotonic() + timeout
    while predicted(client, press.edit_id) is None:
        assert time.monotonic() < deadline, "no prediction for the drag"
        d += 1e-3
        client.send_edit("param:length", [d, 0.0], phase="drag", edit_id=press.edit_id)
        time.sleep(0.1)
    return press, d


def test_a_release_resumes_the_solve_its_press_cut_off(live):
    """A press holds the solver (no solve runs mid-drag); a design that arrives
    during the drag waits, and the release starts its solve even though the
    gesture brings no newer design (it ended where it began). Before, the
    solve never ran and the screen kept a stale drape until the next design."""
    client = live["client"]
    solver = "solver-newton"
    t0 = time.time_ns()
    before = fresh_status(client, solver, t0).counters
    client.wait_predictions_ready(60, generation=client.current_generation)
    press = client.send_edit("param:length", [0.0, 0.0], phase="press")
    wait_for(
        "the solver to see the press",
        lambda: (s := client.status.get(solver)) and s.counters.get("presses", 0) > before.get("presses", 0),
        30,
    )
    d = msgspec.structs.replace(SMALL, sloper=Sloper(kind="skirt", params={"length": 0.57}))
    gen = client.publish_pattern(d, name="faults")
    wait_for(
        "the solver to take both meshes of the new design",
        lambda: (
            (s := client.status.get(solver)) and s.counters.get("meshes_taken", 0) >= before.get("meshes_taken", 0) + 2
        ),
        60,
    )
    assert not any(m.final and m.generation == gen for m in client.drapes("fine")), "solved mid-drag"
    client.send_edit("param:length", [0.0, 0.0], phase="release", edit_id=press.edit_id)
    fine = client.wait_drape("fine", generation=gen, final=True, timeout=90)
    assert fine.converged, fine.diagnosis


def test_a_refused_tryon_op_is_answered_and_changes_nothing(live):
    """A try-on op the solver cannot apply (a panel the garment does not have)
    gets a ``rejected`` answer naming the op and the problem at once, instead
    of a drape the sender would wait for in vain; the design stays accepted,
    the ui shows why in its Try-on folder, and a valid op afterwards drapes."""
    from couture.client import TryOnRejected

    sup, client = live["sup"], live["client"]
    pids0 = sup.pids()
    gen = client.current_generation
    t0 = time.monotonic()
    bad = client.send_tryon("move", "no_such_panel", vector=[0.0, 0.0, 0.01])
    with pytest.raises(TryOnRejected, match="no_such_panel") as err:
        client.wait_tryon(bad.op_id, timeout=60)
    print(f"\nrefused try-on answered in {time.monotonic() - t0:.2f} s: {err.value}")
    assert err.value.op_id == bad.op_id and err.value.node == "solver-newton"
    assert client.rejection(gen) is None  # the design itself is not rejected
    mesh = client.mesh_of(gen)
    assert mesh is not None and mesh.panel_names
    ok = client.send_tryon("fix", mesh.panel_names[0])
    d = client.wait_tryon(ok.op_id, timeout=120)
    assert d.final and d.generation == gen
    client.send_tryon("unfix", mesh.panel_names[0])
    assert sup.pids() == pids0


@pytest.mark.parametrize("node", NODES)
def test_kill_9_mid_drag(live, node):
    sup, client = live["sup"], live["client"]
    press, d = drag(client)
    shown = fresh_status(client, "ui", time.time_ns()).shown
    assert "solve by" in shown or "prediction" in shown, shown  # a drape is on screen
    restarts0 = sup.children[node].restarts
    old = sup.pids()[node]

    t_kill = time.monotonic()
    killed_ns = time.time_ns()
    os.kill(old, signal.SIGKILL)
    steps = RECOVERY.setdefault(node, {})

    # mid-drag: the gesture goes on while the node is down
    d += 1e-3
    client.send_edit("param:length", [d, 0.0], phase="drag", edit_id=press.edit_id)
    if node == "solver-newton":  # a dead solver does not stop the previews
        wait_for("a prediction while the solver is down", lambda: predicted(client, press.edit_id, d), 30)
        steps["prediction while down"] = time.monotonic() - t_kill
    if node != "ui":
        # the ui lists the node dead and keeps the last drape on screen
        def dead() -> StatusMsg | None:
            s = client.status.get("ui")
            return s if s is not None and s.stamp_ns > killed_ns and s.nodes.get(node) is False else None

        s = wait_for(f"the ui to list {node} dead", dead, 30)
        steps["ui lists it dead"] = time.monotonic() - t_kill
        assert "solve by" in s.shown or "prediction" in s.shown, s.shown
        assert sup.children[node].restarts == restarts0, "restarted before the ui saw it dead (backoff too short?)"

    # the supervisor restarts it
    new = wait_for(f"{node} restarted", lambda: (p := sup.pids().get(node)) not in (None, old) and p, 60)
    client.wait_nodes([node], timeout=60)
    steps["live again"] = time.monotonic() - t_kill
    assert sup.children[node].restarts == restarts0 + 1
    client.send_edit("param:length", [d, 0.0], phase="release", edit_id=press.edit_id)
    if node != "ui":
        wait_for(
            f"the ui to list {node} alive",
            lambda: (s := client.status.get("ui")) is not None and s.stamp_ns > killed_ns and s.nodes.get(node) is True,
            30,
        )

    # it resumes: the released design drapes and is shown (the ui publishes the
    # design on release; a solver drapes no mesh that came during a drag), then
    # the next gesture is predicted
    length = 0.5 + 0.01 * NODES.index(node)
    gen = client.publish_pattern(
        msgspec.structs.replace(SMALL, sloper=Sloper(kind="skirt", params={"length": length})), name=f"after-{node}"
    )
    fine = client.wait_drape("fine", generation=gen, final=True, timeout=150)
    steps["next fine drape"] = time.monotonic() - t_kill
    wait_for(
        "the ui to show the new design's drape",
        lambda: (s := client.status.get("ui")) is not None and f"generation {fine.generation}" in s.shown,
        60,
    )
    press2, _ = drag(client, timeout=90)
    steps["next prediction"] = time.monotonic() - t_kill
    client.send_edit("param:length", [0.0, 0.0], phase="release", edit_id=press2.edit_id)
    status = fresh_status(client, node, time.time_ns(), timeout=30)
    assert status.pid == new and status.counters.get("callback_errors", 0) == 0, status.last_error
    if node == "recorder":  # the new recorder writes the next part of the same recording
        wait_for("the new recorder to record", lambda: client.status["recorder"].counters.get("recorded", 0) > 0, 30)
        assert (live["tmp"] / "faults.1.mcap").exists()
    assert {n for n, c in sup.children.items() if c.restarts} <= set(RECOVERY)  # no other node crashed

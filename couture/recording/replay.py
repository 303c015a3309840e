"""Replay recorded inputs onto a live bus: by default the topics the table in
schemas.topics marks as replayed (``pattern`` and ``edit``).

Payloads go out byte for byte (same generation, seq and stamps as recorded),
re-keyed into the target session. ``rate`` = 1 keeps the original timing,
R scales it (2: twice as fast), 0 sends as fast as possible; delivery is
reliable with BLOCK congestion control, so nothing is lost at any rate.
Before the first message, replay waits (up to ``wait_timeout_s``) for the
named nodes' liveliness and for a subscriber on every replayed key.

``path`` is a recording file (read with its numbered parts, see
couture.recording.parts) or a list of files, read in the order given.
Payloads the recorder set apart as rejected are never sent, and neither is a
payload that fails the same check now (a recording made before the recorder
checked): each skipped one is counted and the first named in the log.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from dataclasses import dataclass, field

from couture.bus import BusConfig, StopFlag, open_session
from couture.recording.mcapio import check_payload, read_session
from couture.recording.parts import describe, resolve
from schemas import topics as topic_table
from schemas.messages import DrapeMsg, MeshMsg, Message, PatternMsg, RejectedMsg, decode

log = logging.getLogger("couture.replay")


@dataclass
class ReplayConfig:
    path: str | list[str]
    """a recording (with its numbered parts) or several files"""
    bus: BusConfig = field(default_factory=BusConfig)
    topics: list[str] = field(default_factory=topic_table.replayed_topics)
    """relative topics to re-publish; default: the inputs of the topic table"""
    rate: float = 1.0
    loop: bool = False
    wait_nodes: list[str] = field(default_factory=list)
    """node names whose liveliness must be up before sending"""
    wait_timeout_s: float = 10.0
    require_subscribers: bool = True
    """fail (instead of warn) when nobody subscribes to a replayed key in time"""
    linger_s: float = 0.2
    """keep the session open this long after the last message so it drains"""
    lockstep: bool = False
    """after each pattern message, wait for the final drape/fine of its design
    (the generation the remesher gave it, from the mesh naming its identity),
    or a node's rejection of that design, before sending anything else: the
    outputs then do not depend on how fast the machine is (no solve is cut
    short by the next input)"""
    lockstep_timeout_s: float = 300.0
    """[s] to wait for each drape/fine in lockstep mode"""
    parts: bool = True
    """read each file's numbered continuations too (False: exactly the files given)"""


def main(config: ReplayConfig, stop: StopFlag | None = None) -> int:
    """Replay; returns the number of messages sent."""
    files = resolve(config.path, parts=config.parts)
    msgs, skipped = [], 0
    for m in read_session(files, config.topics, parts=False):
        reason = check_payload(m.topic, m.data)
        if reason:
            if not skipped:
                log.warning("replay: not sending an invalid payload on %s from %s: %s", m.topic, m.path, reason)
            skipped += 1
            continue
        msgs.append(m)
    where = describe(files)
    if skipped:
        print(f"[replay] {where}: {skipped} invalid payloads skipped (never sent)", file=sys.stderr)
    if not msgs:
        raise ValueError(f"{where}: no messages on topics {config.topics}")
    stop = stop or StopFlag()
    sent = 0
    with open_session(config.bus, name="replay") as bus:
        pubs = {}
        for m in msgs:
            if m.topic not in pubs:
                cls = topic_table.type_for_topic(m.topic)
                pubs[m.topic] = bus.publisher(m.topic, cls or Message)
        if config.wait_nodes:
            missing = bus.wait_nodes(config.wait_nodes, config.wait_timeout_s)
            if missing:
                raise TimeoutError(
                    f"replay: nodes {missing} not live on session {config.bus.session} after {config.wait_timeout_s:g} s"
                )
        deadline = time.monotonic() + config.wait_timeout_s
        for pub in pubs.values():
            if not pub.wait_matching(max(0.0, deadline - time.monotonic())):
                text = f"replay: no subscriber on {pub.key} after {config.wait_timeout_s:g} s"
                if config.require_subscribers:
                    raise TimeoutError(text)
                log.warning(text)
        # lockstep: each pattern's design is numbered by the remesher (its meshes
        # echo the design's identity with the number), then waited for by that number;
        # a node's rejection of the design (by its identity) is its answer instead
        given: dict[str, int] = {}
        done: set[int] = set()
        rejected: set[str] = set()
        cv = threading.Condition()
        if config.lockstep:

            def on_mesh(msg: MeshMsg) -> None:
                if msg.level == "fine" and msg.design_id:
                    with cv:
                        given[msg.design_id] = msg.generation
                        cv.notify_all()

            def on_drape(msg: DrapeMsg) -> None:
                if msg.final:
                    with cv:
                        done.add(msg.generation)
                        cv.notify_all()

            def on_rejected(msg: RejectedMsg) -> None:
                if msg.op_id:
                    return  # a refused try-on op, not a design
                with cv:
                    rejected.add(msg.design_id)
                    cv.notify_all()

            bus.subscribe("mesh/fine", on_mesh, MeshMsg)
            bus.subscribe("drape/fine", on_drape, DrapeMsg)
            bus.subscribe("rejected", on_rejected, RejectedMsg, history=False)

        def wait_outputs(pattern: PatternMsg) -> None:
            deadline = time.monotonic() + config.lockstep_timeout_s
            key = pattern.identity()
            with cv:
                while given.get(key) not in done and not stop.is_set():
                    if key in rejected:
                        log.warning(
                            "replay --lockstep: design %s (asked for generation %d) was rejected; going on",
                            key,
                            pattern.generation,
                        )
                        return
                    left = deadline - time.monotonic()
                    if left <= 0:
                        g = given.get(key)
                        raise TimeoutError(
                            f"replay --lockstep: no final drape/fine for design {key} (asked for generation "
                            f"{pattern.generation}, "
                            + ("no mesh of it: the remesher never numbered it" if g is None else f"numbered {g}")
                            + f") within {config.lockstep_timeout_s:g} s"
                        )
                    cv.wait(min(left, 0.1))

        while True:
            t_rec0 = msgs[0].log_time
            t_wall0 = time.monotonic()
            for m in msgs:
                if stop.is_set():
                    return sent
                if config.rate > 0:
                    due = t_wall0 + (m.log_time - t_rec0) / 1e9 / config.rate
                    delay = due - time.monotonic()
                    if delay > 0:
                        stop.wait(delay)
                pattern = decode(m.data, PatternMsg) if config.lockstep and m.topic == "pattern" else None
                if pattern is not None:
                    with cv:  # the number it gets now (a looped replay re-sends a design)
                        given.pop(pattern.identity(), None)
                        rejected.discard(pattern.identity())
                pubs[m.topic].put_raw(m.data)
                sent += 1
                if pattern is not None:
                    wait_outputs(pattern)
            if not config.loop or stop.is_set():
                break
        time.sleep(config.linger_s)
    print(f"[replay] sent {sent} messages from {where}", file=sys.stderr)
    return sent

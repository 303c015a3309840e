"""The recorder node: every message on a recorded topic into an MCAP file.

It subscribes to ``couture/<session>/**`` (so any probe on the session sees
it) and writes the samples whose key the table in schemas.topics marks as
recorded; other keys are counted as ``not_recorded``.

Zenoh callbacks only enqueue (key, payload, receive time); the main thread
writes, closes a chunk every ``flush_interval_s`` and finalizes the file on
SIGINT/SIGTERM. Throughput goes to stderr every ``progress_period_s``.
"""

from __future__ import annotations

import logging
import queue
import sys
import time
from dataclasses import dataclass, field

from couture.bus import BusConfig, Node
from couture.recording.mcapio import SessionWriter, split_key
from schemas import topics as topic_table

log = logging.getLogger("couture.recorder")


@dataclass
class RecordConfig:
    out: str
    """output .mcap path"""
    bus: BusConfig = field(default_factory=BusConfig)
    keyexprs: list[str] = field(default_factory=list)
    """absolute key expressions; empty: couture/<session>/** (or couture/** with all_sessions)"""
    all_sessions: bool = False
    flush_interval_s: float = 0.5
    progress_period_s: float = 2.0
    progress: bool = True
    name: str = "recorder"
    """node name (liveliness couture/<session>/status/<name>)"""
    duration_s: float = 0.0
    """stop by itself after this long (0: until SIGINT/SIGTERM)"""


@dataclass
class RecordStats:
    messages: int = 0
    bytes: int = 0
    seconds: float = 0.0


def records(key: str) -> bool:
    """Whether the recorder writes a sample on this absolute key (couture/<session>/<topic>)."""
    return topic_table.is_recorded(split_key(key)[1])


def main(config: RecordConfig) -> RecordStats:
    keys = config.keyexprs or (["couture/**"] if config.all_sessions else [f"couture/{config.bus.session}/**"])
    inbox: queue.SimpleQueue = queue.SimpleQueue()
    writer = SessionWriter(config.out, flush_interval_s=config.flush_interval_s)
    writer.add_metadata("couture", {"session": config.bus.session, "keyexprs": ",".join(keys)})
    stats = RecordStats()
    t0 = time.monotonic()
    try:
        # live only once subscribed: whoever waits for the recorder's liveliness
        # may publish right away and must not be missed
        with Node(config.name, config.bus, kind="recorder", announce=False) as node:

            def on_sample(key: str, data: bytes, t: int) -> None:
                if records(key):
                    inbox.put((key, data, t))
                else:
                    node.count("not_recorded")

            for k in keys:
                node.bus.subscribe_raw(k, on_sample)
            node.announce()
            last_report = time.monotonic()
            last_msgs, last_bytes = 0, 0
            deadline = t0 + config.duration_s if config.duration_s > 0 else float("inf")
            while not node.stopping and time.monotonic() < deadline:
                _drain(inbox, writer, node, timeout=0.05)
                writer.maybe_flush()
                now = time.monotonic()
                if config.progress and now - last_report >= config.progress_period_s:
                    dt = now - last_report
                    print(
                        f"[record] {writer.messages} msgs, {writer.bytes / 1e6:.1f} MB | "
                        f"{(writer.messages - last_msgs) / dt:.0f} msg/s, {(writer.bytes - last_bytes) / dt / 1e6:.2f} MB/s",
                        file=sys.stderr,
                        flush=True,
                    )
                    last_report, last_msgs, last_bytes = now, writer.messages, writer.bytes
            # messages already delivered to our callbacks still belong in the file
            _drain(inbox, writer, node, timeout=0.2)
    finally:
        while True:
            try:
                key, data, t = inbox.get_nowait()
            except queue.Empty:
                break
            writer.write(key, data, t)
        writer.close()
        stats.messages, stats.bytes, stats.seconds = writer.messages, writer.bytes, time.monotonic() - t0
        if config.progress:
            print(
                f"[record] finalized {config.out}: {stats.messages} msgs, {stats.bytes / 1e6:.1f} MB in {stats.seconds:.1f} s",
                file=sys.stderr,
                flush=True,
            )
    return stats


def _drain(inbox: queue.SimpleQueue, writer: SessionWriter, node: Node, timeout: float) -> None:
    try:
        item = inbox.get(timeout=timeout)
    except queue.Empty:
        return
    while True:
        key, data, t = item
        writer.write(key, data, t)
        node.count("recorded")
        writer.maybe_flush()
        try:
            item = inbox.get_nowait()
        except queue.Empty:
            return

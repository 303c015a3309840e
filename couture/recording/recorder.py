"""The recorder node: every message on a recorded topic into an MCAP file.

It subscribes to ``couture/<session>/**`` (so any probe on the session sees
it) and writes the samples whose key the table in schemas.topics marks as
recorded; other keys are counted as ``not_recorded``. A payload that is not
a valid message of its topic's type is written apart, on
``rejected/<key>`` (:func:`couture.recording.mcapio.check_payload`), and
counted as ``rejected`` in the recorder's status; the first one on each key
is logged with its reason.

It never opens an existing file: when ``out`` exists it writes the next
numbered part ``<stem>.<n>.mcap`` and says so in its log
(:mod:`couture.recording.parts`). ``run_id`` names the recording; ``couture
up`` gives every restart of its recorder the same one, so the parts a
crash-and-restart leaves behind read back as one recording.

Zenoh callbacks only enqueue (key, payload, receive time); the main thread
checks and writes, closes a chunk every ``flush_interval_s`` and finalizes
the file on SIGINT/SIGTERM. Status counters: ``recorded``, ``rejected``,
``on_disk`` (messages in flushed chunks, what a SIGKILL would keep),
``not_recorded``. Throughput goes to stderr every ``progress_period_s``.
"""

from __future__ import annotations

import logging
import queue
import sys
import time
import uuid
from dataclasses import dataclass, field

from couture.bus import BusConfig, Node
from couture.recording.mcapio import SessionWriter, check_payload, split_key
from couture.recording.parts import INFO_NAME, create_part, first_of_run
from schemas import topics as topic_table

log = logging.getLogger("couture.recorder")


@dataclass
class RecordConfig:
    out: str
    """output .mcap path (the next numbered part when it exists)"""
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
    run_id: str = ""
    """the recording this file belongs to; '' starts a new one (a fresh id).
    Recorders given the same id write parts of one recording."""


@dataclass
class RecordStats:
    messages: int = 0
    """written, valid and rejected"""
    rejected: int = 0
    bytes: int = 0
    seconds: float = 0.0
    path: str = ""
    """the file written (``out`` or a numbered part of it)"""
    part: int = 0


def records(key: str) -> bool:
    """Whether the recorder writes a sample on this absolute key (couture/<session>/<topic>)."""
    return topic_table.is_recorded(split_key(key)[1])


class _Sink:
    """Checks and writes one sample at a time; keeps the status counters."""

    def __init__(self, writer: SessionWriter, node: Node | None) -> None:
        self.writer = writer
        self.node = node
        self.reported_on_disk = 0
        self.rejected_keys: set[str] = set()

    def count(self, name: str, n: int = 1) -> None:
        if self.node is not None and n:
            self.node.count(name, n)

    def write(self, key: str, data: bytes, t: int) -> None:
        topic = split_key(key)[1]
        reason = check_payload(topic, data)
        if reason:
            self.writer.write_rejected(key, data, t, reason)
            self.count("rejected")
            if self.node is not None:
                self.node.bus.stats.error(f"rejected a payload on {topic}: {reason}")
            if key not in self.rejected_keys:
                self.rejected_keys.add(key)
                log.warning(
                    "rejected a payload on %s (%d bytes): %s; recorded apart on rejected/%s, "
                    "further ones are counted in status (counter 'rejected')",
                    key,
                    len(data),
                    reason,
                    key,
                )
        else:
            self.writer.write(key, data, t)
            self.count("recorded")
        self.maybe_flush()

    def maybe_flush(self) -> None:
        if self.writer.maybe_flush():
            self.count("on_disk", self.writer.on_disk - self.reported_on_disk)
            self.reported_on_disk = self.writer.on_disk


def main(config: RecordConfig) -> RecordStats:
    keys = config.keyexprs or (["couture/**"] if config.all_sessions else [f"couture/{config.bus.session}/**"])
    run_id = config.run_id or uuid.uuid4().hex
    f, path, part = create_part(config.out)
    if part:
        first = first_of_run(config.out, run_id, before=part)
        if first is not None:
            log.warning(
                "recording to %s: part %d of the recording that starts at %s (%s exists; it is never written over)",
                path,
                part,
                first,
                config.out,
            )
        else:
            log.warning(
                "%s exists (another recording; never written over): recording to %s, a new recording (run %s)",
                config.out,
                path,
                run_id,
            )
    else:
        log.info("recording to %s (run %s)", path, run_id)
    writer = SessionWriter(f, flush_interval_s=config.flush_interval_s)
    writer.add_metadata(
        INFO_NAME,
        {
            "session": config.bus.session,
            "keyexprs": ",".join(keys),
            "run_id": run_id,
            "part": str(part),
            "out": str(config.out),
            "started_ns": str(time.time_ns()),
        },
    )
    writer.flush()  # the file is a readable (empty) recording from here on
    inbox: queue.SimpleQueue = queue.SimpleQueue()
    stats = RecordStats(path=str(path), part=part)
    sink = _Sink(writer, None)
    t0 = time.monotonic()
    try:
        # live only once subscribed: whoever waits for the recorder's liveliness
        # may publish right away and must not be missed
        with Node(config.name, config.bus, kind="recorder", announce=False) as node:
            sink.node = node

            def on_sample(key: str, data: bytes, t: int) -> None:
                if records(key):
                    inbox.put((key, data, t))
                else:
                    node.count("not_recorded")

            for k in keys:
                node.bus.subscribe_raw(k, on_sample)
            node.count("file_part", part)
            node.announce()
            last_report = time.monotonic()
            last_msgs, last_bytes = 0, 0
            deadline = t0 + config.duration_s if config.duration_s > 0 else float("inf")
            while not node.stopping and time.monotonic() < deadline:
                _drain(inbox, sink, timeout=0.05)
                sink.maybe_flush()
                now = time.monotonic()
                if config.progress and now - last_report >= config.progress_period_s:
                    dt = now - last_report
                    print(
                        f"[record] {writer.messages} msgs ({writer.rejected} rejected), {writer.bytes / 1e6:.1f} MB | "
                        f"{(writer.messages - last_msgs) / dt:.0f} msg/s, {(writer.bytes - last_bytes) / dt / 1e6:.2f} MB/s",
                        file=sys.stderr,
                        flush=True,
                    )
                    last_report, last_msgs, last_bytes = now, writer.messages, writer.bytes
            # messages already delivered to our callbacks still belong in the file
            _drain(inbox, sink, timeout=0.2)
    finally:
        sink.node = None
        while True:
            try:
                key, data, t = inbox.get_nowait()
            except queue.Empty:
                break
            sink.write(key, data, t)
        writer.close()
        stats.messages, stats.rejected, stats.bytes = writer.messages, writer.rejected, writer.bytes
        stats.seconds = time.monotonic() - t0
        if config.progress or part or writer.rejected:
            print(
                f"[record] finalized {path}: {stats.messages} msgs ({stats.rejected} rejected, recorded apart), "
                f"{stats.bytes / 1e6:.1f} MB in {stats.seconds:.1f} s",
                file=sys.stderr,
                flush=True,
            )
    return stats


def _drain(inbox: queue.SimpleQueue, sink: _Sink, timeout: float) -> None:
    try:
        item = inbox.get(timeout=timeout)
    except queue.Empty:
        return
    while True:
        sink.write(*item)
        try:
            item = inbox.get_nowait()
        except queue.Empty:
            return

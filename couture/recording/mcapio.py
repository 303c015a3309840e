"""MCAP files of couture sessions: writing (crash-tolerant) and reading
(tolerant of a truncated tail).

Layout: one channel per full key (``couture/<session>/<topic>``), message
encoding ``msgpack``, one schema per versioned type name with encoding
``jsonschema`` (msgspec's JSON Schema of the Struct), ``log_time`` = receive
time and ``publish_time`` = the message's ``stamp_ns``. Chunks are zstd and
closed at least every ``flush_interval_s`` so a SIGKILL loses at most that
much; :func:`recover` rewrites such a file with a summary.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import BinaryIO, Iterator

import msgspec
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from schemas.messages import REGISTRY, json_schema

MESSAGE_ENCODING = "msgpack"
PROFILE = "couture"


@dataclass
class Recorded:
    """One message read back from a recording."""

    key: str
    """full key, couture/<session>/<topic>"""
    topic: str
    """key relative to couture/<session>/"""
    schema: str
    """versioned type name ('' if the payload claimed none)"""
    data: bytes
    """the msgpack payload as received"""
    log_time: int
    """receive time [ns since epoch]"""
    publish_time: int
    """sender's stamp_ns [ns since epoch]"""


def split_key(key: str) -> tuple[str, str]:
    """'couture/s1/drape/fine' -> ('s1', 'drape/fine')."""
    parts = key.split("/", 2)
    if len(parts) == 3 and parts[0] == "couture":
        return parts[1], parts[2]
    return "", key


class SessionWriter:
    """Appends couture messages to an MCAP file; call ``close()`` to finalize."""

    def __init__(self, out: str | BinaryIO, *, chunk_size: int = 4 << 20, flush_interval_s: float = 0.5) -> None:
        self._file = open(out, "wb") if isinstance(out, str) else out
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile=PROFILE, library="couture")
        self._schemas: dict[str, int] = {}
        self._channels: dict[tuple[str, str], int] = {}
        self.flush_interval_s = flush_interval_s
        self._last_flush = time.monotonic()
        self._dirty = False
        self.messages = 0
        self.bytes = 0

    def _schema_id(self, name: str) -> int:
        if name not in self._schemas:
            cls = REGISTRY.get(name)
            if cls is None:
                return 0  # unknown or malformed payload: recorded without a schema
            self._schemas[name] = self._writer.register_schema(name=name, encoding="jsonschema", data=json_schema(cls))
        return self._schemas[name]

    def write(
        self, key: str, data: bytes, log_time: int, publish_time: int | None = None, schema: str | None = None
    ) -> None:
        if schema is None or publish_time is None:
            sch, stamp = _head(data)
            schema = sch if schema is None else schema
            publish_time = (stamp or log_time) if publish_time is None else publish_time
        cid = self._channels.get((key, schema))
        if cid is None:
            session, topic = split_key(key)
            cid = self._writer.register_channel(
                topic=key,
                message_encoding=MESSAGE_ENCODING,
                schema_id=self._schema_id(schema),
                metadata={"session": session, "topic": topic, "schema": schema},
            )
            self._channels[(key, schema)] = cid
        self._writer.add_message(channel_id=cid, log_time=log_time, data=data, publish_time=publish_time)
        self.messages += 1
        self.bytes += len(data)
        self._dirty = True

    def maybe_flush(self) -> None:
        """Close the open chunk if flush_interval_s has passed (crash tolerance)."""
        if self._dirty and time.monotonic() - self._last_flush >= self.flush_interval_s:
            self.flush()

    def flush(self) -> None:
        self._writer.flush()
        try:
            os.fsync(self._file.fileno())
        except (OSError, AttributeError, ValueError):
            pass
        self._last_flush = time.monotonic()
        self._dirty = False

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        self._writer.add_metadata(name, data)

    def close(self) -> None:
        self._writer.finish()
        self._file.close()


class _Head(msgspec.Struct):
    schema: str = ""
    stamp_ns: int = 0


_HEAD = msgspec.msgpack.Decoder(_Head)


def _head(data: bytes) -> tuple[str, int]:
    """(schema, stamp_ns) of a payload, ('', 0) for what is not a couture message."""
    try:
        h = _HEAD.decode(data)
        return h.schema, h.stamp_ns
    except Exception:
        return "", 0


def read_session(path: str, topics: list[str] | None = None, *, strict: bool = False) -> Iterator[Recorded]:
    """Messages of a recording in file order, with the non-seeking reader so a
    file cut short (SIGKILL) yields everything up to its last whole chunk.
    ``topics``: relative topics or prefixes ending in '/*' (None: all)."""
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    with open(path, "rb") as f:
        reader = StreamReader(f, record_size_limit=1 << 31)
        it = reader.records
        while True:
            try:
                rec = next(it)
            except StopIteration:
                return
            except Exception:
                if strict:
                    raise
                return  # truncated tail
            if isinstance(rec, Schema):
                schemas[rec.id] = rec
            elif isinstance(rec, Channel):
                channels[rec.id] = rec
            elif isinstance(rec, Message):
                ch = channels.get(rec.channel_id)
                if ch is None:
                    continue
                _, topic = split_key(ch.topic)
                if topics is not None and not any(topic_matches(p, topic) for p in topics):
                    continue
                sch = schemas.get(ch.schema_id)
                yield Recorded(
                    key=ch.topic,
                    topic=topic,
                    schema=sch.name if sch else ch.metadata.get("schema", ""),
                    data=rec.data,
                    log_time=rec.log_time,
                    publish_time=rec.publish_time,
                )


def topic_matches(pattern: str, topic: str) -> bool:
    """'drape/*' matches 'drape/fine'; '**' and 'drape/**' match any depth."""
    if pattern in ("**", topic):
        return True
    if pattern.endswith("/**"):
        return topic.startswith(pattern[:-2]) or topic == pattern[:-3]
    if pattern.endswith("/*"):
        head = pattern[:-1]
        return topic.startswith(head) and "/" not in topic[len(head) :]
    return False


def recover(src: str, dst: str) -> int:
    """Rewrite a (possibly truncated) recording into a finalized MCAP with a
    summary. Returns the number of messages kept."""
    w = SessionWriter(dst, flush_interval_s=1e9)
    try:
        for m in read_session(src):
            w.write(m.key, m.data, m.log_time, m.publish_time, m.schema)
    finally:
        w.close()
    return w.messages

"""MCAP files of couture sessions: writing (crash-tolerant) and reading
(tolerant of a truncated tail, across the numbered parts of a recording).

Layout: one channel per full key (``couture/<session>/<topic>``), message
encoding ``msgpack``, one schema per versioned type name with encoding
``jsonschema`` (msgspec's JSON Schema of the Struct), ``log_time`` = receive
time and ``publish_time`` = the message's ``stamp_ns``. Chunks are zstd and
closed at least every ``flush_interval_s`` so a SIGKILL loses at most that
much; :func:`read_session` reads such a file up to its last whole chunk and
:func:`recover` rewrites it (or a whole set of parts) with a summary.

A payload that is not a valid message of its topic's type
(:func:`check_payload`: not msgpack, an unknown schema or version, another
message type, a bad field) is *rejected*: the recorder writes it byte for
byte on its own channel, topic ``rejected/<key>``, message encoding
``application/octet-stream``, no schema, metadata ``rejected`` = the first
reason seen. :func:`read_session` leaves those out unless asked, so replay
never re-sends them and compare never compares them.

Recordings made before Ψ had its own topic hold Ψ inside ``couture/mesh/v1``
payloads (fields ``psi``, ``psi_edit_id``, ``unchanged``; a mesh re-sent on
every press only to carry it). :func:`read_session` migrates them as it reads
(:func:`migrate_legacy`): such a payload becomes a ``couture/psi/v1`` message
on ``psi/<level>``, preceded by the mesh without those fields unless it was
such a re-send. Replay, compare and ``couture golden check`` read the old
goldens as if recorded today.

A writer never opens an existing file: :class:`SessionWriter` creates its
file exclusively, and the recorder writes the next numbered part when its
target exists (:mod:`couture.recording.parts`).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, Iterable, Iterator, Literal

import msgspec
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from couture.recording.parts import PathLike, resolve
from schemas import topics as topic_table
from schemas.arrays import Array
from schemas.messages import REGISTRY, MeshMsg, PsiMsg, SchemaError, decode, encode, json_schema

MESSAGE_ENCODING = "msgpack"
PROFILE = "couture"
REJECTED_PREFIX = "rejected/"
"""MCAP topic prefix of the channels that hold rejected payloads"""
REJECTED_ENCODING = "application/octet-stream"


@dataclass
class Recorded:
    """One message read back from a recording."""

    key: str
    """full key, couture/<session>/<topic> (for a rejected payload, the key it came on)"""
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
    rejected: str = ""
    """why the recorder set this payload apart ('' for valid traffic)"""
    path: str = ""
    """the file it was read from"""


def split_key(key: str) -> tuple[str, str]:
    """'couture/s1/drape/fine' -> ('s1', 'drape/fine')."""
    parts = key.split("/", 2)
    if len(parts) == 3 and parts[0] == "couture":
        return parts[1], parts[2]
    return "", key


def check_payload(topic: str, data: bytes) -> str:
    """'' when ``data`` is a valid message of the type the topic table gives
    ``topic`` (any known type for a key outside the table), else the reason
    (names the schema and the field)."""
    try:
        topic_table.check_size(topic, len(data))
        decode(data, topic_table.type_for_topic(topic))
    except SchemaError as e:
        return str(e)
    return ""


class SessionWriter:
    """Appends couture messages to a new MCAP file; call ``close()`` to finalize.

    ``out``: a path, created exclusively (FileExistsError when it exists: a
    recording is never written over), or an open binary file."""

    def __init__(self, out: PathLike | BinaryIO, *, chunk_size: int = 4 << 20, flush_interval_s: float = 0.5) -> None:
        if isinstance(out, (str, os.PathLike)):
            try:
                self._file: BinaryIO = open(out, "xb")
            except FileExistsError:
                raise FileExistsError(
                    f"{out}: exists; a recording is never written over (choose another name)"
                ) from None
        else:
            self._file = out
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile=PROFILE, library="couture")
        self._schemas: dict[str, int] = {}
        self._channels: dict[tuple[str, str], int] = {}
        self._rejected_channels: dict[str, int] = {}
        self.flush_interval_s = flush_interval_s
        self._last_flush = time.monotonic()
        self._dirty = False
        self.messages = 0
        """messages written, valid and rejected"""
        self.rejected = 0
        """of which rejected payloads"""
        self.bytes = 0
        self.on_disk = 0
        """messages in chunks already flushed (what a SIGKILL now would keep)"""

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
        """Write a payload on its key's channel (the caller has checked it: see :meth:`write_rejected`)."""
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
        self._add(cid, data, log_time, publish_time)

    def write_rejected(self, key: str, data: bytes, log_time: int, reason: str) -> None:
        """Write a payload that failed :func:`check_payload` apart, on ``rejected/<key>``."""
        cid = self._rejected_channels.get(key)
        if cid is None:
            session, topic = split_key(key)
            cid = self._writer.register_channel(
                topic=REJECTED_PREFIX + key,
                message_encoding=REJECTED_ENCODING,
                schema_id=0,
                metadata={"session": session, "topic": topic, "rejected": reason[:500]},
            )
            self._rejected_channels[key] = cid
        self.rejected += 1
        self._add(cid, data, log_time, log_time)

    def _add(self, cid: int, data: bytes, log_time: int, publish_time: int) -> None:
        self._writer.add_message(channel_id=cid, log_time=log_time, data=data, publish_time=publish_time)
        self.messages += 1
        self.bytes += len(data)
        self._dirty = True

    def maybe_flush(self) -> bool:
        """Close the open chunk if flush_interval_s has passed (crash tolerance); True if it did."""
        if self._dirty and time.monotonic() - self._last_flush >= self.flush_interval_s:
            self.flush()
            return True
        return False

    def flush(self) -> None:
        """Write the open chunk and fsync: everything written so far survives a SIGKILL."""
        self._writer.flush()
        try:
            os.fsync(self._file.fileno())
        except (OSError, AttributeError, ValueError):
            pass
        self._last_flush = time.monotonic()
        self._dirty = False
        self.on_disk = self.messages

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        self._writer.add_metadata(name, data)

    def close(self) -> None:
        self._writer.finish()
        self._file.close()
        self.on_disk = self.messages


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


class _LegacyPsi(msgspec.Struct):
    """What a ``couture/mesh/v1`` payload recorded before ``couture/psi/v1``
    existed carried for Ψ, with the header and mesh names a PsiMsg needs."""

    seq: int = 0
    stamp_ns: int = 0
    generation: int = 0
    level: str = "fine"
    mesh_generation: int = 0
    design_id: str = ""
    psi: Array | None = None
    psi_edit_id: str = ""
    unchanged: bool = False


_LEGACY_PSI = msgspec.msgpack.Decoder(_LegacyPsi)
_LEGACY_MARK = b"\xa9unchanged"
"""the msgpack key ``unchanged`` (a fixstr of 9 bytes): every legacy mesh payload has it, no current one"""


def migrate_legacy(topic: str, data: bytes) -> list[tuple[str, bytes]]:
    """A recorded payload as (topic, payload) pairs of today's messages: a
    legacy ``mesh/<level>`` payload that carried Ψ becomes the mesh alone
    (unless it was a re-send flagged ``unchanged``) followed by a
    ``couture/psi/v1`` payload on ``psi/<level>`` with the mesh's header; any
    other payload is returned as it is (an invalid one too: the reader's
    checks name its problem)."""
    if not topic.startswith("mesh/") or _LEGACY_MARK not in data:
        return [(topic, data)]
    try:
        old = _LEGACY_PSI.decode(data)
    except (msgspec.DecodeError, msgspec.ValidationError):
        return [(topic, data)]
    if old.psi is None and not old.unchanged:
        return [(topic, data)]  # a plain mesh: the stale fields are ignored by the decoder
    out: list[tuple[str, bytes]] = []
    try:
        if not old.unchanged:
            out.append((topic, encode(decode(data, MeshMsg))))
        if old.psi is not None and old.psi_edit_id and old.level in ("coarse", "fine"):
            psi = PsiMsg(
                seq=old.seq,
                stamp_ns=old.stamp_ns,
                generation=old.generation,
                level=old.level,  # type: ignore[arg-type]
                mesh_generation=old.mesh_generation,
                design_id=old.design_id,
                edit_id=old.psi_edit_id,
                psi=old.psi,
            )
            out.append((f"psi/{old.level}", encode(psi)))
    except SchemaError:
        return [(topic, data)]
    return out


Which = Literal["valid", "rejected", "all"]


def read_session(
    paths: PathLike | Iterable[PathLike],
    topics: list[str] | None = None,
    *,
    strict: bool = False,
    which: Which = "valid",
    parts: bool = True,
) -> Iterator[Recorded]:
    """Messages of a recording: every file of ``paths``, each expanded to its
    numbered parts (``parts``, see :mod:`couture.recording.parts`), in part
    order, and within a file in file order. The non-seeking reader gets
    through a file cut short (SIGKILL) up to its last whole chunk.
    ``topics``: relative topics or prefixes ending in '/*' (None: all);
    ``which``: 'valid' traffic (default), the 'rejected' payloads the
    recorder set apart, or 'all' (``Recorded.rejected`` tells them apart)."""
    for path in resolve(paths, parts=parts):
        yield from _read_file(path, topics, strict, which)


def _read_file(path: Path, topics: list[str] | None, strict: bool, which: Which) -> Iterator[Recorded]:
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
                is_rejected = ch.topic.startswith(REJECTED_PREFIX)
                if (which == "valid" and is_rejected) or (which == "rejected" and not is_rejected):
                    continue
                key = ch.topic[len(REJECTED_PREFIX) :] if is_rejected else ch.topic
                _, topic = split_key(key)
                if topics is not None and not any(topic_matches(p, t) for p in topics for t in _read_as(topic)):
                    continue
                reason = ""
                if is_rejected:  # the recorder's check again, for this payload's own reason
                    reason = (
                        check_payload(topic, rec.data) or f"rejected when recorded: {ch.metadata.get('rejected', '')}"
                    )
                    schema = _head(rec.data)[0]
                else:
                    sch = schemas.get(ch.schema_id)
                    schema = sch.name if sch else ch.metadata.get("schema", "")
                    if topic.startswith("mesh/"):
                        yield from _migrated(key, topic, rec, topics, str(path))
                        continue
                yield Recorded(
                    key=key,
                    topic=topic,
                    schema=schema,
                    data=rec.data,
                    log_time=rec.log_time,
                    publish_time=rec.publish_time,
                    rejected=reason,
                    path=str(path),
                )


def _read_as(topic: str) -> tuple[str, ...]:
    """The topics a recorded topic's messages may be read as (a legacy mesh: its Ψ too)."""
    return (topic, "psi/" + topic[5:]) if topic.startswith("mesh/") else (topic,)


def _migrated(key: str, topic: str, rec: Message, topics: list[str] | None, path: str) -> Iterator[Recorded]:
    """A valid mesh record as today's messages (:func:`migrate_legacy`), filtered by ``topics``."""
    prefix = key[: len(key) - len(topic)]
    for t, data in migrate_legacy(topic, rec.data):
        if topics is not None and not any(topic_matches(p, t) for p in topics):
            continue
        yield Recorded(
            key=prefix + t,
            topic=t,
            schema=_head(data)[0],
            data=data,
            log_time=rec.log_time,
            publish_time=rec.publish_time,
            path=path,
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


def recover(src: PathLike | Iterable[PathLike], dst: PathLike, *, parts: bool = True) -> int:
    """Rewrite a recording (possibly cut short, possibly in numbered parts:
    every file of ``src``, expanded as :func:`read_session` does) into one
    new finalized MCAP with a summary; rejected payloads stay apart. ``dst``
    must not exist. Returns the number of messages kept."""
    files = resolve(src, parts=parts)
    w = SessionWriter(dst, flush_interval_s=1e9)
    try:
        for m in read_session(files, which="all", parts=False):
            if m.rejected:
                w.write_rejected(m.key, m.data, m.log_time, m.rejected)
            else:
                w.write(m.key, m.data, m.log_time, m.publish_time, m.schema)
    finally:
        w.close()
    return w.messages

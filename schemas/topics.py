"""The topic table: every key the nodes publish on, what it carries, how it is
delivered, and what recording, replay and compare do with it.

Keys are relative to ``couture/<session>/``. A key ending in ``*`` stands for
one more key segment, the name of a node (``status/<node>``) or of a solver
(``solve/result/<solver>``). The bus (couture.bus.session), the recorder,
replay, compare and the CLI read this table when they need it, so adding a
topic or a message type is an edit here and in schemas/messages.py only.

The ``solve/<solver>`` queryable is not in the table: a query is invisible to
subscribers, which is why each request and result is mirrored on
``solve/request`` and ``solve/result/<solver>``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from schemas.messages import (
    AdjustMsg,
    AdjustStatusMsg,
    DrapeMsg,
    EditMsg,
    MeshMsg,
    Message,
    PatternMsg,
    PsiMsg,
    RejectedMsg,
    SchemaError,
    SolveRequestMsg,
    SolveResultMsg,
    StatusMsg,
    TryOnMsg,
)

MiB = 1 << 20

MAX_BYTES_ENV = "COUTURE_MAX_MESSAGE_BYTES"
"""a site-wide cap [bytes] on every topic's ``max_bytes`` (the smaller wins);
unset or 0: the table's limits alone"""


@dataclass(frozen=True)
class Delivery:
    """How a topic's messages travel (Zenoh publisher settings)."""

    history: int = 0
    """samples the publisher keeps for subscribers that join late (0: none).
    A restarted solver or a reopened UI resumes from the latest state."""
    express: bool = False
    """sent at once, without batching (latency-critical)"""
    drop: bool = False
    """DROP congestion control: a late sample is worthless and may be lost.
    False: BLOCK, the publisher waits (Zenoh 1.10 can silently lose large
    fragmented messages under DROP, so never for patterns or meshes)."""

    @property
    def name(self) -> str:
        """'history(n)', 'express', 'drop' or a '+'-joined mix; 'reliable' for none of them."""
        parts = [f"history({self.history})"] if self.history else []
        parts += ["express"] if self.express else []
        parts += ["drop"] if self.drop else []
        return "+".join(parts) or "reliable"


HISTORY = Delivery(history=1)
"""state: the last sample waits for late joiners"""
EXPRESS = Delivery(express=True)
"""a user gesture: sent at once, never dropped"""
PREVIEW = Delivery(express=True, drop=True)
"""high-rate previews: sent at once, dropped under congestion"""
PLAIN = Delivery()
"""reliable, batched, no history"""


@dataclass(frozen=True)
class Topic:
    """One row of the table."""

    key: str
    """relative key; a trailing '*' is one segment (a node or solver name)"""
    msg_type: type[Message]
    delivery: Delivery
    recorded: bool
    """the recorder writes it to MCAP"""
    replayed: bool
    """an input: replay re-publishes it from a recording"""
    compared: bool
    """an output: compare checks it against a golden recording"""
    publisher: str
    """who publishes it (documentation)"""
    max_bytes: int = MiB
    """[bytes] the largest payload a receiver accepts; a larger one is dropped
    unread and counted (a flood of huge payloads must not stall a node). The
    mesh-sized topics allow a mesh at the largest target size (250k vertices:
    about 27 MB), with room to spare."""


TOPICS: tuple[Topic, ...] = (
    # A few patterns, so a late joiner also sees the last *valid* design when the newest one was rejected.
    Topic(
        "pattern",
        PatternMsg,
        Delivery(history=8),
        recorded=True,
        replayed=True,
        compared=False,
        publisher="ui, scripts, sensitivity (3D tug)",
        max_bytes=8 * MiB,
    ),
    Topic(
        "edit",
        EditMsg,
        EXPRESS,
        recorded=True,
        replayed=True,
        compared=False,
        publisher="ui, scripts",
        max_bytes=64 << 10,
    ),
    Topic(
        "tryon",
        TryOnMsg,
        EXPRESS,
        recorded=True,
        replayed=True,
        compared=False,
        publisher="ui, scripts",
        max_bytes=64 << 10,
    ),
    # a request for many solves: sent at once, never dropped, never replayed
    # (its outcome, the adjusted pattern, is recorded and replayed as a pattern)
    Topic(
        "adjust",
        AdjustMsg,
        EXPRESS,
        recorded=True,
        replayed=False,
        compared=False,
        publisher="ui, scripts",
        max_bytes=1 * MiB,
    ),
    Topic(
        "adjust/status",
        AdjustStatusMsg,
        PLAIN,
        recorded=True,
        replayed=False,
        compared=False,
        publisher="adjust",
        max_bytes=64 << 10,
    ),
    Topic(
        "mesh/coarse",
        MeshMsg,
        HISTORY,
        recorded=True,
        replayed=False,
        compared=True,
        publisher="remesher",
        max_bytes=128 * MiB,
    ),
    Topic(
        "mesh/fine",
        MeshMsg,
        HISTORY,
        recorded=True,
        replayed=False,
        compared=True,
        publisher="remesher",
        max_bytes=128 * MiB,
    ),
    # Ψ of each press, apart from the mesh it lives on (a press moves Ψ alone); kept, so a
    # node restarted mid-drag gets the gesture's Ψ, and sent at once (the first prediction waits on it)
    Topic(
        "psi/coarse",
        PsiMsg,
        Delivery(history=1, express=True),
        recorded=True,
        replayed=False,
        compared=True,
        publisher="remesher",
        max_bytes=32 * MiB,
    ),
    Topic(
        "psi/fine",
        PsiMsg,
        Delivery(history=1, express=True),
        recorded=True,
        replayed=False,
        compared=True,
        publisher="remesher",
        max_bytes=32 * MiB,
    ),
    Topic(
        "drape/predicted",
        DrapeMsg,
        PREVIEW,
        recorded=True,
        replayed=False,
        compared=True,
        publisher="sensitivity",
        max_bytes=32 * MiB,
    ),
    Topic(
        "drape/coarse",
        DrapeMsg,
        HISTORY,
        recorded=True,
        replayed=False,
        compared=True,
        publisher="solver",
        max_bytes=32 * MiB,
    ),
    Topic(
        "drape/fine",
        DrapeMsg,
        HISTORY,
        recorded=True,
        replayed=False,
        compared=True,
        publisher="solver",
        max_bytes=32 * MiB,
    ),
    Topic("status/*", StatusMsg, PLAIN, recorded=True, replayed=False, compared=False, publisher="every node"),
    # Sent at once (a client waiting for that design's drape stops waiting), and
    # kept like the patterns, so a late joiner learns which recent designs were refused.
    Topic(
        "rejected",
        RejectedMsg,
        Delivery(history=8, express=True),
        recorded=True,
        replayed=False,
        compared=False,
        publisher="remesher, solver",
    ),
    Topic(
        "solve/request",
        SolveRequestMsg,
        PLAIN,
        recorded=True,
        replayed=False,
        compared=False,
        publisher="any solve client",
        max_bytes=128 * MiB,
    ),
    Topic(
        "solve/result/*",
        SolveResultMsg,
        PLAIN,
        recorded=True,
        replayed=False,
        compared=True,
        publisher="solver",
        max_bytes=32 * MiB,
    ),
)
"""The topic table. Readers look it up at call time (``schemas.topics.TOPICS``),
so a test may extend it."""


def _chunks_intersect(a: list[str], b: list[str]) -> bool:
    """Whether two key expressions, as lists of chunks ('*' one chunk, '**'
    any number, Zenoh's rules), can match a common key."""
    if not a and not b:
        return True
    if a and a[0] == "**":
        return _chunks_intersect(a[1:], b) or (bool(b) and _chunks_intersect(a, b[1:]))
    if b and b[0] == "**":
        return _chunks_intersect(a, b[1:]) or (bool(a) and _chunks_intersect(a[1:], b))
    if not a or not b:
        return False
    if a[0] == "*" or b[0] == "*" or a[0] == b[0]:
        return _chunks_intersect(a[1:], b[1:])
    return False


def key_intersects(a: str, b: str) -> bool:
    """Whether key expressions ``a`` and ``b`` ('drape/*', 'status/*', '**', 'pattern') share a key."""
    return _chunks_intersect(a.split("/"), b.split("/"))


def topic_spec(topic: str) -> Topic | None:
    """The table row of a concrete relative key ('drape/fine', 'status/ui'), or None."""
    for t in TOPICS:
        if key_intersects(t.key, topic):
            return t
    return None


def topics_matching(keyexpr: str) -> list[Topic]:
    """Table rows a subscription such as 'mesh/*' or '**' can receive."""
    return [t for t in TOPICS if key_intersects(keyexpr, t.key)]


def type_for_topic(topic: str) -> type[Message] | None:
    """Message class a relative key such as 'drape/fine' carries, or None."""
    t = topic_spec(topic)
    return t.msg_type if t else None


def type_for_keyexpr(keyexpr: str) -> type[Message] | None:
    """The one message class every key under a subscription carries, or None
    when it covers several types (or none): then each sample's own key decides."""
    types = {t.msg_type for t in topics_matching(keyexpr)}
    return types.pop() if len(types) == 1 else None


def max_bytes_for(topic: str) -> int:
    """[bytes] the largest payload accepted on a relative key: the table's
    ``max_bytes`` (keys outside the table: 1 MiB), capped by
    ``$COUTURE_MAX_MESSAGE_BYTES`` when set."""
    t = topic_spec(topic)
    limit = t.max_bytes if t else MiB
    cap = os.environ.get(MAX_BYTES_ENV, "")
    if cap.strip():
        try:
            n = int(cap)
        except ValueError:
            raise ValueError(f"${MAX_BYTES_ENV} must be a whole number of bytes, got {cap!r}") from None
        if n > 0:
            limit = min(limit, n)
    return limit


def check_size(topic: str, nbytes: int) -> None:
    """Raise SchemaError when a payload of ``nbytes`` is above the limit of ``topic``."""
    limit = max_bytes_for(topic)
    if nbytes > limit:
        raise SchemaError(f"oversized payload on {topic}: {nbytes} bytes, the limit is {limit} bytes")


def delivery_for(topic: str) -> Delivery:
    """How a publisher on ``topic`` sends; keys outside the table travel PLAIN."""
    t = topic_spec(topic)
    return t.delivery if t else PLAIN


def history_for_subscription(keyexpr: str) -> int:
    """Samples a subscriber on ``keyexpr`` asks late publishers for: the largest
    history among the topics it covers, 0 when none keeps any."""
    return max((t.delivery.history for t in topics_matching(keyexpr)), default=0)


def is_recorded(topic: str) -> bool:
    """Whether the recorder writes messages on this relative key."""
    t = topic_spec(topic)
    return t is not None and t.recorded


def replayed_topics() -> list[str]:
    """The inputs replay re-publishes by default, in table order."""
    return [t.key for t in TOPICS if t.replayed]


def compared_topics() -> list[str]:
    """The outputs compare checks by default, in table order."""
    return [t.key for t in TOPICS if t.compared]


def markdown_table() -> str:
    """The table as Markdown (the README embeds it; a test keeps them equal)."""
    rows = ["| key | message | delivery | recorded | replay / compare | publisher |", "|---|---|---|---|---|---|"]
    for t in TOPICS:
        role = "replayed" if t.replayed else "compared" if t.compared else "-"
        key = t.key
        if key.endswith("/*"):
            key = key[:-1] + ("<node>" if key.startswith("status/") else "<solver>")
        rows.append(
            f"| `{key}` | `{t.msg_type.TYPE}` | {t.delivery.name} | {'yes' if t.recorded else 'no'} "
            f"| {role} | {t.publisher} |"
        )
    return "\n".join(rows)


__all__ = [
    "Delivery",
    "Topic",
    "TOPICS",
    "HISTORY",
    "EXPRESS",
    "PREVIEW",
    "PLAIN",
    "key_intersects",
    "topic_spec",
    "topics_matching",
    "type_for_topic",
    "type_for_keyexpr",
    "delivery_for",
    "max_bytes_for",
    "check_size",
    "MAX_BYTES_ENV",
    "history_for_subscription",
    "is_recorded",
    "replayed_topics",
    "compared_topics",
    "markdown_table",
]

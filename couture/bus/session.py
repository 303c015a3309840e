"""A couture session on Zenoh: shared CLI flags, typed publishers and
subscribers, liveliness, and the ``solve`` request/reply.

Keys live under ``couture/<session>/``; methods take keys relative to that
prefix (``"drape/fine"``, ``"mesh/*"``). Defaults are loopback only: the
session listens on ``tcp/127.0.0.1:0`` (a free port), multicast scouting is
off, gossip scouting is on (so peers that connect to one peer find the rest).

Lifecycle: ``with open_session(cfg) as bus: ...`` closes every subscriber,
queryable, token and the session on every exit path. Zenoh 1.10 hangs
interpreter exit if a callback subscriber is left open, so close explicitly;
``install_stop_signals()`` turns SIGTERM into a flag so ``finally`` runs.
"""

from __future__ import annotations

import argparse
import json
import logging
import queue
import threading
import time
import traceback
import uuid
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any, Callable, Generic, TypeVar

import zenoh
import zenoh.ext

from schemas import topics
from schemas.messages import (
    Message,
    SchemaError,
    SolveRequestMsg,
    SolveResultMsg,
    decode,
    encode,
)

log = logging.getLogger("couture.bus")

M = TypeVar("M", bound=Message)

RESERVED_SOLVER_NAMES = ("request", "result")

DEFAULT_PORT = 7447
DEFAULT_ENDPOINT = f"tcp/127.0.0.1:{DEFAULT_PORT}"
HEARTBEAT_S = 1.0
"""[s] period of the sequence-number heartbeat of publishers that keep history: a
subscriber that missed a topic's last sample (a partition) recovers it within
about this long after the link heals"""
"""where `couture up` listens when that port is free, and where Client connects by default"""


@dataclass
class BusConfig:
    """Where and how to join the bus (the shared flags of every node)."""

    session: str = "default"
    """namespace: keys live under couture/<session>/"""
    connect: list[str] = field(default_factory=list)
    """endpoints to connect to, e.g. ['tcp/127.0.0.1:7447']"""
    listen: list[str] = field(default_factory=lambda: ["tcp/127.0.0.1:0"])
    """endpoints to listen on; loopback and a free port by default"""
    mode: str = "peer"
    """'peer', 'client' or 'router'"""
    config_file: str | None = None
    """a Zenoh JSON5 config file applied first (flags override it)"""
    multicast: bool = False
    """multicast scouting (off: loopback-only by default)"""
    tls: str | None = None
    """a secure directory (``couture certs``): TLS only, mTLS, access control
    (couture.bus.secure); None: plain TCP as before"""
    tls_name: str = ""
    """whose certificate in ``tls`` to use; '' for the session's node name"""

    def zenoh_config(self, name: str = "") -> zenoh.Config:
        """The Zenoh config; ``name`` picks the certificate when ``tls`` is set
        (``tls_name`` wins over it)."""
        if self.config_file:
            with open(self.config_file) as f:
                conf = zenoh.Config.from_json5(f.read())
        else:
            conf = zenoh.Config()
        conf.insert_json5("mode", json.dumps(self.mode))
        listen = self.listen
        if self.tls and listen == ["tcp/127.0.0.1:0"]:
            listen = ["tls/127.0.0.1:0"]  # the loopback default, secured
        if self.connect:
            conf.insert_json5("connect/endpoints", json.dumps(self.connect))
        if listen and self.mode != "client":
            conf.insert_json5("listen/endpoints", json.dumps(listen))
        conf.insert_json5("scouting/multicast/enabled", json.dumps(self.multicast))
        if self.mode != "client":
            conf.insert_json5("scouting/gossip/enabled", "true")
        # advanced publishers (history for late joiners on state topics) need timestamps
        conf.insert_json5("timestamping/enabled", '{"router": true, "peer": true, "client": true}')
        if self.tls:
            from couture.bus import secure

            secure.check_endpoints(self.connect, "--connect")
            if self.mode != "client":
                secure.check_endpoints(listen, "--listen")
            secure.apply(conf, self.tls, self.tls_name or name)
        return conf

    def to_args(self) -> list[str]:
        """Flags that reproduce this config on a child's command line."""
        args = ["--session", self.session, "--mode", self.mode]
        for e in self.connect:
            args += ["--connect", e]
        for e in self.listen:
            args += ["--listen", e]
        if self.config_file:
            args += ["--config", self.config_file]
        if self.multicast:
            args += ["--multicast"]
        if self.tls:
            args += ["--tls", self.tls]
        return args


def add_bus_args(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add --connect/--listen/--mode/--config/--session/--multicast (every node takes them)."""
    g = parser.add_argument_group("bus")
    g.add_argument("--session", default="default", help="keys live under couture/<session>/ (default: %(default)s)")
    g.add_argument(
        "--connect",
        "-e",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable)",
    )
    g.add_argument(
        "--listen",
        "-l",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint to listen on (repeatable; default tcp/127.0.0.1:0, loopback only)",
    )
    g.add_argument("--mode", "-m", choices=["peer", "client", "router"], default="peer")
    g.add_argument("--config", dest="zenoh_config", default=None, metavar="FILE", help="Zenoh JSON5 config file")
    g.add_argument("--multicast", action="store_true", help="enable multicast scouting (off by default)")
    g.add_argument(
        "--tls",
        metavar="DIR",
        default=None,
        help="join a secured session: TLS endpoints only (default listen tls/127.0.0.1:0), this node's certificate "
        "DIR/<name>.pem signed by DIR/ca.pem, access control from DIR/policy.json (make DIR with `couture certs`)",
    )
    return parser


def bus_config_from_args(args: argparse.Namespace) -> BusConfig:
    tls = getattr(args, "tls", None)
    return BusConfig(
        session=args.session,
        connect=list(args.connect),
        listen=list(args.listen) or ["tcp/127.0.0.1:0"],
        mode=args.mode,
        config_file=args.zenoh_config,
        multicast=args.multicast,
        tls=tls,
    )


def open_session(cfg: "BusConfig | argparse.Namespace | None" = None, *, name: str = "") -> "Bus":
    """Open a Bus from a BusConfig or parsed flags (see add_bus_args)."""
    if cfg is None:
        cfg = BusConfig()
    elif isinstance(cfg, argparse.Namespace):
        cfg = bus_config_from_args(cfg)
    return Bus(cfg, name=name)


class Stats:
    """Per-node counters and event rates, exposed in the status message."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.counters: dict[str, int] = defaultdict(int)
        self.last_error = ""
        self._window: dict[str, int] = defaultdict(int)
        self._window_start = time.monotonic()

    def count(self, name: str, n: int = 1) -> None:
        with self._lock:
            self.counters[name] += n
            self._window[name] += n

    def error(self, text: str) -> None:
        with self._lock:
            self.last_error = text

    def take_rates(self) -> dict[str, float]:
        """Events per second since the previous call."""
        with self._lock:
            now = time.monotonic()
            dt = max(now - self._window_start, 1e-9)
            rates = {k: v / dt for k, v in self._window.items()}
            self._window.clear()
            self._window_start = now
            return rates

    def snapshot(self) -> dict[str, int]:
        with self._lock:
            return dict(self.counters)


def publisher_options(topic: str, *, drop: bool | None = None) -> tuple[dict[str, Any], int]:
    """Zenoh publisher options for ``topic`` from the topic table, and the
    number of samples to keep for late joiners (0: a plain publisher).
    ``drop`` overrides the table's congestion control."""
    delivery = topics.delivery_for(topic)
    if drop is None:
        drop = delivery.drop
    opts: dict[str, Any] = dict(
        congestion_control=zenoh.CongestionControl.DROP if drop else zenoh.CongestionControl.BLOCK,
        reliability=zenoh.Reliability.RELIABLE,
        express=delivery.express,
    )
    return opts, delivery.history


def has_subscribers(pub: Any) -> bool:
    """Whether a subscriber matches a plain Zenoh publisher now. (zenoh 1.10's
    stubs type ``matching_status`` as bool; it is a MatchingStatus object.)"""
    return bool(pub.matching_status.matching)


class TypedPublisher(Generic[M]):
    """Publishes one message type on one key; fills seq and stamp_ns."""

    def __init__(self, bus: "Bus", topic: str, msg_type: type[M], *, drop: bool | None = None) -> None:
        """Delivery (history, express, drop) comes from the topic table
        (schemas.topics); ``drop`` overrides its congestion control."""
        self.topic = topic
        self.key = bus.key(topic)
        self.msg_type = msg_type
        self._bus = bus
        self._seq = 0
        self._lock = threading.Lock()
        opts, history = publisher_options(topic, drop=drop)
        self._pub: zenoh.Publisher | zenoh.ext.AdvancedPublisher
        self._probe: zenoh.Publisher | None = None
        if history:
            # zenoh-ext advanced publisher: a subscriber that joins late (a
            # restarted solver, a reopened UI) receives the cached samples
            # and a heartbeat (the last sequence number, every HEARTBEAT_S) lets a
            # subscriber that missed the last sample (cut off by a partition while
            # it went out) notice and fetch it from the cache once the link heals
            self._pub = zenoh.ext.declare_advanced_publisher(
                bus.zenoh,
                self.key,
                cache=zenoh.ext.CacheConfig(max_samples=history),
                sample_miss_detection=zenoh.ext.MissDetectionConfig(heartbeat=HEARTBEAT_S, sporadic_heartbeat=None),
                publisher_detection=True,
                **opts,
            )
            # AdvancedPublisher has no matching status: a plain publisher that
            # never sends answers "does anyone subscribe here?"
            self._probe = bus.zenoh.declare_publisher(self.key)
        else:
            self._pub = bus.zenoh.declare_publisher(self.key, **opts)

    def put(self, msg: M) -> int:
        """Send ``msg`` (validated); returns its seq."""
        if not isinstance(msg, self.msg_type):
            raise TypeError(f"{self.key} carries {self.msg_type.TYPE}, got {type(msg).__name__}")
        with self._lock:
            self._seq += 1
            msg.seq = self._seq
            if not msg.stamp_ns:
                msg.stamp_ns = time.time_ns()
            data = encode(msg)
            self._pub.put(data)
        self._bus.stats.count(f"sent/{self.topic}")
        return msg.seq

    def put_raw(self, data: bytes) -> None:
        """Send an already encoded payload as is (replay)."""
        self._pub.put(data)

    def matching(self) -> bool:
        """Whether any subscriber matches this key now."""
        return has_subscribers(self._probe if self._probe is not None else self._pub)

    def wait_matching(self, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.matching():
                return True
            time.sleep(0.01)
        return self.matching()

    def close(self) -> None:
        try:
            if self._probe is not None:
                self._probe.undeclare()
            self._pub.undeclare()
        except Exception:  # session already closed
            pass


class Bus:
    """One Zenoh session scoped to ``couture/<session>/``. Use as a context manager."""

    def __init__(self, cfg: BusConfig, *, name: str = "") -> None:
        self.cfg = cfg
        self.name = name
        self.prefix = f"couture/{cfg.session}"
        self.stats = Stats()
        self.zenoh = zenoh.open(cfg.zenoh_config(name))
        self._closeables: list[Any] = []
        self._workers: list[threading.Thread] = []
        self._closed = threading.Event()
        self._bad_keys: set[str] = set()
        """keys a bad message was logged for (later ones are only counted)"""

    # -- keys
    def key(self, topic: str) -> str:
        return f"{self.prefix}/{topic}"

    def topic_of(self, key: str) -> str:
        """Relative topic of a full key (the key itself if outside the session)."""
        p = self.prefix + "/"
        return key[len(p) :] if key.startswith(p) else key

    # -- publish / subscribe
    def publisher(self, topic: str, msg_type: type[M], *, drop: bool | None = None) -> TypedPublisher[M]:
        """A typed, reliable publisher on ``couture/<session>/<topic>``, delivered
        as the topic table says (schemas.topics: history, express, drop)."""
        p = TypedPublisher(self, topic, msg_type, drop=drop)
        self._closeables.append(p)
        return p

    def subscribe(
        self,
        topic: str,
        callback: Callable[..., Any],
        expected: type[Message] | None = None,
        *,
        with_topic: bool = False,
        history: bool | None = None,
    ) -> Any:
        """Call ``callback(msg)`` (or ``callback(topic, msg)`` with with_topic) for
        every valid message on ``couture/<session>/<topic>`` (wildcards ok).

        The expected type defaults to the type the topic carries. A payload that
        fails validation is logged with key and reason, counted as
        ``bad_messages`` (and ``bad/<table key>``, e.g. ``bad/status/*``) and
        dropped, as is a payload above the topic's ``max_bytes``; a callback exception is logged, counted as
        ``callback_errors`` and never propagates into Zenoh.

        Callbacks run on a Zenoh thread: hand long work to a worker thread.
        """
        if expected is None:
            expected = topics.type_for_keyexpr(topic)

        def on_sample(sample: zenoh.Sample) -> None:
            key = str(sample.key_expr)
            rel = self.topic_of(key)
            try:
                data = sample.payload.to_bytes()
                topics.check_size(rel, len(data))  # a huge payload is dropped unread
                want = expected or topics.type_for_topic(rel)
                msg = decode(data, want)
            except SchemaError as e:
                self.stats.count("bad_messages")
                spec = topics.topic_spec(rel)
                self.stats.count(f"bad/{spec.key if spec else rel}")
                self.stats.error(f"bad message on {key}: {e}")
                # a flood must not flood the log too: the first per key is a warning, the rest are counted
                first = key not in self._bad_keys
                self._bad_keys.add(key)
                log.log(logging.WARNING if first else logging.DEBUG, "dropped bad message on %s: %s", key, e)
                return
            self.stats.count(f"recv/{rel}")
            try:
                if with_topic:
                    callback(rel, msg)
                else:
                    callback(msg)
            except Exception as e:
                self.stats.count("callback_errors")
                self.stats.error(f"callback for {key} raised {type(e).__name__}: {e}")
                log.error("callback for %s raised:\n%s", key, traceback.format_exc())

        n_history = topics.history_for_subscription(topic)
        if history is None:
            history = n_history > 0
        sub: zenoh.Subscriber | zenoh.ext.AdvancedSubscriber
        if history:  # late joiners get the cached samples of the topics that keep some
            sub = zenoh.ext.declare_advanced_subscriber(
                self.zenoh,
                self.key(topic),
                on_sample,
                history=zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=max(n_history, 1)),
                recovery=zenoh.ext.RecoveryConfig(periodic_queries=None, heartbeat=True),
            )
        else:
            sub = self.zenoh.declare_subscriber(self.key(topic), on_sample)
        self._closeables.append(sub)
        return sub

    def subscribe_raw(self, keyexpr: str, callback: Callable[[str, bytes, int], Any]) -> Any:
        """``callback(full_key, payload, receive_time_ns)`` for every sample on an
        absolute key expression (the recorder uses it). Exceptions are contained."""

        def on_sample(sample: zenoh.Sample) -> None:
            t = time.time_ns()
            try:
                callback(str(sample.key_expr), sample.payload.to_bytes(), t)
            except Exception as e:
                self.stats.count("callback_errors")
                self.stats.error(f"raw callback raised {type(e).__name__}: {e}")
                log.error("raw callback for %s raised:\n%s", sample.key_expr, traceback.format_exc())

        sub = self.zenoh.declare_subscriber(keyexpr, on_sample)
        self._closeables.append(sub)
        return sub

    # -- liveliness
    def declare_token(self, node: str) -> Any:
        """Announce ``node`` alive at couture/<session>/status/<node> until closed."""
        tok = self.zenoh.liveliness().declare_token(self.key(f"status/{node}"))
        self._closeables.append(tok)
        return tok

    def live_nodes(self, timeout: float = 1.0) -> list[str]:
        """Names of nodes whose liveliness token is alive now."""
        names = []
        for reply in self.zenoh.liveliness().get(self.key("status/*"), timeout=timeout):
            if reply.ok is not None:
                names.append(self.topic_of(str(reply.ok.key_expr)).split("/", 1)[1])
        return sorted(set(names))

    def watch_nodes(self, callback: Callable[[str, bool], Any], *, history: bool = True) -> Any:
        """``callback(node, alive)`` when a node appears (True) or disappears (False)."""

        def on_sample(sample: zenoh.Sample) -> None:
            node = self.topic_of(str(sample.key_expr)).split("/", 1)[1]
            try:
                callback(node, sample.kind == zenoh.SampleKind.PUT)
            except Exception:
                self.stats.count("callback_errors")
                log.error("liveliness callback raised:\n%s", traceback.format_exc())

        sub = self.zenoh.liveliness().declare_subscriber(self.key("status/*"), on_sample, history=history)
        self._closeables.append(sub)
        return sub

    def wait_nodes(self, nodes: list[str], timeout: float) -> list[str]:
        """Wait until every named node is live; returns the ones still missing."""
        deadline = time.monotonic() + timeout
        missing = list(nodes)
        while True:
            live = set(self.live_nodes(timeout=min(1.0, max(0.1, deadline - time.monotonic()))))
            missing = [n for n in nodes if n not in live]
            if not missing or time.monotonic() >= deadline:
                return missing
            time.sleep(0.05)

    # -- solve request / reply
    def serve_solve(self, solver: str, handler: Callable[[SolveRequestMsg], SolveResultMsg]) -> None:
        """Answer ``solve/<solver>`` queries with ``handler`` on a worker thread
        (one request at a time), mirroring each result on solve/result/<solver>."""
        if solver in RESERVED_SOLVER_NAMES or "/" in solver or not solver:
            raise ValueError(f"solver name {solver!r} is reserved or invalid")
        result_pub = self.publisher(f"solve/result/{solver}", SolveResultMsg)
        pending: queue.Queue = queue.Queue()

        def on_query(query: zenoh.Query) -> None:
            pending.put(query)

        qbl = self.zenoh.declare_queryable(self.key(f"solve/{solver}"), on_query, complete=True)
        self._closeables.append(qbl)

        def work() -> None:
            while not self._closed.is_set():
                try:
                    query = pending.get(timeout=0.1)
                except queue.Empty:
                    continue
                try:
                    payload = query.payload.to_bytes() if query.payload is not None else b""
                    try:
                        topics.check_size("solve/request", len(payload))
                        req = decode(payload, SolveRequestMsg)
                    except SchemaError as e:
                        self.stats.count("bad_messages")
                        self.stats.count(f"bad/solve/{solver}")
                        self.stats.error(f"bad solve request: {e}")
                        query.reply_err(str(e).encode())
                        continue
                    try:
                        res = handler(req)
                    except Exception as e:
                        self.stats.count("callback_errors")
                        self.stats.error(f"solve handler raised {type(e).__name__}: {e}")
                        log.error("solve handler raised:\n%s", traceback.format_exc())
                        res = SolveResultMsg(error=f"{type(e).__name__}: {e}")
                    res.request_id = req.request_id
                    res.solver = solver
                    res.generation = res.generation or req.generation
                    result_pub.put(res)  # mirror first: the recording sees it even if the requester is gone
                    query.reply(self.key(f"solve/{solver}"), encode(res))
                except Exception:
                    log.error("solve reply failed:\n%s", traceback.format_exc())
                finally:
                    try:
                        query.drop()
                    except Exception:
                        pass

        t = threading.Thread(target=work, name=f"solve-{solver}", daemon=True)
        t.start()
        self._workers.append(t)

    def solve(self, request: SolveRequestMsg, *, solver: str = "", timeout: float = 120.0) -> SolveResultMsg:
        """Ask a solver (``solver`` or request.solver; '' for any) and wait for its
        result. The request is mirrored on solve/request. Raises TimeoutError if
        no solver answers, RuntimeError with the solver's text on an error reply."""
        name = solver or request.solver
        if not request.request_id:
            request.request_id = uuid.uuid4().hex
        if not request.stamp_ns:
            request.stamp_ns = time.time_ns()
        if not hasattr(self, "_request_pub"):
            self._request_pub = self.publisher("solve/request", SolveRequestMsg)
        self._request_pub.put(request)
        key = self.key(f"solve/{name}" if name else "solve/*")
        replies = self.zenoh.get(
            key,
            payload=encode(request),
            timeout=timeout,
            target=zenoh.QueryTarget.BEST_MATCHING,
            congestion_control=zenoh.CongestionControl.BLOCK,
        )
        for reply in replies:
            if reply.ok is not None:
                try:
                    return decode(reply.ok.payload.to_bytes(), SolveResultMsg)
                except SchemaError as e:
                    raise RuntimeError(f"solver on {reply.ok.key_expr} sent an invalid result: {e}") from None
            why = reply.err.payload.to_bytes().decode(errors="replace") if reply.err is not None else "empty reply"
            raise RuntimeError(f"solver on {key} failed: {why}")
        live = self.live_nodes(timeout=0.5)
        raise TimeoutError(f"no solver answered on {key} within {timeout:g} s (live nodes: {live or 'none'})")

    # -- lifecycle
    def close(self) -> None:
        if self._closed.is_set():
            return
        self._closed.set()
        for w in self._workers:
            w.join(timeout=2.0)
        for c in reversed(self._closeables):
            try:
                c.undeclare()
            except Exception:
                pass
        self._closeables.clear()
        try:
            self.zenoh.close()
        except Exception:
            pass

    def __enter__(self) -> "Bus":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

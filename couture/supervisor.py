"""``couture up``: every node as its own OS process, restarted when it crashes.

Topology: the supervisor opens a Zenoh *router* session listening on
loopback (``tcp/127.0.0.1:7447`` if free, else a free port, unless
``--listen`` names one; the endpoint is printed); every child is a peer that connects to it (``--connect``) and listens
on a free loopback port itself, so peers also find each other by gossip.
Nothing binds a non-loopback interface unless asked. With ``--tls DIR``
(``SupervisorConfig.bus.tls``) every endpoint is ``tls/`` instead, the router
uses the certificate ``DIR/router.pem`` and each child its own
(couture.bus.secure).

Which nodes run, and with what configuration, is data: a node graph
(couture/graph.py; ``couture/graphs/default.toml`` without ``--graph``).
:func:`graph_nodes` turns the part of a graph placed on one machine into
:class:`NodeSpec` s, each node's flags written from its configuration with its
Config's own flags (couture.bus.nodeargs).

Several machines: a graph declares them (``[machines.<name>]`` with the
router's ``listen`` or ``connect`` endpoints) and places each node on one;
each machine runs ``couture up --graph FILE --machine NAME``. One router
listens on its network address, the others connect to it, so their routers
link and each machine's nodes reach the others through them; a router that
loses the link reconnects by itself once it is back (tests/test_netns.py).
``couture up --only <kinds>`` (:func:`only_nodes`) still starts a part of the
default graph.

Children are started with ``subprocess`` (fork + immediate exec: no Zenoh
state crosses it) in their own process group, with ``COUTURE_PARENT_PID`` so
they stop by themselves if the supervisor dies. A child that exits is
restarted after an exponential backoff (``backoff_initial_s`` doubling up to
``backoff_max_s``; reset once it has run ``stable_after_s``). Shutdown
(SIGINT/SIGTERM): SIGTERM to every child's group (the recorder last, so it
records the others leaving), wait ``term_timeout_s``, SIGKILL stragglers.

The recorder (``--record FILE``) gets one run id for the whole ``up``: the
file it writes is never reopened for writing, so a recorder restarted after
a crash writes ``<stem>.1.mcap``, ``<stem>.2.mcap``, ... (FILE itself when it
did not exist yet), and ``couture replay FILE`` reads them as one recording.

Adding a node: a kind in couture.graph.KINDS (module ``nodes.<kind>`` with a
``Config`` and a ``__main__`` calling ``run_node``) and a ``[nodes.<name>]``
table in a graph.
"""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import threading
import time
import uuid
from dataclasses import dataclass, field

from couture.bus import DEFAULT_PORT, PARENT_PID_ENV, Bus, BusConfig, StopFlag, open_session
from couture.bus.ports import free_port, port_is_free
from couture.bus.secure import ROUTER_NAME, node_files
from couture.graph import KINDS, Graph, load_graph

log = logging.getLogger("couture.supervisor")


@dataclass
class NodeSpec:
    """One child process: ``python -m <module> <bus flags> --name <name> <args>``."""

    name: str
    module: str
    args: list[str] = field(default_factory=list)
    restart: bool = True
    stop_last: bool = False
    """stopped after the others (the recorder)"""
    kind: str = ""
    """its node kind (``couture up --only`` selects by it); '' : the name before its first '-'"""

    @property
    def kind_or_name(self) -> str:
        return self.kind or self.name.split("-", 1)[0]


@dataclass
class SupervisorConfig:
    bus: BusConfig = field(default_factory=BusConfig)
    """the supervisor's own session: listen endpoints (loopback), session name"""
    nodes: list[NodeSpec] = field(default_factory=list)
    ui_url: str = ""
    """printed once the ui node is up ('' when there is no ui)"""
    backoff_initial_s: float = 0.5
    backoff_max_s: float = 30.0
    stable_after_s: float = 10.0
    term_timeout_s: float = 5.0
    python: str = sys.executable
    child_log: str | None = None
    """file the children's stdout and stderr are appended to (their lifecycle
    and library logs); None: they share the supervisor's terminal"""


def graph_nodes(graph: Graph, machine: str | None = None) -> list[NodeSpec]:
    """The nodes ``graph`` places on ``machine`` (None: a graph without machines), as child processes."""
    return [NodeSpec(n.name, KINDS[n.kind].module, graph.args(n), kind=n.kind) for n in graph.on_machine(machine)]


def recorder_node(record: str) -> NodeSpec:
    """The recorder writing ``record``, with one run id for every restart: a
    restarted recorder writes the next numbered part of this recording (never
    over the file it had open)."""
    run_id = uuid.uuid4().hex
    return NodeSpec(
        "recorder",
        "couture.recording",
        ["--out", record, "--quiet", "--run-id", run_id],
        stop_last=True,
        kind="recorder",
    )


def default_nodes(
    *,
    solvers: list[str] | None = None,
    ui: bool = True,
    ui_host: str = "127.0.0.1",
    ui_port: int = 8080,
    record: str | None = None,
    adjust: bool = False,
) -> list[NodeSpec]:
    """The default graph (couture/graphs/default.toml) as child processes:
    remesher, one solver node per solver name (default: the graph's, newton),
    sensitivity, the adjust node (``couture up`` starts it, tests ask for it),
    ui, and the recorder when ``record`` names a file."""
    graph = load_graph()
    if solvers:
        graph = graph.with_solvers(solvers)
    if not adjust:
        graph = graph.without("adjust")
    if not ui:
        graph = graph.without("ui")
    else:
        graph.set("ui", "host", ui_host)
        graph.set("ui", "port", str(ui_port))
    nodes = graph_nodes(graph)
    if record:
        nodes.append(recorder_node(record))
    return nodes


def node_kinds() -> tuple[str, ...]:
    """What ``couture up --only`` selects by: a node kind (every node of it), or the recorder."""
    return (*KINDS, "recorder")


NODE_KINDS = node_kinds()


def only_nodes(nodes: list[NodeSpec], kinds: list[str] | None) -> list[NodeSpec]:
    """The nodes of ``kinds`` (``None``: all of them), for ``couture up --only``:
    one machine runs some nodes, another the rest (``--only solver`` keeps every
    solver node). A node's name selects it too. A kind none of ``nodes`` is
    raises ValueError naming it."""
    if kinds is None:
        return list(nodes)
    names = {n.name for n in nodes}
    unknown = [k for k in kinds if k not in NODE_KINDS and k not in names]
    if unknown:
        raise ValueError(
            f"--only {' '.join(unknown)}: not a node kind (one of {', '.join(NODE_KINDS)}) nor a node's name"
        )
    picked = [n for n in nodes if n.kind_or_name in kinds or n.name in kinds]
    missing = [k for k in kinds if not any(k in (n.kind_or_name, n.name) for n in picked)]
    if missing:
        hint = {"recorder": " (the recorder needs --record FILE)", "ui": " (not with --no-ui)"}
        raise ValueError("--only " + ", ".join(f"{k}: no such node here{hint.get(k, '')}" for k in missing))
    return picked


@dataclass
class _Child:
    spec: NodeSpec
    proc: subprocess.Popen | None = None
    started: float = 0.0
    restarts: int = 0
    backoff: float = 0.0
    restart_at: float | None = None


class Supervisor:
    """Starts, watches and stops the node processes. Context manager."""

    def __init__(self, config: SupervisorConfig) -> None:
        self.config = config
        cfg = config.bus
        proto = "tls" if cfg.tls else "tcp"
        if cfg.listen and cfg.listen != ["tcp/127.0.0.1:0"]:
            listen = list(cfg.listen)
        else:  # the well-known port (what Client connects to by default), or any free one
            listen = [f"{proto}/127.0.0.1:{DEFAULT_PORT if port_is_free(DEFAULT_PORT) else free_port()}"]
        self.bus_config = BusConfig(
            session=cfg.session,
            connect=list(cfg.connect),
            listen=listen,
            mode="router",
            config_file=cfg.config_file,
            multicast=cfg.multicast,
            tls=cfg.tls,
            tls_name=ROUTER_NAME if cfg.tls else "",
        )
        self.child_bus = BusConfig(
            session=cfg.session,
            connect=listen,
            listen=[f"{proto}/127.0.0.1:0"],
            mode="peer",
            # the user's Zenoh settings hold for every node; the explicit
            # endpoints and mode above still win over the file's
            config_file=cfg.config_file,
            multicast=cfg.multicast,
            tls=cfg.tls,
        )
        if cfg.tls:  # a node without a certificate would only crash and restart: say so now
            for spec in config.nodes:
                node_files(cfg.tls, spec.name)
        self.children = {s.name: _Child(s) for s in config.nodes}
        self.bus: Bus | None = None
        self.events: list[tuple[str, bool]] = []

    @property
    def endpoint(self) -> str:
        """Where nodes and clients connect (``--connect``)."""
        return self.bus_config.listen[0]

    def pids(self) -> dict[str, int]:
        return {n: c.proc.pid for n, c in self.children.items() if c.proc is not None and c.proc.poll() is None}

    def __enter__(self) -> "Supervisor":
        bus = self.bus = open_session(self.bus_config, name="supervisor")
        bus.watch_nodes(self._on_liveliness, history=False)
        for c in self.children.values():
            self._spawn(c)
        # restarts happen however the supervisor is used (``couture up``,
        # ``couture drape``, golden runs, tests)
        self._monitor_stop = threading.Event()
        self._monitor = threading.Thread(target=self._watch, name="supervisor", daemon=True)
        self._monitor.start()
        return self

    def _watch(self) -> None:
        while not self._monitor_stop.wait(0.1):
            try:
                self.poll()
            except Exception:
                log.exception("supervisor poll failed")

    def __exit__(self, *exc: object) -> None:
        try:
            self._monitor_stop.set()
            self._monitor.join(timeout=2.0)
            self.stop_children()
        finally:
            if self.bus is not None:
                self.bus.close()

    def _on_liveliness(self, node: str, alive: bool) -> None:
        self.events.append((node, alive))
        log.info("node %s %s", node, "is up" if alive else "went away")

    def _spawn(self, c: _Child) -> None:
        cmd = [self.config.python, "-m", c.spec.module, *self.child_bus.to_args(), "--name", c.spec.name, *c.spec.args]
        env = dict(os.environ, **{PARENT_PID_ENV: str(os.getpid())})
        if self.config.child_log:
            # the child holds its own descriptor, so closing ours here is safe
            with open(self.config.child_log, "ab") as out:
                c.proc = subprocess.Popen(
                    cmd, env=env, start_new_session=True, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT
                )
        else:
            c.proc = subprocess.Popen(cmd, env=env, start_new_session=True, stdin=subprocess.DEVNULL)
        c.started = time.monotonic()
        c.restart_at = None
        log.info("started %s (pid %d): %s", c.spec.name, c.proc.pid, " ".join(cmd[1:3]))

    def stop_node(self, name: str) -> None:
        """Stop one child for good (SIGTERM, then SIGKILL after ``term_timeout_s``): not restarted."""
        self._terminate([self.children[name]])

    def start_node(self, spec: NodeSpec) -> None:
        """Start one more child (a name already stopped is started afresh)."""
        c = self.children[spec.name] = _Child(spec)
        self._spawn(c)

    def kill_node(self, name: str) -> int:
        """SIGKILL one child's process group, as a crash would (it is restarted
        after its backoff when its spec says so); returns the pid killed."""
        proc = self.children[name].proc
        if proc is None or proc.poll() is not None:
            raise RuntimeError(f"node {name} is not running")
        _signal_group(proc, signal.SIGKILL)
        return proc.pid

    def poll(self) -> None:
        """Restart children that exited, after their backoff."""
        now = time.monotonic()
        for c in list(self.children.values()):
            if c.proc is None:
                continue
            code = c.proc.poll()
            if code is None:
                if c.backoff and now - c.started > self.config.stable_after_s:
                    c.backoff = 0.0
                continue
            if not c.spec.restart:
                continue
            if c.restart_at is None:
                c.backoff = min(
                    self.config.backoff_max_s, c.backoff * 2 if c.backoff else self.config.backoff_initial_s
                )
                c.restart_at = now + c.backoff
                log.warning(
                    "node %s (pid %d) exited with code %s after %.1f s; restart %d in %.1f s",
                    c.spec.name,
                    c.proc.pid,
                    code,
                    now - c.started,
                    c.restarts + 1,
                    c.backoff,
                )
                print(
                    f"[up] node {c.spec.name} (pid {c.proc.pid}) exited with code {code}; restarting in {c.backoff:.1f} s",
                    file=sys.stderr,
                    flush=True,
                )
            elif now >= c.restart_at:
                c.restarts += 1
                self._spawn(c)

    def run(self, stop: StopFlag) -> None:
        """Block until ``stop`` is set (SIGINT/SIGTERM); the monitor thread restarts nodes."""
        stop.wait()

    def stop_children(self) -> None:
        first = [c for c in self.children.values() if not c.spec.stop_last]
        last = [c for c in self.children.values() if c.spec.stop_last]
        for group in (first, last):
            self._terminate(group)

    def _terminate(self, group: list[_Child]) -> None:
        live = [(c.spec.name, c.proc) for c in group if c.proc is not None and c.proc.poll() is None]
        for _, proc in live:
            _signal_group(proc, signal.SIGTERM)
        deadline = time.monotonic() + self.config.term_timeout_s
        for name, proc in live:
            try:
                proc.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                log.warning("node %s (pid %d) ignored SIGTERM; killing", name, proc.pid)
                _signal_group(proc, signal.SIGKILL)
                proc.wait()
        for c in group:  # grandchildren left in a group whose leader already exited
            if c.proc is not None:
                _signal_group(c.proc, signal.SIGKILL)
        for c in group:
            c.spec.restart = False


def _signal_group(proc: subprocess.Popen, sig: int) -> None:
    try:
        os.killpg(proc.pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def main(config: SupervisorConfig) -> int:
    stop = StopFlag().install()
    try:
        with Supervisor(config) as sup:
            print(
                f"[up] session {config.bus.session}: connect nodes and clients with --connect {sup.endpoint} "
                f"--session {config.bus.session}",
                file=sys.stderr,
                flush=True,
            )
            for name, pid in sup.pids().items():
                print(f"[up]   {name:<18} pid {pid}", file=sys.stderr, flush=True)
            if config.ui_url:
                print(f"[up] UI: {config.ui_url}", flush=True)
            sup.run(stop)
            print("[up] stopping nodes...", file=sys.stderr, flush=True)
    finally:
        stop.restore()
    return 0

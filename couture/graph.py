"""The node graph as data: which nodes run, what each takes and gives, how
each is configured, and on which machine (dora's ``dataflow.yml``).

A graph is a TOML file (``couture/graphs/default.toml`` is today's demo on one
machine; ``couture up --graph FILE``)::

    clients_give = ["pattern", "edit", "tryon", "adjust"]   # what scripts may publish

    [machines.a]                      # optional: several machines
    listen = ["tcp/10.0.0.1:7447"]    # the supervisor's router there
    [machines.b]
    connect = ["tcp/10.0.0.1:7447"]

    [nodes.solver-newton]             # the node's name (--name, status/<name>)
    kind = "solver"                   # python -m nodes.solver
    machine = "b"                     # where it runs (only with [machines])
    takes = ["pattern", "mesh/coarse", ...]
    gives = ["drape/coarse", "drape/fine", ...]
    config = { solver = "newton", max_seconds = 60.0 }   # fields of nodes.solver.main.Config

:func:`load_graph` checks everything before a process starts and raises
:class:`GraphError` naming each problem: an unknown kind, key, machine or
topic (topics are the rows of ``schemas/topics.py``), ``takes``/``gives`` that
differ from what the kind subscribes to and publishes (:data:`KINDS`, which
``tests/test_graph.py`` checks against each node's source), a topic taken that
no node nor client gives, a config key that is not a field of the kind's
Config, a value of the wrong type or out of its choices. Every node also
gives ``status/<its name>`` (the bus does it), so ``status/*`` is not listed.

A node's command line is made from its config with the Config's own flags
(:mod:`couture.bus.nodeargs`): the graph holds values, never flags. A path
in a config (the UI's ``design``, ``export_dir``) is taken as a command line
would take it: relative to the directory ``couture up`` runs in.

The kinds' Config classes are read from ``nodes.<kind>.main`` by name, the way
the supervisor starts ``python -m nodes.<kind>``: nodes are plugins the data
names, and nothing here imports them statically (the layer rules hold).
"""

from __future__ import annotations

import copy
import importlib
import re
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

from couture.bus.nodeargs import Option, check_value, convert_text, format_value, options
from schemas.topics import TOPICS

STATUS = "status/*"
"""what every node gives (its status and liveliness, published by the bus)"""


@dataclass(frozen=True)
class NodeKind:
    """What one kind of node is: its module, Config, inputs and outputs."""

    module: str
    """``python -m <module>`` starts it; its Config is ``<module>.main.Config``"""
    takes: tuple[str, ...]
    """topics it subscribes to (rows of the topic table)"""
    gives: tuple[str, ...]
    """topics it publishes (besides status/<name>)"""
    optional: tuple[str, ...] = ()
    """taken topics it works without (nothing in the graph need give them)"""

    def config_class(self) -> type:
        config: type = importlib.import_module(f"{self.module}.main").Config
        return config

    def options(self) -> dict[str, Option]:
        """Its Config's fields that a graph may set (not the bus, not the name), by field name."""
        return {o.field: o for o in options(self.config_class()) if o.field != "name"}


KINDS: dict[str, NodeKind] = {
    "remesher": NodeKind(
        "nodes.remesher",
        takes=("pattern", "edit", "mesh/coarse", "mesh/fine", "drape/coarse", "drape/fine"),
        gives=("mesh/coarse", "mesh/fine", "psi/coarse", "psi/fine", "rejected"),
        optional=("edit", "drape/coarse", "drape/fine"),
    ),
    "solver": NodeKind(
        "nodes.solver",
        takes=("pattern", "edit", "tryon", "mesh/coarse", "mesh/fine", "drape/predicted"),
        gives=("drape/coarse", "drape/fine", "rejected", "solve/result/*"),
        optional=("edit", "tryon", "drape/predicted"),
    ),
    "sensitivity": NodeKind(
        "nodes.sensitivity",
        takes=("pattern", "edit", "mesh/fine", "psi/fine", "drape/fine"),
        gives=("drape/predicted", "pattern"),
        optional=("edit",),
    ),
    "adjust": NodeKind("nodes.adjust", takes=("adjust",), gives=("adjust/status", "pattern")),
    "ui": NodeKind(
        "nodes.ui",
        takes=(
            "pattern",
            "edit",
            "mesh/coarse",
            "mesh/fine",
            "drape/predicted",
            "drape/coarse",
            "drape/fine",
            "rejected",
            "adjust/status",
            STATUS,
        ),
        gives=("pattern", "edit", "tryon", "adjust"),
        optional=("edit", "drape/predicted", "drape/coarse", "rejected", "adjust/status"),
    ),
}
"""Every node kind. Adding one: a ``nodes/<kind>/`` package whose ``main.py``
has a ``Config`` dataclass and a ``main(config)``, and a row here."""

DEFAULT_GRAPH = "default.toml"
"""in couture/graphs/: what ``couture up`` runs without --graph"""

_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_-]*$")
_TOP_KEYS = {"description", "clients_give", "machines", "nodes"}
_NODE_KEYS = {"kind", "machine", "takes", "gives", "config"}
_MACHINE_KEYS = {"listen", "connect"}


class GraphError(ValueError):
    """A node graph that cannot run; the message names every problem found."""


@dataclass
class Machine:
    name: str
    listen: list[str] = field(default_factory=list)
    """endpoints the supervisor's router listens on there ([]: loopback)"""
    connect: list[str] = field(default_factory=list)
    """routers it connects to (another machine's listen endpoint)"""


@dataclass
class GraphNode:
    name: str
    kind: str
    takes: list[str]
    gives: list[str]
    config: dict[str, Any] = field(default_factory=dict)
    """field name -> value (Config form: Path for a path, float for a float)"""
    machine: str | None = None


@dataclass
class Graph:
    nodes: list[GraphNode]
    machines: dict[str, Machine] = field(default_factory=dict)
    clients_give: list[str] = field(default_factory=list)
    description: str = ""
    source: str = "<graph>"
    """where it was read from (for messages)"""

    def node(self, name: str) -> GraphNode:
        for n in self.nodes:
            if n.name == name:
                return n
        raise KeyError(name)

    def on_machine(self, machine: str | None) -> list[GraphNode]:
        """The nodes placed on ``machine``; every node when None (a graph without machines)."""
        if machine is None:
            if self.machines:
                raise GraphError(
                    f"{self.source}: the nodes are spread over machines {', '.join(self.machines)}: "
                    "say which one this is with --machine NAME"
                )
            return list(self.nodes)
        if machine not in self.machines:
            known = ", ".join(self.machines) or "none (the graph places no node on a machine)"
            raise GraphError(f"{self.source}: --machine {machine}: no such machine (declared: {known})")
        return [n for n in self.nodes if n.machine == machine]

    def without(self, kind: str) -> Graph:
        """A copy without the nodes of ``kind`` (``--no-ui``, ``--no-adjust``)."""
        g = copy.deepcopy(self)
        g.nodes = [n for n in g.nodes if n.kind != kind]
        return g

    def with_solvers(self, solvers: list[str]) -> Graph:
        """A copy with one ``solver-<name>`` node per solver name in place of its
        solver nodes (``couture up --solver kinetic newton``), each like the first."""
        g = copy.deepcopy(self)
        at = [i for i, n in enumerate(g.nodes) if n.kind == "solver"]
        if not at:
            raise GraphError(f"{self.source}: --solver: the graph has no solver node to run as {', '.join(solvers)}")
        template = g.nodes[at[0]]
        new = [
            replace(template, name=f"solver-{s}", config={**template.config, "solver": s}, takes=list(template.takes))
            for s in solvers
        ]
        g.nodes = g.nodes[: at[0]] + new + [n for n in g.nodes[at[0] :] if n.kind != "solver"]
        g.check()
        return g

    def set(self, node: str, key: str, text: str) -> None:
        """Set one config value from its command-line text (``couture up --set NODE.KEY=VALUE``);
        NODE is a node's name or a kind (every node of it); a list takes comma-separated items."""
        picked = [n for n in self.nodes if node in (n.name, n.kind)]
        if not picked:
            raise GraphError(f"--set {node}.{key}: no node or kind {node!r} in {self.source}")
        for n in picked:
            opts = KINDS[n.kind].options()
            if key not in opts:
                raise GraphError(f"--set {node}.{key}: {_unknown_key(n, key, opts)}")
            o = opts[key]
            try:
                items = (
                    [convert_text(o, t.strip()) for t in text.split(",") if t.strip()]
                    if o.many
                    else convert_text(o, text)
                )
            except ValueError as e:
                raise GraphError(f"--set {node}.{key}={text}: {e}") from None
            n.config[key] = items
        self.check()

    def args(self, node: GraphNode) -> list[str]:
        """The node's own flags (its config), written with its Config's flags."""
        opts = KINDS[node.kind].options()
        out: list[str] = []
        for key, value in node.config.items():
            out += format_value(opts[key], value)
        return out

    def check(self) -> None:
        """Raise GraphError listing every problem (see the module's docstring)."""
        errors = []
        names = [n.name for n in self.nodes]
        errors += [f"node {x}: named twice" for x in sorted({x for x in names if names.count(x) > 1})]
        for n in self.nodes:
            errors += _check_node(self, n)
        given = {t for n in self.nodes for t in [*n.gives, STATUS]} | set(self.clients_give)
        for n in self.nodes:
            if n.kind not in KINDS:
                continue
            for t in n.takes:
                if t in _TABLE and t not in given and t not in KINDS[n.kind].optional:
                    errors.append(
                        f"node {n.name}: takes {t!r} but no node gives it"
                        + (" nor do clients (clients_give)" if self.clients_give else " (and no clients_give lists it)")
                    )
        for t in self.clients_give:
            if t not in _TABLE:
                errors.append(f"clients_give: {t!r} is not a topic ({_topics_hint()})")
        if errors:
            raise GraphError(f"{self.source}: " + ("\n  " if len(errors) > 1 else "") + "\n  ".join(errors))


_TABLE = {t.key for t in TOPICS}


def _topics_hint() -> str:
    return "the topics are " + ", ".join(sorted(_TABLE)) + " (schemas/topics.py)"


def _unknown_key(n: GraphNode, key: str, opts: dict[str, Option]) -> str:
    cls = KINDS[n.kind].config_class()
    known = ", ".join(opts) or "none"
    why = " (the node's name is its table key)" if key == "name" else ""
    return f"{key!r} is not a field of {cls.__module__}.Config{why} (its fields: {known})"


def _check_node(g: Graph, n: GraphNode) -> list[str]:
    errors = []
    where = f"node {n.name}"
    if not _NAME.match(n.name):
        errors.append(f"{where}: a node name is letters, digits, '_' and '-'")
    kind = KINDS.get(n.kind)
    if kind is None:
        return errors + [f"{where}: unknown kind {n.kind!r} (kinds: {', '.join(KINDS)})"]
    for role, listed, declared, verb in (
        ("takes", n.takes, kind.takes, "subscribes to"),
        ("gives", n.gives, kind.gives, "publishes"),
    ):
        for t in listed:
            if t not in _TABLE:
                errors.append(f"{where}: {role} {t!r}, which is not a topic ({_topics_hint()})")
            elif t not in declared:
                errors.append(f"{where}: {role} {t!r}, but {kind.module} never {verb} it")
        for t in declared:
            if t not in listed:
                errors.append(f"{where}: {role} leaves out {t!r}, which {kind.module} {verb}")
    if g.machines and n.machine is None:
        errors.append(f"{where}: no machine (the graph declares {', '.join(g.machines)}: name one)")
    if n.machine is not None and n.machine not in g.machines:
        known = ", ".join(g.machines) or "none: add a [machines.NAME] table"
        errors.append(f"{where}: machine {n.machine!r} is not declared (machines: {known})")
    opts = kind.options()
    for key, value in n.config.items():
        if key not in opts:
            errors.append(f"{where}: config {_unknown_key(n, key, opts)}")
            continue
        try:
            n.config[key] = check_value(opts[key], value)
            parse = opts[key].parse
            if parse is not None:
                parse(str(value))  # a file named in the graph is read now, not after the node started
        except (ValueError, OSError) as e:
            errors.append(f"{where}: config {key} = {value!r}: {e}")
    return errors


def _strings(where: str, value: Any, errors: list[str]) -> list[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        errors.append(f"{where}: expected a list of strings, got {value!r}")
        return []
    return list(value)


def parse_graph(data: dict[str, Any], source: str = "<graph>") -> Graph:
    """A checked Graph from a TOML document's data; GraphError names every problem."""
    errors = [f"unknown key {k!r} (keys: {', '.join(sorted(_TOP_KEYS))})" for k in data if k not in _TOP_KEYS]
    machines = {}
    for name, m in (data.get("machines") or {}).items():
        if not isinstance(m, dict):
            errors.append(f"machines.{name}: expected a table, got {m!r}")
            continue
        errors += [f"machines.{name}: unknown key {k!r} (keys: listen, connect)" for k in m if k not in _MACHINE_KEYS]
        machines[name] = Machine(
            name,
            _strings(f"machines.{name}.listen", m.get("listen", []), errors),
            _strings(f"machines.{name}.connect", m.get("connect", []), errors),
        )
    nodes = []
    raw_nodes = data.get("nodes")
    if not isinstance(raw_nodes, dict) or not raw_nodes:
        errors.append("no [nodes.NAME] tables: a graph runs at least one node")
        raw_nodes = {}
    for name, d in raw_nodes.items():
        if not isinstance(d, dict):
            errors.append(f"nodes.{name}: expected a table, got {d!r}")
            continue
        errors += [
            f"node {name}: unknown key {k!r} (keys: {', '.join(sorted(_NODE_KEYS))})" for k in d if k not in _NODE_KEYS
        ]
        if not isinstance(d.get("kind"), str):
            errors.append(f"node {name}: no kind (one of {', '.join(KINDS)})")
            continue
        config = d.get("config", {})
        if not isinstance(config, dict):
            errors.append(f"node {name}: config must be a table, got {config!r}")
            config = {}
        machine = d.get("machine")
        if machine is not None and not isinstance(machine, str):
            errors.append(f"node {name}: machine must be a name, got {machine!r}")
            machine = None
        nodes.append(
            GraphNode(
                name,
                d["kind"],
                _strings(f"node {name}: takes", d.get("takes", []), errors),
                _strings(f"node {name}: gives", d.get("gives", []), errors),
                dict(config),
                machine,
            )
        )
    g = Graph(
        nodes,
        machines,
        _strings("clients_give", data.get("clients_give", []), errors),
        str(data.get("description", "")),
        source,
    )
    try:
        g.check()
    except GraphError as e:
        errors += str(e).removeprefix(f"{source}: ").strip().split("\n  ")
    if errors:
        raise GraphError(f"{source}: " + ("\n  " if len(errors) > 1 else "") + "\n  ".join(errors))
    return g


def load_graph(path: str | Path | None = None) -> Graph:
    """A checked Graph from a TOML file (None: the default graph, couture/graphs/default.toml)."""
    if path is None:
        text = resources.files("couture.graphs").joinpath(DEFAULT_GRAPH).read_text()
        source = f"couture/graphs/{DEFAULT_GRAPH}"
    else:
        try:
            text = Path(path).read_text()
        except OSError as e:
            raise GraphError(f"--graph {path}: {e.strerror or e}") from None
        source = str(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise GraphError(f"{source}: not TOML: {e}") from None
    return parse_graph(data, source)


__all__ = ["KINDS", "NodeKind", "Graph", "GraphNode", "Machine", "GraphError", "STATUS", "load_graph", "parse_graph"]

"""The node graph as data (couture/graph.py) and node command lines made from
their Configs (couture/bus/nodeargs.py): the default graph is today's demo,
every bad graph is refused with a message naming the problem, a graph over
two machines splits by --machine, each kind's declared topics are what its
source subscribes to and publishes, and every Config field of every kind
round-trips through its generated command line."""

from __future__ import annotations

import ast
import dataclasses
import json
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import pytest

from couture import supervisor
from couture.bus import BusConfig
from couture.bus.nodeargs import format_config, options, parse_config
from couture.cli import _parser, up_plan
from couture.graph import KINDS, STATUS, GraphError, load_graph, parse_graph
from schemas.topics import TOPICS, topics_matching

ROOT = Path(__file__).resolve().parents[1]
TWO_MACHINES = ROOT / "tests" / "graphs" / "two_machines.toml"


def default_data() -> dict[str, Any]:
    return tomllib.loads((ROOT / "couture" / "graphs" / "default.toml").read_text())


def plan(*argv: str):
    return up_plan(_parser().parse_args(["up", *argv]))


# --- the default graph is today's demo


def test_default_graph_is_the_single_machine_demo():
    # what couture up started before the graph was data (couture/supervisor.py default_nodes)
    config, graph = plan("--ui-port", "0")
    assert graph.machines == {}
    assert [(n.name, n.module, n.kind) for n in config.nodes] == [
        ("remesher", "nodes.remesher", "remesher"),
        ("solver-newton", "nodes.solver", "solver"),
        ("sensitivity", "nodes.sensitivity", "sensitivity"),
        ("adjust", "nodes.adjust", "adjust"),
        ("ui", "nodes.ui", "ui"),
    ]
    args = {n.name: n.args for n in config.nodes}
    assert args["solver-newton"] == ["--solver", "newton"]
    assert args["ui"] == ["--host", "127.0.0.1", "--port", "0"]
    assert args["remesher"] == args["sensitivity"] == args["adjust"] == []
    assert config.ui_url == "http://127.0.0.1:0/"
    # the helper the tests and scripts use gives the same set
    assert [(n.name, n.args) for n in supervisor.default_nodes(adjust=True, ui_port=0)] == [
        (n.name, n.args) for n in config.nodes
    ]


def test_up_flags_adjust_the_graph():
    config, _ = plan("--solver", "kinetic", "newton", "--no-ui", "--no-adjust", "--record", "s.mcap")
    assert [n.name for n in config.nodes] == ["remesher", "solver-kinetic", "solver-newton", "sensitivity", "recorder"]
    assert [n.args for n in config.nodes if n.kind == "solver"] == [["--solver", "kinetic"], ["--solver", "newton"]]
    assert config.ui_url == ""
    config, _ = plan("--only", "solver", "--solver", "verlet")
    assert [(n.name, n.args) for n in config.nodes] == [("solver-verlet", ["--solver", "verlet"])]
    config, _ = plan("--no-ui", "--set", "solver.max_seconds=30", "--set", "sensitivity.method=mls")
    args = {n.name: n.args for n in config.nodes}
    assert args["solver-newton"] == ["--solver", "newton", "--max-seconds", "30.0"]
    assert args["sensitivity"] == ["--method", "mls"]
    config, _ = plan("--no-ui", "--set", "adjust.solvers=solver-a,solver-b")
    assert {n.name: n.args for n in config.nodes}["adjust"] == ["--solver", "solver-a", "--solver", "solver-b"]


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--solver", "bogus"], ["solver-bogus", "'bogus' is not one of", "newton"]),
        (["--set", "solver.max_seconds=soon"], ["--set solver.max_seconds=soon", "soon"]),
        (["--set", "solver.iterations=3"], ["'iterations' is not a field of nodes.solver.main.Config", "max_seconds"]),
        (["--set", "nobody.port=3"], ["no node or kind 'nobody'"]),
        (["--set", "ui-port"], ["is not NODE.KEY=VALUE"]),
        (["--only", "solvers"], ["--only solvers: not a node kind"]),
        (["--solver", "newton", "newton"], ["node solver-newton: named twice"]),
        (["--only", "recorder"], ["recorder: no such node here (the recorder needs --record FILE)"]),
        (["--machine", "b"], ["--machine b: no such machine", "declared: none"]),
        (["--graph", str(TWO_MACHINES)], ["say which one this is with --machine NAME", "a, b"]),
        (["--graph", "/nonexistent/graph.toml"], ["--graph /nonexistent/graph.toml", "No such file"]),
    ],
)
def test_bad_up_flags_say_what_is_wrong(argv, words):
    with pytest.raises(ValueError) as e:
        plan("--no-ui", *argv)
    for w in words:
        assert w in str(e.value), str(e.value)


# --- several machines


def test_a_graph_over_two_machines_splits_by_machine():
    a, graph = plan("--graph", str(TWO_MACHINES), "--machine", "a")
    assert [n.name for n in a.nodes] == ["remesher", "sensitivity"]
    assert a.bus.listen == ["tcp/10.77.1.1:7447"] and a.bus.connect == []
    b, _ = plan("--graph", str(TWO_MACHINES), "--machine", "b")
    assert [(n.name, n.args) for n in b.nodes] == [("solver-newton", ["--solver", "newton"])]
    assert b.bus.connect == ["tcp/10.77.1.1:7447"]
    # every node is on exactly one machine
    assert sorted(n.name for m in graph.machines for n in graph.on_machine(m)) == sorted(n.name for n in graph.nodes)
    # the flags still win over the graph's endpoints
    b2, _ = plan("--graph", str(TWO_MACHINES), "--machine", "b", "--connect", "tcp/10.0.0.9:7447")
    assert b2.bus.connect == ["tcp/10.0.0.9:7447"]


# --- a bad graph file is refused, naming the problem


def _edit(change) -> dict[str, Any]:
    data = default_data()
    change(data)
    return data


def _refused(data: dict[str, Any]) -> str:
    with pytest.raises(GraphError) as e:
        parse_graph(data, "probe.toml")
    assert str(e.value).startswith("probe.toml: ")
    return str(e.value)


def _set(path: str, value: Any):
    def change(data: dict[str, Any]) -> None:
        *where, last = path.split(".")
        d = data
        for k in where:
            d = d.setdefault(k, {})
        d[last] = value

    return change


@pytest.mark.parametrize(
    "change, words",
    [
        (_set("nodes.remesher.kind", "remeshr"), ["node remesher: unknown kind 'remeshr'", "remesher, solver"]),
        (
            _set("nodes.remesher.gives", ["mesh/coarse", "mesh/fine", "rejected", "mesh/medium"]),
            ["node remesher: gives 'mesh/medium', which is not a topic", "schemas/topics.py"],
        ),
        (
            _set("nodes.remesher.gives", ["mesh/coarse", "mesh/fine", "rejected", "drape/fine"]),
            ["node remesher: gives 'drape/fine', but nodes.remesher never publishes it"],
        ),
        (
            _set("nodes.sensitivity.takes", ["pattern", "edit", "mesh/fine"]),
            ["node sensitivity: takes leaves out 'drape/fine', which nodes.sensitivity subscribes to"],
        ),
        (
            _set("nodes.solver-newton.config", {"solver": "newton", "max_secs": 3.0}),
            ["node solver-newton: config 'max_secs' is not a field of nodes.solver.main.Config", "max_seconds"],
        ),
        (
            _set("nodes.solver-newton.config", {"name": "x"}),
            ["'name' is not a field", "the node's name is its table key"],
        ),
        (
            _set("nodes.ui.config", {"port": "8080"}),
            ["node ui: config port = '8080': '8080' is a str, expected int"],
        ),
        (_set("nodes.ui.config", {"port": True}), ["config port = True: True is a bool, expected int"]),
        (
            _set("nodes.solver-newton.config", {"solver": "euler"}),
            ["config solver = 'euler': 'euler' is not one of kinetic, newton"],
        ),
        (
            _set("nodes.ui.config", {"design": "/nonexistent/pattern.json"}),
            ["node ui: config design = '/nonexistent/pattern.json'"],
        ),
        (
            _set("nodes.adjust.config", {"solvers": "solver-newton"}),
            ["config solvers = 'solver-newton'", "expected list of str"],
        ),
        (
            lambda d: (_set("clients_give", ["edit", "pattern"])(d), d["nodes"].pop("ui")),
            ["node adjust: takes 'adjust' but no node gives it nor do clients"],
        ),
        (_set("clients_give", ["edit", "pattern", "patterns"]), ["clients_give: 'patterns' is not a topic"]),
        (_set("nodes.remesher.machine", "gpu"), ["node remesher: machine 'gpu' is not declared", "[machines.NAME]"]),
        (
            _set("machines.a", {"listen": ["tcp/10.0.0.1:7447"]}),
            ["node remesher: no machine (the graph declares a: name one)"],
        ),
        (_set("machines.a", {"listen": "tcp/10.0.0.1:7447"}), ["machines.a.listen: expected a list of strings"]),
        (_set("machines.a", {"port": 7447}), ["machines.a: unknown key 'port'"]),
        (_set("nodes.remesher.config_", {}), ["node remesher: unknown key 'config_'"]),
        (_set("node", {}), ["unknown key 'node'"]),
        (_set("nodes", {}), ["no [nodes.NAME] tables"]),
        (_set("nodes.bad name", {"kind": "remesher"}), ["node bad name: a node name is letters"]),
    ],
)
def test_a_bad_graph_names_its_problem(change, words):
    message = _refused(_edit(change))
    for w in words:
        assert w in message, message


def test_every_problem_is_listed_at_once(tmp_path):
    data = _edit(_set("nodes.remesher.kind", "nope"))
    data["nodes"]["ui"]["config"] = {"colour": "red"}
    message = _refused(data)
    assert "unknown kind 'nope'" in message and "'colour' is not a field" in message
    bad = tmp_path / "bad.toml"
    bad.write_text("[nodes.remesher\nkind = 1\n")
    with pytest.raises(GraphError, match=r"bad\.toml: not TOML"):
        load_graph(bad)


def test_optional_inputs_need_no_giver():
    # the UI takes adjust/status; without the adjust node nothing gives it, and that is fine
    g = load_graph().without("adjust").without("sensitivity")
    g.check()
    assert "drape/predicted" in g.node("solver-newton").takes


# --- each kind's declared topics are what its code subscribes to and publishes


def _source_keys(kind: str) -> tuple[set[str], set[str]]:
    """Keys (f-string holes as '*') a node's source subscribes to and publishes on."""
    tree = ast.parse((ROOT / "nodes" / kind / "main.py").read_text())
    # loop variables over literal strings (``for lv in ("coarse", "fine")``) fill f-string holes
    values: dict[str, list[str]] = {}
    for node in ast.walk(tree):
        if isinstance(node, (ast.comprehension, ast.For)) and isinstance(node.target, ast.Name):
            if isinstance(node.iter, (ast.Tuple, ast.List)) and all(
                isinstance(e, ast.Constant) and isinstance(e.value, str) for e in node.iter.elts
            ):
                values.setdefault(node.target.id, []).extend(e.value for e in node.iter.elts)  # type: ignore[attr-defined]
    subs: set[str] = set()
    pubs = {STATUS}  # the bus publishes every node's status
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)):
            continue
        if node.func.attr == "serve_solve":
            pubs.add("solve/result/*")  # the bus mirrors each answer there
        if node.func.attr not in ("subscribe", "publisher") or not node.args:
            continue
        arg = node.args[0]
        if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
            keys = [arg.value]
        elif isinstance(arg, ast.JoinedStr):
            keys = [""]
            for v in arg.values:
                if isinstance(v, ast.Constant):
                    fill = [str(v.value)]
                elif isinstance(v, ast.FormattedValue) and isinstance(v.value, ast.Name) and v.value.id in values:
                    fill = values[v.value.id]
                else:
                    fill = ["*"]
                keys = [k + f for k in keys for f in fill]
        else:
            raise AssertionError(f"nodes/{kind}/main.py:{node.lineno}: a topic that is not a literal")
        (subs if node.func.attr == "subscribe" else pubs).update(keys)
    return subs, pubs


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_a_kinds_declared_topics_are_its_subscriptions_and_publishers(kind):
    subs, pubs = _source_keys(kind)
    rows = lambda keys: {t.key for k in keys for t in topics_matching(k)}  # noqa: E731
    declared = KINDS[kind]
    assert set(declared.takes) == rows(subs), f"nodes/{kind}/main.py subscribes to {sorted(subs)}"
    assert set(declared.gives) | {STATUS} == rows(pubs), f"nodes/{kind}/main.py publishes {sorted(pubs)}"
    assert set(declared.optional) <= set(declared.takes)
    assert {t.key for t in TOPICS} >= set(declared.takes) | set(declared.gives)


# --- command lines generated from the Configs


def _other(value: Any, opt) -> Any:
    """A value for ``opt`` unlike its default."""
    if opt.choices:
        return next(c for c in opt.choices if c != value)
    if opt.many:
        return [f"{opt.field}-1", f"{opt.field}-2"] if opt.base is str else [opt.base(1), opt.base(2)]
    base = opt.base
    if base is bool:
        return not value
    if base is int:
        return (value or 0) + 3
    if base is float:
        return (value or 0.0) + 1.25
    if base is Path:
        return Path("some dir") / opt.field
    return f"{opt.field} value"


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_every_config_field_round_trips_through_its_command_line(kind):
    cls = KINDS[kind].config_class()
    default = cls()
    # the defaults, then every field changed at once (files aside: they are read from a path)
    assert parse_config(cls, format_config(default)) == default
    changed = {o.field: _other(getattr(default, o.field), o) for o in options(cls) if o.parse is None}
    bus = BusConfig(session="s1", connect=["tcp/10.0.0.1:7447"], listen=["tcp/127.0.0.1:7555"], multicast=True)
    config = dataclasses.replace(default, bus=bus, **changed)
    assert parse_config(cls, format_config(config)) == config
    for o in options(cls):
        assert o.help, f"{cls.__module__}.Config.{o.field} has no docstring (its --help)"
    flags = [o.flag for o in options(cls)]
    assert len(flags) == len(set(flags))


def test_a_file_field_is_read_from_its_path(tmp_path):
    from couture.client import load_design

    cls = KINDS["ui"].config_class()
    src = ROOT / "recordings"
    design = next((p for p in sorted(ROOT.rglob("*.json")) if _is_design(p)), None)
    assert design is not None, f"no couture/design/v1 file under {src}"
    assert parse_config(cls, ["--design", str(design)]).design == load_design(design)
    with pytest.raises(TypeError, match="design is read from a file"):
        format_config(dataclasses.replace(cls(), design=load_design(design)))


def _is_design(p: Path) -> bool:
    if ".venv" in p.parts or "out" in p.parts or p.stat().st_size > 200_000:
        return False
    try:
        raw = json.loads(p.read_text())
    except (ValueError, UnicodeDecodeError):
        return False
    return isinstance(raw, dict) and raw.get("schema") == "couture/design/v1"


def test_solver_choices_and_default_come_from_one_place():
    from couture.solvers import SOLVERS

    cls = KINDS["solver"].config_class()
    solver = {o.field: o for o in options(cls)}["solver"]
    assert solver.choices == tuple(sorted(SOLVERS))
    assert parse_config(cls, []).solver == cls().solver == "newton"
    with pytest.raises(SystemExit):
        parse_config(cls, ["--solver", "euler"])


def test_a_node_prints_its_generated_help():
    r = subprocess.run(
        [sys.executable, "-m", "nodes.sensitivity", "--help"], capture_output=True, text=True, cwd=ROOT, timeout=60
    )
    assert r.returncode == 0, r.stderr
    for flag in ("--method {gmls,mls,linear}", "--pause-s", "--hold-s", "--connect", "--session", "--name"):
        assert flag in r.stdout, r.stdout
    r = subprocess.run(
        [sys.executable, "-m", "nodes.sensitivity", "--pause-s", "soon"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=60,
    )
    assert r.returncode == 2 and "--pause-s" in r.stderr and "soon" in r.stderr, r.stderr

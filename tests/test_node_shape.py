"""Every node has one shape (STYLE.md, "Nodes"): a class over its bus-free
service whose methods are the handlers of its inputs, and a ``main(config)``
that builds it on a Node and runs it. Checked on the source: every
subscription (and solve queryable) is made in an ``...Adapter`` class and
hands the bus a method of it (``self.on_x``), never a closure over shared
state."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NODES = sorted(p.parent.name for p in (ROOT / "nodes").glob("*/main.py"))
WIRING = {"subscribe", "serve_solve", "watch_nodes"}
"""bus calls that hand it a callback"""


def _wiring_calls(tree: ast.Module) -> list[tuple[str | None, ast.Call]]:
    """(enclosing class name or None, call) of every bus call that takes a callback."""
    out: list[tuple[str | None, ast.Call]] = []

    def visit(node: ast.AST, cls: str | None) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef):
                visit(child, child.name)
                continue
            if isinstance(child, ast.Call) and isinstance(child.func, ast.Attribute) and child.func.attr in WIRING:
                out.append((cls, child))
            visit(child, cls)

    visit(tree, None)
    return out


def test_there_are_nodes():
    assert {"remesher", "sensitivity", "solver", "ui", "adjust"} <= set(NODES)


@pytest.mark.parametrize("name", NODES)
def test_inputs_are_wired_to_methods_of_an_adapter_class(name):
    tree = ast.parse((ROOT / "nodes" / name / "main.py").read_text())
    calls = _wiring_calls(tree)
    subscriptions = [(cls, c) for cls, c in calls if c.func.attr == "subscribe"]
    assert subscriptions, f"nodes/{name} subscribes to nothing?"
    for cls, call in calls:
        where = f"nodes/{name}/main.py:{call.lineno}"
        assert cls is not None and cls.endswith("Adapter"), f"{where}: wired outside an ...Adapter class"
        callback = call.args[1] if call.func.attr != "watch_nodes" else call.args[0]
        assert (
            isinstance(callback, ast.Attribute) and isinstance(callback.value, ast.Name) and callback.value.id == "self"
        ), f"{where}: the callback is not a method of {cls} ({ast.unparse(callback)})"


@pytest.mark.parametrize("name", NODES)
def test_main_takes_a_config_and_the_adapter_exists(name):
    import importlib

    mod = importlib.import_module(f"nodes.{name}.main")
    params = list(inspect.signature(mod.main).parameters)
    assert params[0] == "config" and hasattr(mod, "Config")
    adapters = [v for k, v in vars(mod).items() if k.endswith("Adapter") and inspect.isclass(v)]
    assert adapters, f"nodes/{name}/main.py has no ...Adapter class"
    handlers = {m for a in adapters for m in vars(a) if m.startswith("on_")}
    assert handlers, f"nodes/{name}: its adapter has no on_* handler"

"""Import rules between the layers (README, "Layers and their rules"), read
from every import statement in couture/, nodes/, schemas/ and bench/ (function-level
imports included):

- the library never imports the bus: only the bus-facing modules listed in
  BUS_FACING import zenoh, the bus, recording, the client or the supervisor;
- the numerical packages import no bus code and no UI;
- nodes never import each other, and nothing in couture/ or schemas/ imports nodes;
- the benchmarks (bench/, beside the library, not installed with it) sit on
  top: nothing in couture/, nodes/ or schemas/ imports them (``couture bench``
  finds them at run time in the checkout);
- nothing imports upward (schemas < library < bus-facing library < nodes < benchmarks).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

BUS_FACING = (
    "couture.bus",
    "couture.recording",
    "couture.client",
    "couture.supervisor",
    "couture.graph",  # the node graph: node command lines from their Configs (couture.bus.nodeargs)
    "couture.cli",
    "couture.__main__",  # python -m couture: the CLI
)
"""library modules (and packages) that may talk to Zenoh"""

BUS_CODE = ("zenoh", "couture.bus", "couture.recording", "couture.client", "couture.supervisor", "couture.cli")
"""what only the bus-facing modules may import"""

NUMERICAL = (
    "couture.cloth",
    "couture.solvers",
    "couture.remesh",
    "couture.sensitivity",
    "couture.pattern",
    "couture.mesh",
    "couture.adjust",
)
"""packages that compute: no bus, no UI"""

CONVERTERS = ("schemas.convert",)
"""schemas modules that turn messages into library types (and so sit with the library)"""


def _under(name: str, prefixes: tuple[str, ...] | str) -> bool:
    prefixes = (prefixes,) if isinstance(prefixes, str) else prefixes
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imports_of(source: str, me: str, is_package: bool = False) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import in module ``me``'s source;
    ``from a import b`` yields both 'a' and 'a.b' (b may be a submodule)."""
    tree = ast.parse(source)
    package = me if is_package else me.rpartition(".")[0]
    out: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.append((node.lineno, mod))
            out += [(node.lineno, f"{mod}.{a.name}") for a in node.names if a.name != "*"]
    return out


def rank(module: str) -> int:
    """Layer of a first-party module: 0 schemas, 1 library, 2 bus-facing library, 3 nodes, 4 benchmarks;
    -1 third party."""
    if _under(module, "bench"):
        return 4
    if _under(module, "nodes"):
        return 3
    if _under(module, BUS_FACING):
        return 2
    if _under(module, "couture") or _under(module, CONVERTERS):
        return 1
    if _under(module, "schemas"):
        return 0
    return -1


def violations(path: Path, source: str | None = None) -> list[str]:
    """Every broken rule in one file (its text, or ``source`` in its place), as
    'file:line: module imports X (rule)'."""
    me = _module_name(path)
    where = path.relative_to(ROOT)
    bad = []
    text = path.read_text() if source is None else source
    for line, imp in imports_of(text, me, path.name == "__init__.py"):
        if _under(me, "couture") and not _under(me, BUS_FACING) and _under(imp, BUS_CODE):
            bad.append(f"{where}:{line}: {me} imports {imp} (only the bus-facing modules may)")
        if _under(me, NUMERICAL) and _under(imp, "couture.ui"):
            bad.append(f"{where}:{line}: {me} imports {imp} (numerical code imports no UI)")
        if _under(me, "nodes") and _under(imp, "nodes"):
            mine = ".".join(me.split(".")[:2])
            if imp != "nodes" and not _under(imp, mine):
                bad.append(f"{where}:{line}: {me} imports {imp} (nodes never import each other)")
        elif rank(imp) > rank(me):
            bad.append(f"{where}:{line}: {me} imports {imp} (upward: layer {rank(me)} -> {rank(imp)})")
    return bad


def _sources() -> list[Path]:
    return sorted(p for d in ("couture", "nodes", "schemas", "bench") for p in (ROOT / d).rglob("*.py"))


def test_the_tree_keeps_the_import_rules():
    bad = [v for p in _sources() for v in violations(p)]
    assert not bad, "import rules broken:\n" + "\n".join(bad)


@pytest.mark.parametrize(
    "module, source, rule",
    [
        ("couture/cloth/probe.py", "import zenoh", "bus-facing"),
        ("couture/pattern/probe.py", "from couture.bus import Node", "bus-facing"),
        ("couture/solvers/probe.py", "def f():\n    from couture.client import Client\n", "bus-facing"),
        ("couture/remesh/probe.py", "from couture.ui.state import Option", "numerical"),
        ("couture/cli.py", "def f():\n    from bench.adjust import design_fit\n", "upward"),
        ("couture/solvers/probe.py", "import bench", "upward"),
        ("nodes/solver/probe.py", "from bench import write_results", "upward"),
        ("couture/remesh/probe.py", "import nodes.remesher.main", "upward"),
        ("nodes/solver/probe.py", "from nodes.sensitivity.main import main", "each other"),
        ("nodes/solver/probe.py", "from ..ui import main", "each other"),
        ("schemas/probe.py", "from couture.pattern import draft", "upward"),
        ("couture/bus/probe.py", "from nodes.ui.main import UINode", "upward"),
    ],
)
def test_a_forbidden_import_is_caught(module, source, rule):
    found = violations(ROOT / module, source)
    assert found and rule in found[0], found


def test_allowed_imports_pass():
    for module, source in (
        ("couture/bus/probe.py", "import zenoh\nfrom couture.pattern import draft"),
        ("nodes/solver/probe.py", "from couture.bus import Node\nfrom . import main"),
        ("couture/remesh/probe.py", "from schemas.design import Design\nfrom . import service"),
        (
            "bench/probe.py",
            "import zenoh\nfrom bench import write_results\nfrom couture.client import Client\nimport nodes",
        ),
    ):
        assert violations(ROOT / module, source) == []

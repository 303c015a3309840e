"""No import cycles inside couture/: every module of the library, parsed with
ast, gives the couture.* modules it imports (at module level and inside
functions alike: a function-level import only hides a cycle from the
interpreter until the function runs, it does not remove it). Neither that
graph nor the graph of its floors (couture.X: a subpackage or a top-level
module, the units the layer rules speak of) may have a cycle. A failure names
the modules of one cycle in order.

An edge goes to the module an import names: ``from couture.a import b``
points at couture.a.b when that is a module, else at couture.a (b is a name
in it). Importing couture.a.b also runs couture/a/__init__.py, but that
implicit parent edge is left out: a package's __init__ re-exporting its own
submodules is the usual layout, not a cycle anyone wrote.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imported_modules(source: str, me: str, is_package: bool, known: set[str]) -> set[str]:
    """The modules of ``known`` that module ``me`` imports anywhere in ``source``."""
    package = me if is_package else me.rpartition(".")[0]
    out: set[str] = set()

    def add(name: str) -> None:
        while name and name not in known:  # couture.a.b.func -> couture.a.b
            name = name.rpartition(".")[0]
        if name and name != me:
            out.add(name)

    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            for a in node.names:
                add(a.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            for a in node.names:
                add(f"{mod}.{a.name}" if f"{mod}.{a.name}" in known else mod)
    return out


def import_graph(root: Path = ROOT, top: str = "couture") -> dict[str, set[str]]:
    """module -> the modules under ``top`` it imports, for every module under root/top."""
    paths = sorted((root / top).rglob("*.py"))
    names = {module_name(p, root): p for p in paths}
    known = set(names)
    return {
        m: {t for t in imported_modules(p.read_text(), m, p.name == "__init__.py", known) if t.startswith(top)}
        for m, p in names.items()
    }


def floors(graph: dict[str, set[str]], top: str = "couture") -> dict[str, set[str]]:
    """``graph`` collapsed onto its floors (``top``.X): which subpackages and top-level modules import which."""

    def floor(m: str) -> str:
        return ".".join(m.split(".")[:2])

    out: dict[str, set[str]] = {floor(m): set() for m in graph}
    for m, targets in graph.items():
        out[floor(m)] |= {floor(t) for t in targets if floor(t) != floor(m)}
    return out


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as [a, b, ..., a], or None when it has none (depth-first search)."""
    WHITE, GREY, BLACK = 0, 1, 2
    colour = dict.fromkeys(graph, WHITE)
    stack: list[str] = []

    def visit(m: str) -> list[str] | None:
        colour[m] = GREY
        stack.append(m)
        for t in sorted(graph.get(m, ())):
            if colour.get(t, BLACK) == GREY:
                return stack[stack.index(t) :] + [t]
            if colour.get(t) == WHITE:
                found = visit(t)
                if found:
                    return found
        stack.pop()
        colour[m] = BLACK
        return None

    for m in sorted(graph):
        if colour[m] == WHITE:
            found = visit(m)
            if found:
                return found
    return None


def test_couture_has_no_import_cycle():
    graph = import_graph()
    assert len(graph) > 100 and graph["couture.cli"], "the graph missed the library's modules"
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle between modules of couture/: " + " -> ".join(cycle or [])
    cycle = find_cycle(floors(graph))
    assert cycle is None, "import cycle between packages of couture/: " + " -> ".join(cycle or [])


def _tree(tmp_path: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        p = tmp_path / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return tmp_path


@pytest.mark.parametrize(
    "files, cycle",
    [
        # module level, three long
        (
            {
                "couture/__init__.py": "",
                "couture/a.py": "import couture.b\n",
                "couture/b.py": "from couture import c\n",
                "couture/c.py": "from couture.a import f\n",
            },
            ["couture.a", "couture.b", "couture.c", "couture.a"],
        ),
        # hidden in a function, through a relative import inside a package
        (
            {
                "couture/__init__.py": "",
                "couture/tryon.py": "def solve():\n    from couture.solvers import service\n",
                "couture/solvers/__init__.py": "",
                "couture/solvers/service.py": "from ..tryon import solve\n",
            },
            ["couture.solvers.service", "couture.tryon", "couture.solvers.service"],
        ),
    ],
)
def test_a_cycle_is_found_and_named(tmp_path, files, cycle):
    assert find_cycle(import_graph(_tree(tmp_path, files))) == cycle


def test_a_cycle_between_packages_is_found(tmp_path):
    """No module imports back the module that imports it, yet the packages depend on each other."""
    root = _tree(
        tmp_path,
        {
            "couture/__init__.py": "",
            "couture/tryon.py": "def solve():\n    from couture.solvers import get_solver\n",
            "couture/solvers/__init__.py": "def get_solver(): ...\n",
            "couture/solvers/service.py": "from couture.tryon import TryOn\n",
        },
    )
    graph = import_graph(root)
    assert find_cycle(graph) is None
    assert find_cycle(floors(graph)) == ["couture.solvers", "couture.tryon", "couture.solvers"]


def test_a_package_reexporting_its_submodules_is_no_cycle(tmp_path):
    root = _tree(
        tmp_path,
        {
            "couture/__init__.py": "",
            "couture/p/__init__.py": "from .a import f\nfrom .b import g\n",
            "couture/p/a.py": "def f(): ...\n",
            "couture/p/b.py": "from couture.p.a import f\nimport numpy\n",
        },
    )
    graph = import_graph(root)
    assert graph["couture.p"] == {"couture.p.a", "couture.p.b"}
    assert graph["couture.p.b"] == {"couture.p.a"}
    assert find_cycle(graph) is None and find_cycle(floors(graph)) is None

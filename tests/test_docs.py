"""The documentation names only what exists.

README.md, docs/*.md and bench/README.md are read as a newcomer would use
them: every repository path they name (in backticks, in code blocks or as a
link) exists, `<name>` placeholders and globs allowed; every `couture SUB` is
a subcommand of the CLI, every `couture bench NAME` a benchmark, every
`python -m X` of this project a runnable module, every dotted name such as
`couture.pattern.cutting.cut_pieces` a module or a name defined in one; links
into Markdown files land on a heading. README.md stays under 250 lines and
links every docs page.
"""

from __future__ import annotations

import argparse
import ast
import functools
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = [README, *sorted((ROOT / "docs").glob("*.md")), ROOT / "bench" / "README.md"]
README_MAX_LINES = 250
PACKAGES = ("couture", "schemas", "nodes", "bench")
"""first components of this project's importable names"""

PENDING: tuple[str, ...] = ()
"""Paths the docs already name that other branches of issue 28 create (the
slopers package, the benchmarks as a top-level package). A path under one of
these is not checked; once one exists, `test_pending_paths_are_still_missing`
fails: delete the entry, so that the path is checked from then on."""


def _rel(doc: Path) -> str:
    return str(doc.relative_to(ROOT))


def _split(text: str) -> tuple[list[str], str]:
    """(fenced code blocks, the text without them)."""
    fence = re.compile(r"^```[^\n]*\n(.*?)^```[ \t]*$", re.M | re.S)
    return fence.findall(text), fence.sub("", text)


def _spans(text: str) -> list[str]:
    """Inline code spans (they may wrap lines, never a paragraph), whitespace normalized."""
    return [" ".join(s.split()) for s in re.findall(r"`([^`]+)`", text) if "\n\n" not in s]


def _code(doc: Path) -> list[str]:
    """Every piece of code the page shows: its code spans and the lines of its code blocks."""
    blocks, prose = _split(doc.read_text())
    return _spans(prose) + [line for b in blocks for line in b.splitlines()]


def _links(doc: Path) -> list[str]:
    _, prose = _split(doc.read_text())
    prose = re.sub(r"`[^`]+`", "", prose)
    return re.findall(r"\]\(([^)\s]+)\)", prose)


@functools.cache
def _top_level() -> frozenset[str]:
    """Names at the repository root that the repository holds (not .venv, caches, outputs)."""
    try:
        files = subprocess.run(
            ["git", "-C", str(ROOT), "ls-files"], capture_output=True, text=True, timeout=10, check=True
        ).stdout.split()
    except (OSError, subprocess.SubprocessError):
        files = [p.name for p in ROOT.iterdir() if p.name not in (".git", ".venv")]
    names = {f.split("/")[0] for f in files}
    # what this branch adds before it is committed (the docs pages themselves)
    names |= {p.name for p in (ROOT / "docs", ROOT / "bench") if p.exists()}
    return frozenset(names)


def _is_path(token: str) -> bool:
    if token in _top_level():
        return True
    first = token.split("/")[0]
    if "/" not in token or first not in _top_level():
        return False
    if re.fullmatch(r"couture/([a-z_]+|<\w+>)/v\d+", token):  # a message type name, not a file
        return False
    return not any(s in token for s in ("...", "**", "://", "$"))


def _glob(token: str) -> str:
    """`<name>` and NAME placeholders become `*`."""
    token = re.sub(r"<[^>/]+>", "*", token)
    return "/".join("*" if re.fullmatch(r"[A-Z]{1,8}", part) else part for part in token.split("/"))


def _exists(path: str) -> bool:
    pattern = _glob(path.rstrip("/"))
    if not any(c in pattern for c in "*?["):
        return (ROOT / pattern).exists()
    return any(ROOT.glob(pattern))


def _pending(path: str) -> bool:
    return any(path == p or path.startswith(p) for p in PENDING)


def _tokens(code: str) -> list[str]:
    out = []
    for raw in code.replace("(", " ").replace(")", " ").replace(",", " ").split():
        tok = raw.strip("'\"`;:,.[]")
        if raw.endswith("/") and not tok.endswith("/"):
            tok += "/"
        if tok:
            out.append(tok)
    return out


def _named_paths(doc: Path) -> set[str]:
    return {t for code in _code(doc) for t in _tokens(code) if _is_path(t)}


@pytest.mark.parametrize("doc", DOCS, ids=_rel)
def test_every_named_path_exists(doc):
    assert doc.exists(), f"{_rel(doc)} is missing"
    missing = sorted(p for p in _named_paths(doc) if not _pending(p) and not _exists(p))
    assert not missing, f"{_rel(doc)} names paths that are not in the repository: {missing}"


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def _anchors(doc: Path) -> set[str]:
    _, prose = _split(doc.read_text())
    return {_slug(h) for h in re.findall(r"^#{1,6} +(.+?)\s*$", prose, re.M)}


@pytest.mark.parametrize("doc", DOCS, ids=_rel)
def test_every_link_lands(doc):
    bad = []
    for link in _links(doc):
        if re.match(r"[a-z]+:", link):  # http:, mailto:
            continue
        target, _, anchor = link.partition("#")
        path = (doc.parent / target).resolve() if target else doc
        if not path.exists():
            bad.append(f"{link}: no such file")
        elif anchor and path.suffix == ".md" and anchor not in _anchors(path):
            bad.append(f"{link}: no heading #{anchor} in {path.relative_to(ROOT)}")
    assert not bad, f"{_rel(doc)}: " + "; ".join(bad)


@functools.cache
def _cli() -> tuple[frozenset[str], frozenset[str]]:
    """(the `couture` subcommands, the benchmark names) from the CLI's own parser."""
    from couture import cli

    parser: argparse.ArgumentParser = cli._parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    commands = frozenset(subs.choices)
    benches: set[str] = set()
    for action in subs.choices["bench"]._actions:
        if action.choices and not isinstance(action, argparse._SubParsersAction):
            benches |= set(action.choices)
    if not benches:  # a launcher without choices: the benchmark modules
        for folder in (ROOT / "bench", ROOT / "couture" / "bench"):
            benches |= {p.stem for p in folder.glob("*.py") if not p.stem.startswith("_")}
    return commands, frozenset(benches)


def _commands(doc: Path) -> list[tuple[str, str | None]]:
    """(subcommand, benchmark or None) for every `couture SUB ...` the page shows."""
    out = []
    for code in _code(doc):
        for m in re.finditer(r"(?:^|[\s(])(?:[\w./-]*/)?couture +([a-z][\w-]*)(?: +([a-z_]\w*))?", code):
            out.append((m.group(1), m.group(2) if m.group(1) == "bench" else None))
    return out


def test_the_docs_show_commands():
    """The parsers below see something: the README's two commands and the pages' couture commands."""
    assert ("up", None) in _commands(ROOT / "docs" / "running.md")
    assert ("bench", "adjust") in _commands(ROOT / "bench" / "README.md")
    assert "scripts/demo.sh" in _named_paths(README) and "scripts/test.sh" in _named_paths(README)
    assert "couture.pattern.cutting.cut_pieces" in _dotted(ROOT / "docs" / "export.md")


@pytest.mark.parametrize("doc", DOCS, ids=_rel)
def test_every_couture_command_exists(doc):
    commands, benches = _cli()
    bad = sorted({f"couture {c}" for c, _ in _commands(doc) if c not in commands})
    bad += sorted({f"couture bench {b}" for c, b in _commands(doc) if c == "bench" and b and b not in benches})
    assert not bad, f"{_rel(doc)} shows commands the CLI does not have: {bad} (have {sorted(commands)})"


def _module_file(dotted: str) -> Path | None:
    base = ROOT.joinpath(*dotted.split("."))
    if (base / "__init__.py").exists():
        return base / "__init__.py"
    if base.with_suffix(".py").exists():
        return base.with_suffix(".py")
    return None


def _defines(module: Path, name: str) -> bool:
    """Whether a module defines or imports ``name`` at its top level."""
    for node in ast.parse(module.read_text()).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node.name == name:
            return True
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            if any((a.asname or a.name.split(".")[0]) == name for a in node.names):
                return True
        targets = node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and any(
            isinstance(t, ast.Name) and t.id == name for t in targets
        ):
            return True
    return False


def _resolves(dotted: str) -> bool:
    """A module of this project, or a name defined in one (attributes of that name unchecked)."""
    parts = dotted.split(".")
    module = None
    for i in range(1, len(parts) + 1):
        found = _module_file(".".join(parts[:i]))
        if found is None:
            return module is not None and _defines(module, parts[i - 1])
        module = found
    return True


def _dotted(doc: Path) -> set[str]:
    names = set()
    pattern = r"(?<![\w/.])((?:%s)(?:\.[A-Za-z_]\w*)+)(?![\w/])" % "|".join(PACKAGES)
    for code in _code(doc):
        for m in re.finditer(pattern, code):
            name = m.group(1)
            if name.rsplit(".", 1)[1] in ("py", "json", "md", "mcap", "toml", "log", "png", "obj"):
                continue  # a file name
            names.add(name)
    return names


@pytest.mark.parametrize("doc", DOCS, ids=_rel)
def test_every_dotted_name_resolves(doc):
    bad = sorted(n for n in _dotted(doc) if not _resolves(n))
    assert not bad, f"{_rel(doc)} names modules or names that do not exist: {bad}"


@pytest.mark.parametrize("doc", DOCS, ids=_rel)
def test_every_python_m_module_runs(doc):
    bad = []
    for code in _code(doc):
        for m in re.finditer(r"python -m ([\w.<>]+)", code):
            module = m.group(1)
            if module.split(".")[0] not in PACKAGES:
                continue  # pytest, pip, ...
            path = _glob(module.replace(".", "/"))
            runs = _exists(path + "/__main__.py") or (module.split(".")[0] != "nodes" and _exists(path + ".py"))
            if not runs:
                bad.append(module)
    assert not bad, f"{_rel(doc)}: `python -m` of modules that cannot run: {sorted(set(bad))}"


def test_readme_is_short_and_links_every_page():
    lines = README.read_text().splitlines()
    assert len(lines) < README_MAX_LINES, f"README.md has {len(lines)} lines (keep it under {README_MAX_LINES})"
    assert (
        lines[:12]
        and "bash scripts/demo.sh" in "\n".join(lines[:12])
        and "bash scripts/test.sh" in "\n".join(lines[:12])
    ), "the README's first lines must show the two commands"
    linked = {(README.parent / t.partition("#")[0]).resolve() for t in _links(README)}
    unlinked = [_rel(d) for d in DOCS[1:] if d.resolve() not in linked]
    assert not unlinked, f"README.md does not link {unlinked}"


def test_pending_paths_are_still_missing():
    landed = [p for p in PENDING if _exists(p)]
    assert not landed, f"{landed} exist now: remove them from PENDING in tests/test_docs.py so the docs are checked"

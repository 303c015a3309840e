"""A node's command line, generated from its ``Config`` dataclass.

Every node's ``__main__`` is ``run_node(Config, main, "kind")``: the flags are
the dataclass's fields (``max_seconds`` -> ``--max-seconds``), typed from the
annotations, with the field's default and its docstring as help, plus the bus
flags every node takes (:func:`add_bus_args`). ``couture up`` writes a node's
command line from its configuration in the node graph with the same table
(:func:`config_args`), so a flag is written once, in the Config.

Types: ``bool`` (``--x`` / ``--no-x``), ``int``, ``float``, ``str``, ``Path``,
``list[...]`` of those (the flag repeated), ``X | None`` (absent: None) and
``Literal[...]`` (choices). Field metadata refines a field:

- ``choices``: the allowed values, or a function returning them (the solver
  kind asks the solver registry);
- ``flag``: the flag's name when it is not the field's (``--serve-session``);
- ``help``: help text when the field has no docstring;
- ``parse``: ``str -> value`` for a type with no command-line form of its own
  (the UI's initial design is read from a pattern file named on the line);
- ``cli``: False leaves the field off the command line (set in code only).
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import logging
import sys
import textwrap
import types
import typing
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Literal, TypeVar, Union, get_args, get_origin

from couture.bus.session import BusConfig, add_bus_args, bus_config_from_args

C = TypeVar("C")

_SCALARS = (bool, int, float, str, Path)


@dataclasses.dataclass(frozen=True)
class Option:
    """One Config field as a command-line flag."""

    field: str
    """the dataclass field's name"""
    flag: str
    """'--max-seconds'"""
    base: type
    """bool, int, float, str or Path (a ``parse`` field: str)"""
    many: bool
    """a list: the flag repeats"""
    optional: bool
    """``X | None``: absent means None"""
    choices: tuple[Any, ...] | None
    default: Any
    help: str
    parse: Callable[[str], Any] | None = None

    def describe(self) -> str:
        kind = self.base.__name__
        kind = f"list of {kind}" if self.many else kind
        kind += " or none" if self.optional else ""
        return kind + (f", one of {', '.join(map(str, self.choices))}" if self.choices else "")


def field_docs(cls: type) -> dict[str, str]:
    """The docstrings written under each field of a dataclass (PEP 257 attribute docstrings), by field name."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError):
        return {}
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    docs: dict[str, str] = {}
    for prev, node in zip(body, body[1:], strict=False):
        if (
            isinstance(prev, ast.AnnAssign)
            and isinstance(prev.target, ast.Name)
            and isinstance(node, ast.Expr)
            and isinstance(node.value, ast.Constant)
            and isinstance(node.value.value, str)
        ):
            docs[prev.target.id] = " ".join(node.value.value.split())
    return docs


def _default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return dataclasses.MISSING


def options(cls: type) -> list[Option]:
    """The command-line form of every field of ``cls`` except the bus (which
    :func:`add_bus_args` covers). A field whose type has no command-line form
    raises TypeError naming it."""
    hints = typing.get_type_hints(cls)
    docs = field_docs(cls)
    out = []
    for f in dataclasses.fields(cls):
        if hints[f.name] is BusConfig or f.metadata.get("cli", True) is False:
            continue
        where = f"{cls.__module__}.{cls.__qualname__}.{f.name}"
        tp, optional, many, choices = hints[f.name], False, False, None
        if get_origin(tp) in (Union, types.UnionType):
            rest = [a for a in get_args(tp) if a is not type(None)]
            optional = len(rest) < len(get_args(tp))
            if len(rest) != 1:
                raise TypeError(f"{where}: a union {tp} has no command-line form")
            tp = rest[0]
        if get_origin(tp) is list:
            many, tp = True, get_args(tp)[0]
        if get_origin(tp) is Literal:
            choices = get_args(tp)
            tp = type(choices[0])
        parse = f.metadata.get("parse")
        if parse is not None:
            tp = str
        if tp not in _SCALARS:
            raise TypeError(f"{where}: type {tp} has no command-line form (give the field metadata parse=...)")
        meta_choices = f.metadata.get("choices")
        if meta_choices is not None:
            choices = tuple(meta_choices() if callable(meta_choices) else meta_choices)
        flag = f.metadata.get("flag") or "--" + f.name.replace("_", "-")
        help_text = f.metadata.get("help") or docs.get(f.name, "")
        out.append(Option(f.name, flag, tp, many, optional, choices, _default(f), help_text, parse))
    return out


def convert_text(opt: Option, text: str) -> Any:
    """One command-line word as ``opt``'s value; ValueError saying what was expected."""
    if opt.optional and text.lower() == "none":
        return None
    if opt.base is bool:
        if text.lower() in ("1", "true", "yes", "on"):
            return True
        if text.lower() in ("0", "false", "no", "off"):
            return False
        raise ValueError(f"{text!r} is not true or false")
    value = opt.base(text)
    if opt.choices is not None and value not in opt.choices:
        raise ValueError(f"{text!r} is not one of {', '.join(map(str, opt.choices))}")
    return value


def add_config_args(parser: argparse.ArgumentParser, cls: type) -> list[Option]:
    """Add one flag per field of ``cls`` (see the module's docstring); returns the options."""
    opts = options(cls)
    for o in opts:
        shown = o.default if not isinstance(o.default, list) else " ".join(map(str, o.default)) or "none"
        help_text = f"{o.help} (default: {shown})" if o.help else f"default: {shown}"
        help_text = help_text.replace("%", "%%")
        if o.base is bool and not o.many:
            parser.add_argument(
                o.flag, dest=o.field, action=argparse.BooleanOptionalAction, default=o.default, help=help_text
            )
            continue

        def typ(text: str, o: Option = o) -> Any:
            try:
                return convert_text(o, text)
            except ValueError as e:
                raise argparse.ArgumentTypeError(str(e)) from None

        typ.__name__ = o.base.__name__  # argparse names the type in its errors
        parser.add_argument(
            o.flag,
            dest=o.field,
            type=typ,
            action="append" if o.many else "store",
            default=None,
            metavar=o.field.upper() if o.choices is None else "{" + ",".join(map(str, o.choices)) + "}",
            help=help_text + (" (repeatable)" if o.many else ""),
        )
    return opts


def config_from_args(cls: type[C], args: argparse.Namespace, **fixed: Any) -> C:
    """The Config the parsed flags describe: a flag left out keeps the field's
    default; ``fixed`` fields (the bus) are passed as given."""
    kw: dict[str, Any] = dict(fixed)
    for o in options(cls):
        value = getattr(args, o.field)
        if value is None:
            continue  # not given: the dataclass default (a fresh default_factory value)
        if o.parse is not None:
            value = [o.parse(v) for v in value] if o.many else o.parse(value)
        kw[o.field] = value
    return cls(**kw)


def parse_config(cls: type[C], argv: Sequence[str] | None = None, *, prog: str | None = None) -> C:
    """``cls`` from a command line: its fields' flags plus the bus flags."""
    module_doc = getattr(sys.modules.get(cls.__module__), "__doc__", None) or ""
    p = argparse.ArgumentParser(prog=prog, description=module_doc.strip().split("\n\n")[0] or None)
    add_config_args(p, cls)
    fields = {f.name for f in dataclasses.fields(typing.cast(Any, cls))}
    if "bus" in fields:
        add_bus_args(p)
    a = p.parse_args(argv)
    return config_from_args(cls, a, **({"bus": bus_config_from_args(a)} if "bus" in fields else {}))


def format_value(opt: Option, value: Any) -> list[str]:
    """The flags that give ``opt`` the value ``value`` (a Config's value, or a
    node graph's: str for Path); [] for None."""
    if value is None:
        return []
    if opt.base is bool and not opt.many:
        return [opt.flag if value else "--no-" + opt.flag[2:]]
    items = value if opt.many else [value]
    out: list[str] = []
    for v in items:
        out += [opt.flag, str(v).lower() if isinstance(v, bool) else str(v)]
    return out


def format_config(config: Any) -> list[str]:
    """The command line :func:`parse_config` reads back into ``config``
    (``parse_config(type(c), format_config(c)) == c``). A field set through
    ``parse`` (a file named on the line) has no flag form as a value: it raises
    TypeError naming the field."""
    out = [] if not hasattr(config, "bus") else config.bus.to_args()
    for o in options(type(config)):
        value = getattr(config, o.field)
        if o.parse is not None and value is not None:
            raise TypeError(f"{type(config).__qualname__}.{o.field} is read from a file: give its path, not its value")
        out += format_value(o, value)
    return out


def check_value(opt: Option, value: Any) -> Any:
    """A value from a data file (TOML) checked against ``opt``: returns it in
    its Config form (str -> Path, int -> float); raises ValueError saying what
    was expected."""

    def one(v: Any) -> Any:
        expected = opt.base
        if expected is float and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        elif expected is Path and isinstance(v, str):
            v = Path(v)
        if not isinstance(v, expected) or (expected is int and isinstance(v, bool)):
            raise ValueError(f"{v!r} is a {type(v).__name__}, expected {opt.describe()}")
        if opt.choices is not None and v not in opt.choices:
            raise ValueError(f"{v!r} is not one of {', '.join(map(str, opt.choices))}")
        return v

    if opt.many:
        if not isinstance(value, list):
            raise ValueError(f"{value!r} is a {type(value).__name__}, expected {opt.describe()}")
        return [one(v) for v in value]
    return one(value)


def run_node(cls: type[C], main: Callable[[C], object], kind: str, argv: Sequence[str] | None = None) -> None:
    """A node's ``__main__``: parse its Config from the command line, log with its kind, run ``main``."""
    config = parse_config(cls, argv, prog=f"python -m nodes.{kind}")
    logging.basicConfig(level=logging.INFO, format=f"%(asctime)s {kind} %(levelname)s %(message)s")
    main(config)


__all__ = [
    "Option",
    "options",
    "field_docs",
    "add_config_args",
    "config_from_args",
    "parse_config",
    "format_value",
    "format_config",
    "check_value",
    "convert_text",
    "run_node",
]

"""Messages of any registered type built from its schema alone (the Struct's
field types and ``ARRAYS``), so that the schema tests and the fault flood take
their list of types from ``schemas.messages.MESSAGE_TYPES`` and a new message
type needs no edit in them. A type whose ``check`` asks more than its field
types say (a nonzero amount, a panel for some ops) gets a hand-written
strategy in tests/test_schemas.py; :func:`minimal` satisfies the rules of
every type registered today, and a test says so for each."""

from __future__ import annotations

from typing import Any

import msgspec
import numpy as np
from hypothesis import strategies as st

from schemas.arrays import Array
from schemas.messages import ArraySpec, Message, SchemaError, validate

HEADER = {"schema", "version"}
"""set by the message itself"""


def _zeros(spec: ArraySpec, dims: dict[str, int]) -> np.ndarray:
    shape = tuple(s if isinstance(s, int) else dims[s] for s in spec.shape)
    return np.zeros(shape, dtype=spec.dtypes[0])


def _minimal_value(t: msgspec.inspect.Type) -> Any:
    if isinstance(t, msgspec.inspect.StrType):
        return "x"
    if isinstance(t, msgspec.inspect.BoolType):
        return False
    if isinstance(t, msgspec.inspect.IntType):
        return 1
    if isinstance(t, msgspec.inspect.FloatType):
        return 0.1
    if isinstance(t, msgspec.inspect.LiteralType):
        return t.values[0]
    if isinstance(t, (msgspec.inspect.ListType, msgspec.inspect.DictType)):
        return [] if isinstance(t, msgspec.inspect.ListType) else {}
    if isinstance(t, msgspec.inspect.StructType):
        if issubclass(t.cls, Message):
            return minimal(t.cls)
        return t.cls()
    raise TypeError(f"no minimal value for {t}")


def minimal(cls: type[Message], **fields: Any) -> Message:
    """One valid message of ``cls``: required fields filled from their types
    (str 'x', int 1, float 0.1, the first literal, arrays of zeros with every
    named dimension 1), the others at their defaults; ``fields`` override."""
    dims = {s: 1 for spec in cls.ARRAYS.values() for s in spec.shape if isinstance(s, str)}
    kw: dict[str, Any] = {}
    for f in msgspec.inspect.type_info(cls).fields:  # type: ignore[union-attr]
        if f.name in fields or not f.required:
            continue
        kw[f.name] = _zeros(cls.ARRAYS[f.name], dims) if f.name in cls.ARRAYS else _minimal_value(f.type)
    # a literal may decide what else is needed (a try-on op: a panel): the first that needs nothing more
    literals = [
        (f.name, f.type.values)
        for f in msgspec.inspect.type_info(cls).fields  # type: ignore[union-attr]
        if f.name in kw and isinstance(f.type, msgspec.inspect.LiteralType)
    ]
    candidates = [kw] + [{**kw, name: v} for name, values in literals for v in values]
    for i, c in enumerate(candidates):
        msg = cls(**c, **fields)
        try:
            validate(msg)
            return msg
        except SchemaError:
            if i == len(candidates) - 1:
                raise
    raise AssertionError("unreachable")


finite = st.floats(allow_nan=False, allow_infinity=False, width=64, min_value=-1e6, max_value=1e6)
ints = st.integers(min_value=0, max_value=2**40)
text = st.text(max_size=8)


def _value(t: msgspec.inspect.Type, depth: int) -> st.SearchStrategy[Any]:
    if isinstance(t, msgspec.inspect.StrType):
        return text
    if isinstance(t, msgspec.inspect.BoolType):
        return st.booleans()
    if isinstance(t, msgspec.inspect.IntType):
        return ints
    if isinstance(t, msgspec.inspect.FloatType):
        return finite
    if isinstance(t, msgspec.inspect.LiteralType):
        return st.sampled_from(t.values)
    if isinstance(t, msgspec.inspect.ListType):
        return st.lists(_value(t.item_type, depth), max_size=3)
    if isinstance(t, msgspec.inspect.DictType):
        return st.dictionaries(_value(t.key_type, depth), _value(t.value_type, depth), max_size=3)
    if isinstance(t, msgspec.inspect.NoneType):
        return st.none()
    if isinstance(t, msgspec.inspect.UnionType):
        return st.one_of(*[_value(u, depth) for u in t.types])
    if isinstance(t, msgspec.inspect.StructType):
        if issubclass(t.cls, Message):
            return messages(t.cls, depth + 1) if depth < 1 else st.just(minimal(t.cls))
        return st.just(t.cls())  # a nested data class (Design): its defaults
    raise TypeError(f"no strategy for {t}")


def _array(draw: st.DrawFn, spec: ArraySpec, dims: dict[str, int]) -> Array:
    dtype = draw(st.sampled_from(spec.dtypes))
    shape = tuple(s if isinstance(s, int) else dims[s] for s in spec.shape)
    n = int(np.prod(shape))
    if np.issubdtype(np.dtype(dtype), np.integer):
        # indices: the schemas check them against a named dimension, every one at least 1
        vals: list[Any] = draw(st.lists(st.integers(0, min(dims.values(), default=1) - 1), min_size=n, max_size=n))
    else:
        vals = draw(st.lists(finite, min_size=n, max_size=n))
    return Array.from_numpy(np.array(vals, dtype=dtype).reshape(shape), dtype)


def _valid(msg: Message) -> bool:
    try:
        validate(msg)
    except SchemaError:
        return False
    return True


def messages(cls: type[Message], depth: int = 0) -> st.SearchStrategy[Message]:
    """Random valid messages of ``cls``: every field drawn from its type, the
    arrays from ``ARRAYS`` (named dimensions 1..4 shared across fields),
    optional ones sometimes None; those ``check`` refuses are filtered out."""

    @st.composite
    def build(draw: st.DrawFn) -> Message:
        names = {s for spec in cls.ARRAYS.values() for s in spec.shape if isinstance(s, str)}
        dims = {s: draw(st.integers(1, 4)) for s in sorted(names)}
        kw: dict[str, Any] = {}
        for f in msgspec.inspect.type_info(cls).fields:  # type: ignore[union-attr]
            if f.name in HEADER:
                continue
            spec = cls.ARRAYS.get(f.name)
            if spec is None:
                kw[f.name] = draw(_value(f.type, depth))
            elif spec.optional and draw(st.booleans()):
                kw[f.name] = None
            else:
                kw[f.name] = _array(draw, spec, dims)
        return cls(**kw)

    return build().filter(_valid)

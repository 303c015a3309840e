"""Arrays on the wire: dtype name + shape + raw little-endian bytes (viser's habit).

``Array.from_numpy(a)`` copies nothing but the bytes; ``arr.numpy()`` returns a
read-only zero-copy view. Only the dtypes in ``DTYPES`` travel.
"""

from __future__ import annotations

import math

import msgspec
import numpy as np

DTYPES: dict[str, np.dtype] = {
    "float32": np.dtype("<f4"),
    "float64": np.dtype("<f8"),
    "int32": np.dtype("<i4"),
    "int64": np.dtype("<i8"),
    "uint8": np.dtype("u1"),
}
"""wire dtype name -> little-endian numpy dtype"""

FLOAT_DTYPES = ("float32", "float64")
INT_DTYPES = ("int32", "int64")


class Array(msgspec.Struct, array_like=False, kw_only=True):
    """An n-dimensional array: ``dtype`` (a key of ``DTYPES``), ``shape``, and
    ``data``, the C-order little-endian bytes (len = prod(shape) * itemsize)."""

    dtype: str
    """wire dtype name, one of DTYPES"""
    shape: list[int]
    """dimensions, C order"""
    data: bytes
    """raw little-endian element bytes"""

    @classmethod
    def from_numpy(cls, a: np.ndarray, dtype: str | None = None) -> "Array":
        """Wrap ``a`` (converted to ``dtype`` if given, e.g. 'float32' for drapes)."""
        a = np.asarray(a)
        name = dtype or _wire_name(a.dtype)
        a = np.ascontiguousarray(a, dtype=DTYPES[name])
        return cls(dtype=name, shape=[int(s) for s in a.shape], data=a.tobytes())

    def numpy(self) -> np.ndarray:
        """Read-only view of the bytes as an array (validated messages only)."""
        return np.frombuffer(self.data, dtype=DTYPES[self.dtype]).reshape(self.shape)

    def problem(self) -> str | None:
        """Why this array is not self-consistent, or None."""
        if self.dtype not in DTYPES:
            return f"dtype {self.dtype!r} not allowed (allowed: {', '.join(DTYPES)})"
        if any(s < 0 for s in self.shape):
            return f"negative dimension in shape {self.shape}"
        expected = math.prod(self.shape) * DTYPES[self.dtype].itemsize
        if len(self.data) != expected:
            return f"byte count {len(self.data)} does not match shape {self.shape} of {self.dtype} ({expected} bytes)"
        return None


def _wire_name(dt: np.dtype) -> str:
    dt = np.dtype(dt)
    for name, d in DTYPES.items():
        if d == dt.newbyteorder("<") or d == dt:
            return name
    if dt == np.bool_:
        return "uint8"
    raise ValueError(f"dtype {dt} cannot travel; allowed: {', '.join(DTYPES)}")


def as_array(a: "np.ndarray | Array | None", dtype: str | None = None) -> "Array | None":
    """numpy array (or Array, or None) -> Array (or None)."""
    if a is None or isinstance(a, Array):
        return a
    return Array.from_numpy(a, dtype)


def to_numpy(a: "Array | None") -> "np.ndarray | None":
    """Array (or None) -> read-only numpy view (or None)."""
    return None if a is None else a.numpy()

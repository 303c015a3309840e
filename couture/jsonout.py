"""Standard JSON out: every file couture writes parses with any JSON reader.

Python's ``json`` writes NaN and ±inf as the bare words ``NaN`` and
``Infinity``, which are not JSON (RFC 8259) and which strict readers
(browsers' ``JSON.parse``, jq, msgspec) reject. Here a non-finite float
becomes ``null`` (unknown / not a number) and ``allow_nan=False`` makes any
that slipped through an error instead of a bad file.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np


def finite_json(obj: Any) -> Any:
    """``obj`` with every non-finite float (NaN, ±inf; Python or numpy) replaced
    by None, numpy scalars and arrays turned into Python numbers and lists,
    tuples into lists. Other values are returned as they are."""
    if isinstance(obj, dict):
        return {k: finite_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_json(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return finite_json(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def dumps(obj: Any, **kw: Any) -> str:
    """``json.dumps`` of :func:`finite_json` (obj), refusing NaN and Infinity."""
    return json.dumps(finite_json(obj), allow_nan=False, **kw)

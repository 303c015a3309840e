"""UI state that is not drawing: the latest-value mailbox the bus callbacks
write into, node liveness, fabric presets, and the sloper option tables
(read from couture.pattern when it provides them)."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import numpy as np

T = TypeVar("T")


class LatestSlot(Generic[T]):
    """Holds only the newest value: writers never block on readers, readers
    take the value at most once. The UI never waits on the solver; a burst of
    drapes between two frames costs one render, not a queue."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._value: T | None = None
        self._fresh = False
        self.n_put = 0
        self.n_coalesced = 0

    def put(self, value: T) -> None:
        with self._cond:
            if self._fresh:
                self.n_coalesced += 1
            self._value = value
            self._fresh = True
            self.n_put += 1
            self._cond.notify_all()

    def take(self, timeout: float | None = None) -> T | None:
        """The newest value not yet taken, waiting up to ``timeout`` [s]; None if none."""
        with self._cond:
            if not self._fresh and timeout:
                self._cond.wait(timeout)
            if not self._fresh:
                return None
            self._fresh = False
            return self._value

    def peek(self) -> T | None:
        with self._cond:
            return self._value


@dataclass
class DrapeFrame:
    """One drape to show."""

    x: np.ndarray
    """[m], shape (n, 3)"""
    level: str
    """'predicted', 'coarse' or 'fine'"""
    method: str = ""
    residual: float = float("nan")
    error_estimate: float | None = None
    generation: int = 0
    tag: Any = None
    """opaque value echoed to the page with the frame (benchmarks use it)"""
    solver: str = ""
    """solver node that produced it ('' for predictions)"""
    converged: bool | None = None
    """None: unknown (demo, replay)"""
    diagnosis: str = ""
    final: bool = True
    """False for a solver's progress snapshot"""
    edit_id: str = ""
    received: float = field(default_factory=time.time)
    """arrival time, Unix [s]"""


@dataclass
class NodeInfo:
    name: str
    alive: bool = True
    kind: str = ""
    state: str = ""
    rates: dict[str, float] = field(default_factory=dict)
    last_error: str = ""
    seen: float = field(default_factory=time.time)


@dataclass(frozen=True)
class FabricPreset:
    name: str
    bend_stiffness: float
    """[N m]"""
    stretch_stiffness: float
    """[N/m]"""
    area_density: float
    """[kg/m²]"""


FABRIC_PRESETS: dict[str, FabricPreset] = {
    p.name: p for p in (
        # SC Table 1 rows (bending, stretching, density)
        FabricPreset("silk-like", 1e-8, 10.0, 0.2),
        FabricPreset("cotton", 5e-6, 200.0, 0.15),
        FabricPreset("stiff", 3e-4, 2000.0, 0.08),
    )
}


@dataclass(frozen=True)
class Option:
    """A sloper option as data (FreeSewing style)."""

    name: str
    default: float
    min: float
    max: float
    unit: str = "m"
    step: float | None = None


def _option_from_any(name: str, o: Any) -> Option:
    if isinstance(o, Option):
        return o
    get = (lambda k, d=None: o.get(k, d)) if isinstance(o, dict) else (lambda k, d=None: getattr(o, k, d))
    step = get("step") or (1.0 if get("integer", False) else None)
    return Option(str(get("name", name) or name), float(get("default")), float(get("min")), float(get("max")),
                  str(get("unit", "") or ""), step)


def sloper_kinds() -> list[str]:
    """The slopers couture.pattern can draft."""
    from couture.pattern import SLOPERS

    return list(SLOPERS)


def sloper_options(kind: str) -> list[Option]:
    """The option table of a sloper (couture.pattern's data: default, min, max, unit)."""
    from couture.pattern import SLOPERS

    return [_option_from_any(o.name, o) for o in SLOPERS[kind].options]

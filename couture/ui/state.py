"""UI state that is not drawing: the latest-value mailbox the bus callbacks
write into, the drape frame, fabric presets, and the sloper option tables
(couture.pattern's data)."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Any, Generic, Literal, TypeVar

import numpy as np

from couture.pattern import SLOPERS, Option
from schemas.design import Fabric

T = TypeVar("T")

Phase = Literal["press", "drag", "release"]
"""phase of a drag gesture"""
VISER_DRAG_PHASE: dict[str, Phase] = {"start": "press", "update": "drag", "end": "release"}
"""viser's drag event phase -> ours"""


class LatestSlot(Generic[T]):
    """Holds only the newest value: writers never block on readers, readers
    take the value at most once. The UI never waits on the solver; a burst of
    drapes between two frames costs one render, not a queue."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._value: T | None = None
        self._fresh = False

    def put(self, value: T) -> None:
        with self._cond:
            self._value = value
            self._fresh = True
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
    error_estimate_m: float | None = None
    """a prediction's estimated distance from the true equilibrium [m] (None: not known)"""


SC_PRESETS: dict[str, Fabric] = {
    f.name: f
    for f in (
        # SC Table 1 rows (bending [N m], stretching [N/m], density [kg/m²]): the
        # ends and middle of the solver's tested range, not measured fabrics
        Fabric(name="silk-like", bend_stiffness=1e-8, stretch_stiffness=10.0, area_density=0.2),
        Fabric(name="cotton", bend_stiffness=5e-6, stretch_stiffness=200.0, area_density=0.15),
        Fabric(name="stiff", bend_stiffness=3e-4, stretch_stiffness=2000.0, area_density=0.08),
    )
}


def _library_presets() -> dict[str, Fabric]:
    from couture import fabrics

    return {name: fabrics.get(name) for name in fabrics.names()}


LIBRARY_PRESETS: dict[str, Fabric] = _library_presets()
"""the fabric library (couture/assets/fabrics/library.toml): measured or
estimated real fabrics, directional values and skin friction included"""

FABRIC_PRESETS: dict[str, Fabric] = {**LIBRARY_PRESETS, **SC_PRESETS}
"""what the fabric panel offers besides 'custom': the library, then SC's three"""


def sloper_kinds() -> list[str]:
    """The slopers couture.pattern can draft."""
    return list(SLOPERS)


def sloper_options(kind: str) -> tuple[Option, ...]:
    """The option table of a sloper (default, min, max, unit); none for a
    design of free-form pieces (sloper kind 'none')."""
    return tuple(SLOPERS[kind].options) if kind in SLOPERS else ()


def option_values(design: Any) -> dict[str, float]:
    """The design's option values short of the table defaults: its own params,
    over the named body's measurements for a sloper drafted from the body
    (``couture.pattern.draft.sloper_params``); its own params alone where the
    sloper or body is unknown (drafting reports those)."""
    from couture.pattern.draft import sloper_params
    from couture.pattern.errors import PatternError

    try:
        return sloper_params(design)
    except (PatternError, ValueError):
        return dict(design.sloper.params)

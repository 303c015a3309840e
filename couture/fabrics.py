"""The fabric library: named real fabrics (data in ``couture/assets/fabrics/library.toml``).

    from couture import fabrics
    fabrics.names()                  # ['canvas', 'chiffon', ..., 'wool_suiting']
    fabrics.get("denim")             # a schemas.design.Fabric, named 'denim'
    fabrics.source("denim")          # field -> where its number comes from
    fabrics.entry("denim").valid_strain

Every entry carries the directional values (warp, weft, shear stiffness
[N/m]; warp, weft, bias bending [N m]; thickness [m]) and the isotropic
fallbacks (``stretch_stiffness``, ``bend_stiffness``) a model without the
directional path reads, each number with its source; an entry whose fabric
was also drape-tested in the paper its numbers come from may carry that
Cusick drape coefficient (``measured_dc``, with ``measured_dc_diameter``),
which ``couture bench fabric`` sets beside its own. The file is checked
when read: every value through :func:`couture.pattern.limits.check_fabric`,
every number with a source; a bad entry raises :class:`FabricLibraryError`
naming the file, the fabric and the field. Bus-free and cheap (no numba).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import msgspec

from couture.pattern.errors import PatternError
from couture.pattern.limits import check_fabric
from schemas.design import Fabric

LIBRARY = Path(__file__).resolve().parent / "assets" / "fabrics" / "library.toml"
"""the shipped library"""

NUMBERS = (
    "area_density",
    "thickness",
    "warp_stiffness",
    "weft_stiffness",
    "shear_stiffness",
    "poisson_ratio",
    "bend_warp",
    "bend_weft",
    "bend_bias",
    "stretch_stiffness",
    "bend_stiffness",
    "friction_static",
    "friction_kinetic",
)
"""the Fabric fields every library entry gives (all of them, each with a source)"""

MEASURED_DRAPE = ("measured_dc", "measured_dc_diameter")
"""optional, together: a published Cusick drape coefficient of the very fabric an
entry's numbers were measured on, and the specimen diameter [m] it was measured
with (ISO 9073-9 allows 24, 30 and 36 cm discs, whose coefficients differ);
the coefficient's source 'measured:', naming the paper and its table"""

KINDS = ("woven", "knit")


class FabricLibraryError(ValueError):
    """A library file that cannot be used; the message names file, fabric and field."""


@dataclass(frozen=True)
class FabricEntry:
    """One library fabric: the Fabric the model reads plus what the library knows about it."""

    name: str
    label: str
    """what a designer calls it, e.g. 'Denim (3/1 cotton twill, ~12 oz/yd2)'"""
    kind: str
    """'woven' or 'knit'"""
    fabric: Fabric
    valid_strain: float
    """strain up to which the linear (draping-range) stiffness fit holds"""
    sources: dict[str, str]
    """field -> its source and conversion ('measured: ...' or 'estimate: ...')"""
    measured_dc: float | None = None
    """a published Cusick drape coefficient (0..1) of this fabric, if one was found (see MEASURED_DRAPE)"""
    measured_dc_diameter: float | None = None
    """[m] the specimen diameter that coefficient was measured with"""

    @property
    def bending_length_warp(self) -> float:
        """[m] Peirce's bending length c = (G / (w g))^(1/3) of a warp strip."""
        return peirce_bending_length(self.fabric.bend_warp or self.fabric.bend_stiffness, self.fabric.area_density)


def peirce_bending_length(rigidity: float, area_density: float, gravity: float = 9.81) -> float:
    """[m] c = (G / (w g))^(1/3) for rigidity per width G [N m] and area density w [kg/m^2] (Peirce 1930)."""
    return float((rigidity / (area_density * gravity)) ** (1.0 / 3.0))


def _fail(path: Path, where: str, what: str) -> FabricLibraryError:
    return FabricLibraryError(f"{path}: {where}: {what}")


def _entry(path: Path, name: str, raw: object) -> FabricEntry:
    if not isinstance(raw, dict):
        raise _fail(path, f"fabric.{name}", "not a table")
    known = set(NUMBERS) | set(MEASURED_DRAPE) | {"label", "kind", "valid_strain", "source"}
    extra = sorted(set(raw) - known)
    if extra:
        raise _fail(path, f"fabric.{name}.{extra[0]}", f"unknown field (known: {sorted(known)})")
    sources = raw.get("source")
    if not isinstance(sources, dict):
        raise _fail(path, f"fabric.{name}.source", "missing: every number needs its source")
    values: dict[str, float] = {}
    for field in (*NUMBERS, "valid_strain"):
        if field not in raw:
            raise _fail(path, f"fabric.{name}.{field}", "missing")
        v = raw[field]
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise _fail(path, f"fabric.{name}.{field}", f"{v!r} is not a finite number")
        values[field] = float(v)
        src = sources.get(field)
        if not isinstance(src, str) or not src.strip():
            raise _fail(path, f"fabric.{name}.source.{field}", "missing: every number needs its source")
    kind = raw.get("kind")
    if kind not in KINDS:
        raise _fail(path, f"fabric.{name}.kind", f"{kind!r}: use one of {list(KINDS)}")
    label = raw.get("label")
    if not isinstance(label, str) or not label:
        raise _fail(path, f"fabric.{name}.label", "missing")
    if not 0.0 < values["valid_strain"] <= 1.0:
        raise _fail(path, f"fabric.{name}.valid_strain", f"{values['valid_strain']} is outside (0, 1]")
    strain = values.pop("valid_strain")
    drape = _measured_drape(path, name, raw, sources)
    fabric = Fabric(name=name, **values)
    try:
        check_fabric(fabric, prefix=f"fabric.{name}")
    except PatternError as e:
        raise FabricLibraryError(f"{path}: {e}") from None
    return FabricEntry(name, label, kind, fabric, strain, {k: str(v) for k, v in sources.items()}, *drape)


def _measured_drape(
    path: Path, name: str, raw: dict[str, object], sources: dict[str, object]
) -> tuple[float | None, float | None]:
    """(measured_dc, measured_dc_diameter) of an entry, both or neither, each with a source, the DC's 'measured:'."""
    given = [f for f in MEASURED_DRAPE if f in raw]
    if not given:
        return None, None
    if len(given) == 1:
        missing = next(f for f in MEASURED_DRAPE if f not in raw)
        raise _fail(path, f"fabric.{name}.{missing}", f"missing: {given[0]} needs it (a coefficient and its specimen)")
    out = []
    for field in MEASURED_DRAPE:
        v = raw[field]
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise _fail(path, f"fabric.{name}.{field}", f"{v!r} is not a finite number")
        src = sources.get(field)
        if not isinstance(src, str) or not src.strip():
            raise _fail(path, f"fabric.{name}.source.{field}", "missing: every number needs its source")
        if field == "measured_dc" and not src.startswith("measured:"):
            raise _fail(path, f"fabric.{name}.source.{field}", "needs a 'measured: ...' source (paper, table)")
        out.append(float(v))
    dc, diameter = out
    if not 0.0 < dc < 1.0:
        raise _fail(path, f"fabric.{name}.measured_dc", f"{dc} is outside (0, 1) (a fraction, not a percentage)")
    if not 0.24 <= diameter <= 0.36:
        raise _fail(path, f"fabric.{name}.measured_dc_diameter", f"{diameter} m is not a Cusick specimen (0.24-0.36 m)")
    return dc, diameter


def load(path: str | Path = LIBRARY) -> dict[str, FabricEntry]:
    """Every fabric of a library file, checked (see the module docstring), by name."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise FabricLibraryError(f"{path}: cannot be read as TOML: {e}") from None
    table = data.get("fabric")
    if not isinstance(table, dict) or not table:
        raise _fail(path, "fabric", "no [fabric.NAME] tables")
    return {name: _entry(path, name, raw) for name, raw in sorted(table.items())}


@lru_cache(maxsize=1)
def _library() -> dict[str, FabricEntry]:
    return load(LIBRARY)


def names() -> list[str]:
    """The library's fabric names, sorted."""
    return list(_library())


def entry(name: str) -> FabricEntry:
    """The library entry ``name``; a ValueError listing the names otherwise."""
    try:
        return _library()[name]
    except KeyError:
        raise ValueError(f"unknown fabric {name!r}; the library has {names()}") from None


def get(name: str) -> Fabric:
    """The library fabric ``name`` as a design's Fabric (a fresh copy)."""
    return msgspec.structs.replace(entry(name).fabric)


def source(name: str) -> dict[str, str]:
    """field -> where the library's number for fabric ``name`` comes from."""
    return dict(entry(name).sources)


def references() -> dict[str, str]:
    """The library's [sources] table: short key -> full reference."""
    data = tomllib.loads(LIBRARY.read_text())
    return {str(k): str(v) for k, v in data.get("sources", {}).items()}

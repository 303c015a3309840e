"""The bodies a design can be dressed on: the default mannequin and graded sizes.

``Design.body.name`` picks one: ``'default'`` (``couture/assets/mannequin``)
or a graded size shipped in ``couture/assets/bodies`` (``<name>.obj``, its
placement sections ``<name>.sections.npz``, and ``bodies.json``: requested and
measured ISO 8559-1 measurements). All share the default's pose, axes and
units (A-pose, metres, y up, facing +z, feet at the same floor height), so
garment placement and the solvers work on any of them.

The graded sizes were fitted once with the Anny body model
(:mod:`couture.bodies.make`, the optional extra ``couture[bodies]``) to
:data:`SIZE_TABLE`; using them needs no extra.

A design may also carry its body's own measurements (``Design.body.measurements``,
e.g. an imported pattern's measurement set): :func:`use` registers them under
the body's name in this process, and the body is built on first use by
warping the nearest shipped body (:mod:`couture.bodies.warp`, numpy and scipy
only, a few seconds) and cached under ``$COUTURE_CACHE/bodies`` or
``~/.cache/couture/bodies`` (one folder per name, measurements and warp
version), so every process that gets the design builds or finds the same body.
"""

from __future__ import annotations

import hashlib
import json
import os
from functools import lru_cache
from pathlib import Path
from typing import Any

ASSETS = Path(__file__).resolve().parents[1] / "assets"
BODIES_DIR = ASSETS / "bodies"
DEFAULT_OBJ = ASSETS / "mannequin" / "body_a_pose.obj"
DEFAULT_SECTIONS = ASSETS / "mannequin" / "sections.npz"
DEFAULT_FLOOR_Y = -0.81676
"""[m] lowest y of the default mannequin; every graded body stands on it"""

SIZE_TABLE: dict[str, dict[str, float]] = {
    "XS": {"height": 1.66, "bust_girth": 0.80, "waist_girth": 0.62, "hip_girth": 0.90, "inseam": 0.77},
    "S": {"height": 1.66, "bust_girth": 0.84, "waist_girth": 0.66, "hip_girth": 0.94, "inseam": 0.77},
    "M": {"height": 1.66, "bust_girth": 0.88, "waist_girth": 0.70, "hip_girth": 0.98, "inseam": 0.77},
    "L": {"height": 1.66, "bust_girth": 0.92, "waist_girth": 0.74, "hip_girth": 1.02, "inseam": 0.77},
    "XL": {"height": 1.66, "bust_girth": 0.96, "waist_girth": 0.78, "hip_girth": 1.06, "inseam": 0.77},
}
"""[m] requested measurements of the graded sizes (ISO 8559-1: stature, bust
girth, waist girth, hip girth, inside leg length); see SIZE_TABLE_SOURCE"""

SIZE_TABLE_SOURCE = (
    "Grading in the manner of EN 13402-3 women's sizes: bust, waist and hip girths in 4 cm steps "
    "(EN 13402-3 designates women's sizes by bust girth in 4 cm intervals, e.g. 80, 84, 88, 92, 96 cm) "
    "at one stature (1.66 m) and inside leg (0.77 m), the default mannequin's; the girths are "
    "chosen near the default mannequin (bust 0.849, waist 0.669, hip 0.976 m as measured here), "
    "not copied from the standard's tables, whose figures are not reproduced."
)


_CUSTOM: dict[str, dict[str, float]] = {}
"""bodies of measurements given to this process (register): name -> measurements [m]"""


def _index() -> dict:
    path = BODIES_DIR / "bodies.json"
    return json.loads(path.read_text()) if path.exists() else {"bodies": {}}


@lru_cache(maxsize=1)
def index() -> dict:
    """bodies.json: requested and measured measurements of every graded body."""
    return _index()


def shipped_names() -> tuple[str, ...]:
    """'default', then the graded sizes shipped."""
    shipped = [n for n in index()["bodies"] if (BODIES_DIR / f"{n}.obj").exists()]
    return ("default", *shipped)


def names() -> tuple[str, ...]:
    """Every body a design may name: 'default', the graded sizes shipped, then
    the bodies of measurements this process was given (:func:`register`)."""
    return (*shipped_names(), *_CUSTOM)


WARP_VERSION = 1
"""bump when couture.bodies.warp changes the bodies it makes (a new cache folder)"""
SECTIONS_VERSION = 2
"""bump when couture.pattern.sections changes the tables it measures (a new file in the folder)"""


def _valid_name(name: str) -> bool:
    return bool(name) and len(name) <= 64 and name.replace("_", "").replace("-", "").isalnum()


def register(name: str, measurements: dict[str, float]) -> str:
    """Let ``name`` stand in this process for the body of ``measurements``
    ({ISO 8559-1 name: metres}, couture.bodies.warp.check_measurements); ValueError
    naming the field for bad measurements, a shipped name, or a name this process
    already holds for other measurements."""
    from couture.bodies.warp import check_measurements

    if name in shipped_names():
        raise ValueError(f"body.name: {name!r} is a shipped body; a body of measurements needs a name of its own")
    if not _valid_name(name):
        raise ValueError(f"body.name: {name!r}: use up to 64 letters, digits, '-' or '_'")
    meas = check_measurements(measurements, "body.measurements")
    old = _CUSTOM.get(name)
    if old is not None and old != meas:
        raise ValueError(
            f"body.name: {name!r} already stands for other measurements in this process ({old}); give it another name"
        )
    _CUSTOM[name] = meas
    return name


def use(body: Any) -> str:
    """The name of a design's body (``schemas.design.Body``), registering its
    measurements when it carries any (:func:`register`); ValueError as register
    and check_name."""
    if getattr(body, "measurements", None):
        return register(body.name, body.measurements)
    return check_name(body.name)


def cache_root() -> Path:
    """Where bodies of measurements are built: ``$COUTURE_CACHE/bodies`` or ``~/.cache/couture/bodies``."""
    return Path(os.environ.get("COUTURE_CACHE", Path.home() / ".cache" / "couture")) / "bodies"


def custom_dir(name: str) -> Path:
    """The cache folder of a registered body (built on first call): body.obj,
    body.json (requested and measured measurements, the warp's record) and,
    once the pattern asks, sections_v<SECTIONS_VERSION>.npz."""
    meas = _CUSTOM[check_name(name)]
    key = json.dumps({"name": name, "measurements": meas, "warp": WARP_VERSION}, sort_keys=True)
    folder = cache_root() / f"{name}-{hashlib.sha256(key.encode()).hexdigest()[:16]}"
    if not (folder / "body.json").exists():
        _build(folder, name, meas)
    return folder


def _build(folder: Path, name: str, meas: dict[str, float]) -> None:
    from couture.bodies.measure import measure

    r = warp_to(meas)
    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / f"body.obj.{os.getpid()}.tmp"
    write_obj(
        tmp,
        r.vertices,
        r.faces,
        f"couture body {name!r} of measurements {meas} [m]: the shipped body {r.template!r} warped by "
        "couture.bodies.warp; metres, y up, facing +z",
    )
    tmp.replace(folder / "body.obj")
    V, F = _read(folder / "body.obj", process=True)
    rec = {
        "name": name,
        "requested": meas,
        "measured": {k: round(v, 5) for k, v in measure(V, F).items()},
        "method": f"warp v{WARP_VERSION} of {r.template!r}",
        "factors": {k: round(v, 6) for k, v in r.factors.items()},
        "iterations": r.iterations,
        "seconds": round(r.seconds, 2),
    }
    tmp = folder / f"body.json.{os.getpid()}.tmp"
    tmp.write_text(json.dumps(rec, indent=2) + "\n")
    tmp.replace(folder / "body.json")  # last: its presence says the folder is whole


def warp_to(target: dict[str, float], template: str | None = None, **kw: Any):
    """:func:`couture.bodies.warp.warp_body` of the shipped body ``template``
    (default the one whose girths are nearest ``target``'s)."""
    from couture.bodies.warp import check_measurements, nearest_template, warp_body

    target = check_measurements(target)
    template = template or nearest_template(target, {n: measured(n) for n in shipped_names()})
    return warp_body(target, template, load_mesh(template), measured(template), **kw)


def custom_record(name: str) -> dict[str, Any]:
    """A registered body's record (body.json of :func:`custom_dir`)."""
    return json.loads((custom_dir(name) / "body.json").read_text())


def check_name(name: str) -> str:
    """``name`` if it is a body; ValueError naming it and the bodies otherwise."""
    if name not in names():
        raise ValueError(f"unknown body {name!r}; bodies are {list(names())}")
    return name


def obj_path(name: str = "default") -> Path:
    if check_name(name) in _CUSTOM:
        return custom_dir(name) / "body.obj"
    return DEFAULT_OBJ if name == "default" else BODIES_DIR / f"{name}.obj"


def sections_path(name: str = "default") -> Path:
    """Where a body's placement sections are (a registered body's are written
    there on first use by couture.pattern.sections)."""
    if check_name(name) in _CUSTOM:
        return custom_dir(name) / f"sections_v{SECTIONS_VERSION}.npz"
    return DEFAULT_SECTIONS if name == "default" else BODIES_DIR / f"{name}.sections.npz"


def write_obj(path: Path, V, F, header: str) -> None:
    """A body mesh as Wavefront OBJ: ``header`` as comments, vertices [m], faces."""
    lines = [f"# {h}" for h in header.splitlines()]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in V]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in F]
    path.write_text("\n".join(lines) + "\n")


def _read(path: Path, process: bool):
    import numpy as np
    import trimesh

    mesh: Any = trimesh.load(str(path), force="mesh", process=process)
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


def load_mesh(name: str = "default"):
    """(vertices (n, 3), faces (m, 3)) of a body [m], y up."""
    return _read(obj_path(name), process=True)


def table() -> list[dict[str, Any]]:
    """One row per body: name, requested and measured values [m] and their
    difference (the default has no request: its measurements are its own)."""
    from couture.bodies.measure import MEASURES

    rows: list[dict[str, Any]] = [{"name": "default", "requested": None, "measured": _default_measured()}]
    for name, rec in index()["bodies"].items():
        rows.append({"name": name, "requested": rec["requested"], "measured": rec["measured"]})
    for name in _CUSTOM:
        rec = custom_record(name)
        rows.append({"name": name, "requested": rec["requested"], "measured": rec["measured"]})
    for r in rows:
        req, got = r["requested"], r["measured"]
        r["error"] = None if req is None else {k: round(got[k] - req[k], 5) for k in MEASURES if k in req}
    return rows


def measured(name: str = "default") -> dict[str, float]:
    """A body's measurements [m] (``couture.bodies.measure``): girths and landmark heights."""
    if check_name(name) == "default":
        return _default_measured()
    if name in _CUSTOM:
        return dict(custom_record(name)["measured"])
    return dict(index()["bodies"][name]["measured"])


@lru_cache(maxsize=1)
def _default_measured() -> dict[str, float]:
    from couture.bodies.measure import measure

    V, F = _read(DEFAULT_OBJ, process=False)
    return {k: round(v, 5) for k, v in measure(V, F).items()}

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
"""

from __future__ import annotations

import json
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


def _index() -> dict:
    path = BODIES_DIR / "bodies.json"
    return json.loads(path.read_text()) if path.exists() else {"bodies": {}}


@lru_cache(maxsize=1)
def index() -> dict:
    """bodies.json: requested and measured measurements of every graded body."""
    return _index()


def names() -> tuple[str, ...]:
    """Every body a design may name: 'default', then the graded sizes shipped."""
    shipped = [n for n in index()["bodies"] if (BODIES_DIR / f"{n}.obj").exists()]
    return ("default", *shipped)


def check_name(name: str) -> str:
    """``name`` if it is a body; ValueError naming it and the bodies otherwise."""
    if name not in names():
        raise ValueError(f"unknown body {name!r}; bodies are {list(names())}")
    return name


def obj_path(name: str = "default") -> Path:
    return DEFAULT_OBJ if check_name(name) == "default" else BODIES_DIR / f"{name}.obj"


def sections_path(name: str = "default") -> Path:
    return DEFAULT_SECTIONS if check_name(name) == "default" else BODIES_DIR / f"{name}.sections.npz"


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
    for r in rows:
        req, got = r["requested"], r["measured"]
        r["error"] = None if req is None else {k: round(got[k] - req[k], 5) for k in MEASURES}
    return rows


def measured(name: str = "default") -> dict[str, float]:
    """A body's measurements [m] (``couture.bodies.measure``): girths and landmark heights."""
    if check_name(name) == "default":
        return _default_measured()
    return dict(index()["bodies"][name]["measured"])


@lru_cache(maxsize=1)
def _default_measured() -> dict[str, float]:
    from couture.bodies.measure import measure

    V, F = _read(DEFAULT_OBJ, process=False)
    return {k: round(v, 5) for k, v in measure(V, F).items()}

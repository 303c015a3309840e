"""Physical ranges of a design's numbers (fabric, resolution, body), checked
before anything is drafted or simulated.

Each range is data (:data:`FABRIC_LIMITS`, :data:`RESOLUTION_LIMITS`) and a
value outside it raises :class:`PatternError` naming the field as a path
into the design (``'fabric.area_density'``), the value and the range, e.g.
``fabric.stretch_stiffness: 0 N/m is outside (0, 1e+06] N/m (in-plane
stiffness E·h; woven cloth 10..2000)``. The bounds are physical where physics
gives one (a density or a stiffness is positive, Poisson's ratio of an
isotropic sheet is below 1/2, kinetic friction does not exceed static) and
otherwise far beyond any fabric, to keep the numbers finite downstream (a
stiffness of 1e308 overflows the first force it makes). Lower bounds are
positive where a vanishing value has no equilibrium to find (a fabric with
no stretch stiffness, or no weight to scale the residual by).

The remesher checks them first (:func:`couture.pattern.validate.validate`),
and a solver again before it builds a cloth model from a design
(:class:`couture.solvers.service.SolveService`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from couture.pattern.errors import PatternError
from schemas.design import Body, Design, Fabric, Resolution


@dataclass(frozen=True)
class Limit:
    """An interval of allowed values, with its unit and a line of context."""

    lo: float
    hi: float
    unit: str = ""
    what: str = ""
    """what the value is and its usual range, for the message"""
    lo_open: bool = False
    """lo itself is not allowed"""
    hi_open: bool = False
    """hi itself is not allowed"""

    def contains(self, v: float) -> bool:
        if not math.isfinite(v):
            return False
        above = v > self.lo if self.lo_open else v >= self.lo
        below = v < self.hi if self.hi_open else v <= self.hi
        return above and below

    def text(self) -> str:
        """'(0, 1e+06] N/m'"""
        lo = "(" if self.lo_open else "["
        hi = ")" if self.hi_open else "]"
        return f"{lo}{self.lo:g}, {self.hi:g}{hi}" + (f" {self.unit}" if self.unit else "")


FABRIC_LIMITS: dict[str, Limit] = {
    "stretch_stiffness": Limit(
        1e-1, 1e6, "N/m", "in-plane stiffness E·h, > 0; woven cloth 10..2000, the UI offers 1..1e4"
    ),
    "poisson_ratio": Limit(0.0, 0.5, "", "Poisson's ratio of an isotropic sheet, 0 <= nu < 0.5", hi_open=True),
    "bend_stiffness": Limit(0.0, 1.0, "N m", "bending stiffness, >= 0 (0: a membrane); cloth 1e-8..3e-4"),
    "area_density": Limit(1e-3, 10.0, "kg/m^2", "mass per area, > 0; cloth 0.08..0.2"),
    "friction_static": Limit(0.0, 10.0, "", "Coulomb static coefficient against the body, >= 0; cloth on skin ~0.5"),
    "friction_kinetic": Limit(
        0.0, 10.0, "", "Coulomb kinetic coefficient against the body, >= 0 and at most friction_static"
    ),
}
"""Fabric field -> allowed values (see the module docstring for why each bound)"""

DIRECTIONAL_LIMITS: dict[str, Limit] = {
    "warp_stiffness": Limit(1e-1, 1e6, "N/m", "tensile stiffness along the warp, > 0; wovens 100..10000"),
    "weft_stiffness": Limit(1e-1, 1e6, "N/m", "tensile stiffness along the weft, > 0; wovens 50..10000"),
    "shear_stiffness": Limit(1e-2, 1e6, "N/m", "in-plane shear stiffness, > 0; wovens 1..500"),
    "bend_warp": Limit(0.0, 1.0, "N m", "bending rigidity of a warp strip, >= 0; cloth 1e-8..3e-4"),
    "bend_weft": Limit(0.0, 1.0, "N m", "bending rigidity of a weft strip, >= 0; cloth 1e-8..3e-4"),
    "bend_bias": Limit(0.0, 1.0, "N m", "bending rigidity of a bias strip, >= 0; cloth 1e-8..3e-4"),
    "thickness": Limit(1e-6, 0.05, "m", "the fabric's thickness, > 0; cloth 0.1..5 mm"),
}
"""Optional (directional) Fabric field -> allowed values, checked where given"""

RESOLUTION_LIMITS: dict[str, Limit] = {
    "coarse_vertices": Limit(50, 250_000, "vertices", "target size of the coarse mesh; default 1600"),
    "fine_vertices": Limit(50, 250_000, "vertices", "target size of the fine mesh; default 10000"),
}
"""Resolution field -> allowed target vertex counts (a few hundred to the largest meshes measured, 40k, x6)"""


def check_body(body: Body | str) -> None:
    """A body a design may name ('default' or a graded size of couture.bodies,
    or any name with its own measurements, which this registers:
    couture.bodies.use); PatternError naming the field and the bodies otherwise."""
    from couture import bodies

    if not isinstance(body, str) and body.measurements:
        try:
            bodies.use(body)
        except ValueError as e:
            field, _, msg = str(e).partition(": ")
            raise PatternError(field if field.startswith("body.") else "body.measurements", msg or str(e)) from None
        return
    name = body if isinstance(body, str) else body.name
    if name not in bodies.names():
        raise PatternError("body.name", f"unknown mannequin {name!r}; mannequins are {list(bodies.names())}")


def _number(element: str, v: object) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise PatternError(element, f"{v!r} is not a number")
    return float(v)


def _check(element: str, v: float, lim: Limit) -> None:
    if lim.contains(v):
        return
    unit = f" {lim.unit}" if lim.unit else ""
    shown = f"{v:g}{unit}" if math.isfinite(v) else f"{v} (not finite)"
    raise PatternError(element, f"{shown} is outside the allowed range {lim.text()} ({lim.what})")


def check_fabric(fabric: Fabric, prefix: str = "fabric") -> None:
    """Every fabric number inside its :data:`FABRIC_LIMITS` range, and kinetic
    friction at most static; raises PatternError naming ``fabric.<field>``."""
    for name, lim in FABRIC_LIMITS.items():
        _check(f"{prefix}.{name}", _number(f"{prefix}.{name}", getattr(fabric, name)), lim)
    for name, lim in DIRECTIONAL_LIMITS.items():
        v = getattr(fabric, name)
        if v is not None:
            _check(f"{prefix}.{name}", _number(f"{prefix}.{name}", v), lim)
    if fabric.friction_kinetic > fabric.friction_static:
        raise PatternError(
            f"{prefix}.friction_kinetic",
            f"{fabric.friction_kinetic:g} exceeds friction_static {fabric.friction_static:g}: "
            "kinetic friction is at most static friction (allowed [0, friction_static])",
        )


def check_resolution(res: Resolution, prefix: str = "resolution") -> None:
    """Target vertex counts whole numbers inside :data:`RESOLUTION_LIMITS`."""
    for name, lim in RESOLUTION_LIMITS.items():
        v = getattr(res, name)
        if isinstance(v, bool) or not isinstance(v, int):
            raise PatternError(f"{prefix}.{name}", f"{v!r} is not a whole number of vertices")
        _check(f"{prefix}.{name}", float(v), lim)


def check_fabrics(design: Design) -> None:
    """The design's fabric and every panel's own fabric in range."""
    check_fabric(design.fabric)
    for panel, fabric in design.panel_fabrics.items():
        check_fabric(fabric, f"panel_fabrics.{panel}")


def check_values(design: Design) -> None:
    """The design's numbers outside the drafting (fabric, resolution, body)
    in their physical ranges; raises PatternError naming the field."""
    check_fabrics(design)
    check_resolution(design.resolution)
    check_body(design.body)


def check_simulation_values(design: Design) -> None:
    """What a solver needs of a design (fabric and body), checked before it
    builds a cloth model; raises PatternError naming the field."""
    check_fabrics(design)
    check_body(design.body)

"""A design's numbers in their physical ranges (couture.pattern.limits): each
bad value is refused naming the field, the value and the allowed range, by
the remesher's validation and again by the solver service (which then keeps
the design it had); good fabrics (defaults, the UI's presets, SC Table 1's
ends) pass."""

from __future__ import annotations

import math

import msgspec
import numpy as np
import pytest

from couture.pattern import PatternError
from couture.pattern.limits import FABRIC_LIMITS, RESOLUTION_LIMITS, Limit, check_fabric, check_values
from couture.pattern.validate import validate
from couture.solvers.service import SolveService
from couture.ui.state import FABRIC_PRESETS
from schemas.design import Body, Design, Fabric, Resolution, SceneFlags

BAD_FABRIC = [
    # field, value, a piece of the allowed range as the message prints it
    ("stretch_stiffness", 0.0, "[0.1, 1e+06] N/m"),
    ("stretch_stiffness", 1e-30, "[0.1, 1e+06] N/m"),
    ("stretch_stiffness", -20.0, "[0.1, 1e+06] N/m"),
    ("stretch_stiffness", 1e308, "[0.1, 1e+06] N/m"),
    ("stretch_stiffness", math.inf, "[0.1, 1e+06] N/m"),
    ("stretch_stiffness", math.nan, "[0.1, 1e+06] N/m"),
    ("area_density", 0.0, "[0.001, 10] kg/m^2"),
    ("area_density", -0.15, "[0.001, 10] kg/m^2"),
    ("area_density", 1e300, "[0.001, 10] kg/m^2"),
    ("poisson_ratio", 0.5, "[0, 0.5)"),
    ("poisson_ratio", -0.1, "[0, 0.5)"),
    ("poisson_ratio", math.nan, "[0, 0.5)"),
    ("bend_stiffness", -1e-6, "[0, 1] N m"),
    ("bend_stiffness", 1e308, "[0, 1] N m"),
    ("friction_static", -0.5, "[0, 10]"),
    ("friction_static", math.inf, "[0, 10]"),
    ("friction_kinetic", -0.1, "[0, 10]"),
]


@pytest.mark.parametrize("field, value, allowed", BAD_FABRIC)
def test_bad_fabric_values_name_field_value_and_range(field, value, allowed):
    design = Design(fabric=msgspec.structs.replace(Fabric(), **{field: value}))
    for check in (check_values, validate):  # the limits alone, and the remesher's whole validation
        with pytest.raises(PatternError) as e:
            check(design)
        assert e.value.element == f"fabric.{field}"
        msg = str(e.value)
        assert msg.startswith(f"fabric.{field}: ") and allowed in msg, msg
        shown = f"{value:g}" if math.isfinite(value) else f"{value} (not finite)"
        assert shown in msg, msg


def test_kinetic_friction_above_static_is_refused():
    with pytest.raises(PatternError, match=r"fabric.friction_kinetic: 0.6 exceeds friction_static 0.5"):
        check_fabric(Fabric(friction_static=0.5, friction_kinetic=0.6))
    check_fabric(Fabric(friction_static=0.0, friction_kinetic=0.0))  # frictionless is fine


@pytest.mark.parametrize(
    "fabric",
    [
        Fabric(),
        *FABRIC_PRESETS.values(),
        Fabric(stretch_stiffness=10.0, bend_stiffness=1e-8, area_density=0.08, poisson_ratio=0.0),  # SC Table 1, low
        Fabric(stretch_stiffness=2000.0, bend_stiffness=3e-4, area_density=0.2, poisson_ratio=0.49),  # ... and high
        Fabric(bend_stiffness=0.0),  # a membrane: the kinetic and Newton solvers converge on it
        Fabric(stretch_stiffness=1e6),  # the ends of the ranges are allowed
    ],
)
def test_good_fabrics_pass(fabric):
    check_values(Design(fabric=fabric))


@pytest.mark.parametrize(
    "design, element, piece",
    [
        (Design(resolution=Resolution(coarse_vertices=0)), "resolution.coarse_vertices", "[50, 250000] vertices"),
        (Design(resolution=Resolution(fine_vertices=10**9)), "resolution.fine_vertices", "[50, 250000] vertices"),
        (Design(resolution=Resolution(fine_vertices=-1)), "resolution.fine_vertices", "-1 vertices"),
        (Design(body=Body(name="alien")), "body.name", "unknown mannequin 'alien'"),
    ],
)
def test_resolution_and_body(design, element, piece):
    with pytest.raises(PatternError) as e:
        validate(design)
    assert e.value.element == element and piece in str(e.value), str(e.value)


def test_limits_are_consistent():
    for name, lim in {**FABRIC_LIMITS, **RESOLUTION_LIMITS}.items():
        assert lim.lo < lim.hi and lim.what, name
        default = getattr(Fabric(), name, None)
        if default is None:
            default = getattr(Resolution(), name)
        assert lim.contains(float(default)), f"the default {name} = {default} is outside its own range"
    assert Limit(0.0, 0.5, hi_open=True).text() == "[0, 0.5)" and not Limit(0.0, 1.0).contains(math.nan)


def test_solver_service_refuses_a_bad_fabric_and_keeps_its_design():
    service = SolveService(method="newton")
    good = Design()
    service.set_design(good)
    bad = Design(fabric=Fabric(area_density=0.0))
    with pytest.raises(PatternError, match=r"fabric.area_density: 0 kg/m\^2 is outside the allowed range"):
        service.set_design(bad)
    assert service.design is good


def test_a_refused_mesh_does_not_count_as_taken():
    """A mesh whose design the solver refuses, numbered far above the
    remesher's (sent past it), leaves the matcher as it was: the remesher's
    next meshes are not stale, and edits are judged against the design held."""
    from couture.mesh import grid_sheet
    from couture.solvers.service import IncomingMesh

    def incoming(level: str, generation: int) -> IncomingMesh:
        m = grid_sheet(0.4, 0.4, 5, 5)
        m.level, m.generation = level, generation
        m.pinned = np.nonzero(m.X[:, 1] > 0.4 - 1e-9)[0].astype(np.int32)
        return IncomingMesh(m)

    service = SolveService(method="newton")
    no_body = SceneFlags(body=False, friction=False)
    good, bad = Design(scene=no_body), Design(scene=no_body, fabric=Fabric(stretch_stiffness=0.0))
    service.offer_design(3, good, "good")
    for level, mg in (("coarse", 5), ("fine", 6)):
        out = service.offer_mesh(level, 3, mg, incoming(level, 3), "good")
        assert out.matched is not None
        service.take(out.matched)
    service.offer_design(50, bad, "bad")
    out = service.offer_mesh("coarse", 50, 10_000, incoming("coarse", 50), "bad")
    assert out.matched is not None
    with pytest.raises(PatternError, match="fabric.stretch_stiffness"):
        service.take(out.matched)
    assert service.design is good and service.generation == 3 and service.judge_edit(3) == "current"
    service.offer_design(4, good2 := Design(scene=no_body, fabric=Fabric(stretch_stiffness=50.0)), "good2")
    out = service.offer_mesh("coarse", 4, 7, incoming("coarse", 4), "good2")
    assert out.status == "matched" and out.matched is not None
    service.take(out.matched)
    assert service.design is good2 and service.generation == 4


@pytest.mark.parametrize(
    "field,value", [("warp_stiffness", 0.0), ("shear_stiffness", math.nan), ("bend_bias", -1e-6), ("thickness", 1.0)]
)
def test_a_panels_own_fabric_is_checked_by_its_path(field, value):
    """A directional value outside its range, on a panel's own fabric, is
    refused naming the panel and the field; left out (None) it is not checked."""
    ok = Fabric(warp_stiffness=None, weft_stiffness=500.0)
    check_values(Design(panel_fabrics={"front": ok}))
    bad = Design(panel_fabrics={"front": msgspec.structs.replace(ok, **{field: value})})
    with pytest.raises(PatternError, match=rf"panel_fabrics\.front\.{field}"):
        check_values(bad)

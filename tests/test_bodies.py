"""Bodies by measurement: the graded sizes measure what was asked, a design
names its body (unknown names are refused, naming them), and a body change
re-drapes the current garment from its current state onto the new body."""

from __future__ import annotations

import time

import msgspec
import numpy as np
import pytest
import trimesh

from couture import bodies
from couture.bodies.measure import MEASURES, measure
from couture.pattern import mannequin as M
from couture.pattern.errors import PatternError
from schemas.design import Body, Design, Resolution, Sloper


def test_at_least_five_graded_bodies_are_shipped_with_licence():
    graded = [n for n in bodies.shipped_names() if n != "default"]
    assert len(graded) >= 5, graded
    assert (bodies.BODIES_DIR / "LICENSE").exists()
    for n in graded:
        assert bodies.sections_path(n).exists(), n


@pytest.mark.parametrize("name", [n for n in bodies.SIZE_TABLE if (bodies.BODIES_DIR / f"{n}.obj").exists()])
def test_graded_body_measures_what_was_requested(name):
    """Re-measured from the shipped mesh: every ISO 8559-1 measurement within
    1 cm of the size table; same axes and floor as the default mannequin."""
    m = trimesh.load(str(bodies.obj_path(name)), process=False)
    assert m.is_watertight
    got = measure(m.vertices, m.faces)
    want = bodies.SIZE_TABLE[name]
    for k in MEASURES:
        assert abs(got[k] - want[k]) < 0.01, (name, k, got[k], want[k])
    assert abs(got["floor_y"] - bodies.DEFAULT_FLOOR_Y) < 1e-4
    # the default's template topology, vertex for vertex: same pose, axes (y up,
    # facing +z) and units, so every vertex lies near its default counterpart
    V = np.asarray(m.vertices)
    D = np.asarray(trimesh.load(str(bodies.DEFAULT_OBJ), process=False).vertices)
    assert V.shape == D.shape
    d = np.linalg.norm(V - D, axis=1)
    assert np.median(d) < 0.04 and d.max() < 0.10, (np.median(d), d.max())
    rec = bodies.index()["bodies"][name]
    assert rec["requested"] == want
    for k in MEASURES:
        assert abs(rec["measured"][k] - got[k]) < 1e-4, (name, k)


def test_measuring_agrees_with_the_default_mannequins_constants():
    """The slicer here against the mannequin's stored measurements, which were
    taken independently (trimesh sections, couture.pattern.mannequin)."""
    V, F = bodies.load_mesh("default")
    got = measure(V, F)
    assert abs(got["waist_girth"] - M.WAIST_GIRTH) < 0.004
    assert abs(got["hip_girth"] - M.HIP_GIRTH) < 0.004
    assert abs(got["bust_girth"] - M.BUST_GIRTH) < 0.004
    assert abs(got["underarm_y"] - M.UNDERARM_Y) < 0.01
    assert abs(got["crotch_y"] - M.CROTCH_Y) < 0.01


def test_girth_of_an_ellipse_prism_is_its_perimeter():
    """A closed elliptic prism with a dent: the tape (convex hull) bridges the
    dent and reads the ellipse's perimeter (Ramanujan's formula)."""
    a, b, n = 0.15, 0.10, 256
    th = 2 * np.pi * np.arange(n) / n
    r = np.where(np.abs(th - np.pi / 2) < 0.2, 0.8, 1.0)  # a dent at the front
    ring = np.column_stack([a * r * np.cos(th), np.zeros(n), b * r * np.sin(th)])
    V = np.vstack([ring + [0, -0.5, 0], ring + [0, 0.5, 0], [[0, -0.5, 0], [0, 0.5, 0]]])
    F = []
    for i in range(n):
        j = (i + 1) % n
        F += [[i, j, n + j], [i, n + j, n + i], [2 * n, j, i], [2 * n + 1, n + i, n + j]]
    from couture.bodies.measure import Slicer

    sec = Slicer(V, np.array(F)).torso(0.1)
    h = ((a - b) / (a + b)) ** 2
    ramanujan = np.pi * (a + b) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h)))
    assert abs(sec.girth - ramanujan) < 1e-3 * ramanujan


def test_unknown_body_is_refused_naming_it():
    from couture.cloth.model import ClothModel, Scene
    from couture.mesh import grid_sheet
    from couture.pattern.validate import validate
    from couture.solvers.service import SolveService, scene_from_design

    bad = Design(body=Body(name="XXXL"))
    with pytest.raises(PatternError) as e:
        validate(bad)
    assert e.value.element == "body.name" and "'XXXL'" in str(e.value) and "'M'" in str(e.value)
    svc = SolveService()
    with pytest.raises(PatternError, match="XXXL"):
        svc.set_design(bad)
    assert svc.design is None
    with pytest.raises(ValueError, match="unknown body 'XXXL'"):
        ClothModel(grid_sheet(0.1, 0.1, 2, 2), bad.fabric, scene_from_design(bad))
    with pytest.raises(ValueError, match="unknown body 'XXXL'"):
        bodies.obj_path("XXXL")
    # the body crosses the bus in the pattern message (recordable)
    d = msgspec.msgpack.decode(msgspec.msgpack.encode(Design(body=Body(name="L"))), type=Design)
    assert d.body.name == "L" and scene_from_design(d).body == "L"
    assert Scene(body="mannequin").body == "mannequin"


def test_skirt_redrapes_on_a_larger_body_from_its_drape():
    """Drape a coarse skirt on the default body, then change only the body
    (XL: hip +8 cm): the remesher follows (same vertices), the solver rebuilds
    its model on XL's SDF and starts from the current drape; the result does
    not cross XL (deepest vertex inside less than the contact offset), while
    the default body's drape did cross it."""
    from couture.cloth.body import load_mannequin_sdf
    from couture.remesh.service import RemeshService
    from couture.solvers.service import SolveService

    design = Design(sloper=Sloper(kind="skirt"), resolution=Resolution(coarse_vertices=300, fine_vertices=400))
    remesher, solver = RemeshService(), SolveService()

    def step(d: Design, gen: int):
        ups = remesher.set_design(d, gen)
        solver.set_design(d)
        for up in ups:
            solver.set_mesh(up.level, up.mesh, up.mesh_generation)
        (run,) = solver.run(levels=("coarse",))
        remesher.note_drape("coarse", run.mesh_generation, run.result.x)
        return ups[0], run

    t0 = time.perf_counter()
    _, first = step(design, 1)
    assert first.result.converged
    x_default = first.result.x
    big = msgspec.structs.replace(design, body=Body(name="XL"))
    up, second = step(big, 2)
    assert up.how == "followed" and second.warm_start == "previous"
    assert second.result.converged
    xl = load_mannequin_sdf(verbose=False, name="XL")
    offset = solver.levels["coarse"].model.contact_offset
    phi_before = xl.phi_grad(x_default)[0]
    phi_after = xl.phi_grad(second.result.x)[0]
    assert phi_before.min() < -offset  # the drape on the default body lies inside XL ...
    assert phi_after.min() > -offset, phi_after.min()  # ... the re-drape does not
    assert time.perf_counter() - t0 < 120


def test_placement_wraps_the_chosen_body():
    """A skirt placed for XL starts outside XL (XL's own sections); the same
    skirt placed for the default body would start inside XL."""
    from couture.cloth.body import load_mannequin_sdf
    from couture.remesh.service import RemeshService

    xl = load_mannequin_sdf(verbose=False, name="XL")
    phi = {}
    for name in ("default", "XL"):
        d = Design(sloper=Sloper(kind="skirt"), body=Body(name=name), resolution=Resolution(coarse_vertices=400))
        up = RemeshService().set_design(d, 1)[0]
        phi[name] = xl.phi_grad(up.mesh.x0)[0].min()
    assert phi["XL"] > 0.0 > -0.01 > phi["default"], phi


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_body_change_on_the_bus_redrapes_on_the_new_body():
    """Across processes: the body rides in the pattern message; the solver node
    re-drapes the skirt on XL (not crossing it) after a body-only change."""
    import uuid

    from couture import supervisor
    from couture.bus import BusConfig, free_port
    from couture.client import Client
    from couture.cloth.body import load_mannequin_sdf

    session = f"b{uuid.uuid4().hex[:8]}"
    nodes = [n for n in supervisor.default_nodes(solvers=["kinetic"], ui=False) if n.name != "sensitivity"]
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=session, listen=[f"tcp/127.0.0.1:{free_port()}"]), nodes=nodes
    )
    small = Design(sloper=Sloper(kind="skirt"), resolution=Resolution(coarse_vertices=300, fine_vertices=900))
    xl = load_mannequin_sdf(verbose=False, name="XL")  # built here once, cached for the node
    with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as client:
        client.wait_nodes(["remesher", "solver-kinetic"], timeout=60)
        gen = client.publish_pattern(small, name="default body")
        first = client.wait_drape("fine", generation=gen, timeout=150, final=True)
        gen_xl = client.publish_pattern(msgspec.structs.replace(small, body=Body(name="XL")), name="XL")
        second = client.wait_drape("fine", generation=gen_xl, timeout=150, final=True)
        assert client.latest_mesh("fine").X.shape == client.mesh_of(gen).X.shape  # followed, not remeshed
        assert xl.phi_grad(first.x.numpy())[0].min() < -0.01
        assert xl.phi_grad(second.x.numpy())[0].min() > -0.01
        assert second.converged

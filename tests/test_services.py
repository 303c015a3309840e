"""The node services driven without Zenoh, the way dora's MockNode tests a node:
the shared mesh/design matcher, the solver service's matching, and the
sensitivity service through press, drag, pause, release and a 3D tug.
Small meshes (a ~50-vertex sheet), no body: every test runs in about a second
once numba's cache is warm."""

from __future__ import annotations

import numpy as np
import pytest

from couture.designs import MeshArrival, MeshMatcher
from couture.mesh import GarmentMesh, grid_sheet
from couture.pattern import SLOPERS
from couture.sensitivity.drag3d import project_jacobian
from couture.sensitivity.service import (
    NoEquilibrium,
    PredictionOut,
    Press,
    ReleaseOut,
    SensitivityConfig,
    SensitivityService,
)
from couture.solvers import get_solver
from couture.solvers.service import IncomingMesh, SolveService
from schemas.design import Design, Fabric, SceneFlags, Sloper

SIZE = 0.4


def design(stretch: float = 20.0, **params: float) -> Design:
    """A skirt design whose scene has no body (so models build in milliseconds)."""
    return Design(
        sloper=Sloper(kind="skirt", params=dict(params)),
        fabric=Fabric(stretch_stiffness=stretch),
        scene=SceneFlags(body=False, friction=False),
    )


def sheet(level: str = "fine", generation: int = 1, n: int = 7) -> GarmentMesh:
    """A hanging sheet: pinned along its top edge, the rest free under gravity."""
    m = grid_sheet(SIZE, SIZE, n, n)
    m.level, m.generation = level, generation
    m.pinned = np.nonzero(m.X[:, 1] > SIZE - 1e-9)[0].astype(np.int32)
    m.x0 = np.column_stack([m.X[:, 0], m.X[:, 1] - SIZE, np.zeros(m.n_vertices)])
    return m


# -- the shared matcher ---------------------------------------------------------


def arrival(level: str, generation: int, mesh_generation: int) -> MeshArrival[str]:
    return MeshArrival(level, generation, mesh_generation, f"{level}{mesh_generation}")


def test_matcher_parks_a_mesh_until_its_pattern_arrives():
    m: MeshMatcher[str] = MeshMatcher()
    assert m.add_mesh(arrival("fine", 1, 1)).status == "parked"
    assert m.add_mesh(arrival("coarse", 1, 1)).status == "parked"
    assert m.add_design(0, design()) == []  # an older design does not release them
    released = m.add_design(1, d1 := design(length=0.5))
    assert sorted(r.mesh.level for r in released) == ["coarse", "fine"]
    assert all(r.design is d1 for r in released)
    assert m.parked() == []


def test_matcher_drops_repeats_and_stale_meshes():
    m: MeshMatcher[str] = MeshMatcher()
    m.add_design(1, design())
    assert m.add_mesh(arrival("fine", 1, 3)).status == "matched"
    assert m.add_mesh(arrival("fine", 1, 3)).status == "repeat"  # Ψ re-send of the mesh held
    assert m.add_mesh(arrival("fine", 1, 2)).status == "stale"
    assert m.add_mesh(arrival("coarse", 1, 2)).status == "matched"  # levels are independent
    assert (m.repeats, m.stale) == (1, 1)


def test_matcher_two_designs_in_a_row_each_mesh_gets_its_own():
    m: MeshMatcher[str] = MeshMatcher()
    d1, d2 = design(length=0.5), design(length=0.6)
    m.add_design(1, d1)
    m.add_design(2, d2)
    a = m.add_mesh(arrival("fine", 1, 1))
    b = m.add_mesh(arrival("fine", 2, 2))
    assert a.matched is not None and a.matched.design is d1
    assert b.matched is not None and b.matched.design is d2


def test_matcher_newer_parked_mesh_replaces_older_and_a_lost_pattern_gets_no_stand_in():
    m: MeshMatcher[str] = MeshMatcher()
    m.add_design(1, design())
    m.add_mesh(arrival("fine", 2, 5))
    assert m.add_mesh(arrival("fine", 3, 6)).status == "parked"  # replaces the parked 5
    assert m.add_mesh(arrival("fine", 2, 4)).status == "stale"  # older than the parked one
    # pattern 3 lost, pattern 4 arrived: mesh 6 is of design 3 and no other
    # design's fabric stands in for it (that would drape it wrongly)
    assert m.add_design(4, design(length=0.7)) == []
    assert [p.mesh_generation for p in m.parked()] == [6]
    (r,) = m.add_design(3, d3 := design(length=0.65))  # late, but it comes
    assert r.design is d3 and m.newest == 3


# -- the solver service's matching ----------------------------------------------


def test_solver_service_takes_meshes_only_with_their_design():
    s = SolveService(method="newton")
    fine, coarse = sheet("fine", 1, 7), sheet("coarse", 1, 5)
    assert s.offer_mesh("fine", 1, 1, IncomingMesh(fine)).status == "parked"
    out = s.offer_mesh("coarse", 1, 1, IncomingMesh(coarse))
    assert out.status == "parked" and not s.ready()
    released = s.offer_design(1, d1 := design())
    assert len(released) == 2
    ready = [s.take(m) for m in released]
    assert ready[-1] and s.ready() and s.design is d1
    assert s.levels["fine"].model.mu == pytest.approx(20.0 / 2.6)
    # Ψ re-send and stale mesh: nothing taken
    assert s.offer_mesh("fine", 1, 1, IncomingMesh(fine)).status == "repeat"
    # a second design with a stiffer fabric and its meshes: the models follow it
    s.offer_design(2, d2 := design(stretch=200.0))
    for level, mesh in (("coarse", sheet("coarse", 2, 5)), ("fine", sheet("fine", 2, 7))):
        out = s.offer_mesh(level, 2, 2, IncomingMesh(mesh))
        assert out.matched is not None and out.matched.design is d2
        s.take(out.matched)
    assert s.ready() and s.levels["fine"].mesh_generation == 2
    assert s.levels["fine"].model.mu == pytest.approx(200.0 / 2.6)
    assert s.offer_mesh("fine", 1, 1, IncomingMesh(fine)).status == "stale"


def test_scene_stiffness_factors_scale_the_models_defaults_in_solver_and_sensitivity():
    """``SceneFlags.seam_stiffness_scale`` / ``contact_stiffness_scale`` multiply
    the model's default seam and contact stiffnesses, in every model a node
    builds from a design (solver and sensitivity alike); a change rebuilds them."""
    import msgspec

    from couture.solvers.service import scene_from_design

    base = design()
    scaled = msgspec.structs.replace(
        base, scene=msgspec.structs.replace(base.scene, seam_stiffness_scale=0.1, contact_stiffness_scale=10.0)
    )
    s = SolveService(method="newton")
    s.set_design(base)
    s.set_mesh("fine", sheet(), 1)
    m0 = s.levels["fine"].model
    assert s.set_design(scaled), "a new factor is a new scene: the models are rebuilt"
    m1 = s.levels["fine"].model
    assert m1 is not m0
    assert m1.seam_stiffness == pytest.approx(0.1 * m0.seam_stiffness)
    assert m1.contact_stiffness == pytest.approx(10.0 * m0.contact_stiffness)
    sens = SensitivityService()
    sens.offer_design(1, scaled)
    sens.take(sens.offer_mesh(1, 1, sheet()).matched)
    assert sens.model is not None and sens.model.seam_stiffness == pytest.approx(m1.seam_stiffness)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        flags = msgspec.structs.replace(base.scene, seam_stiffness_scale=bad)
        with pytest.raises(ValueError, match="scene.seam_stiffness_scale"):
            scene_from_design(msgspec.structs.replace(base, scene=flags))


# -- the sensitivity service ------------------------------------------------------


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture(scope="module")
def equilibrium():
    """The fine sheet's equilibrium (mesh generation 1 of design generation 1)."""
    mesh = sheet()
    s = SensitivityService()
    s.offer_design(1, design())
    s.take(s.offer_mesh(1, 1, mesh).matched)
    r = get_solver("newton").solve(s.model, mesh.x0, tol=1e-10, max_iters=200)
    assert r.converged, r.diagnosis
    return mesh, r.x


def ready_service(equilibrium, clock=None, **cfg) -> SensitivityService:
    mesh, x = equilibrium
    s = SensitivityService(SensitivityConfig(**cfg), clock=clock or Clock())
    assert s.offer_mesh(1, 1, mesh).status == "parked"  # before its pattern
    (m,) = s.offer_design(1, design())
    s.take(m)
    assert s.model is not None and s.mesh_generation == 1
    assert s.equilibrium(1, x) is not None
    return s


def stretch_psi(X: np.ndarray) -> np.ndarray:
    """Ψ (n, 2, 2) of a drag of the free bottom edge: rest motion fades to 0 at the pinned top."""
    w = (SIZE - X[:, 1]) / SIZE
    psi = np.zeros((len(X), 2, 2))
    psi[:, 0, 0] = w
    psi[:, 1, 1] = w
    return psi


def test_sensitivity_2d_gesture_press_drag_estimate_release(equilibrium):
    mesh, x_eq = equilibrium
    s = ready_service(equilibrium)
    s.press(Press(edit_id="e1", element="cv:front:hem:0", generation=1))
    assert s.drag("e1", np.array([0.01, 0.0])) is None  # no Ψ yet: no prediction
    assert s.psi("e1", stretch_psi(mesh.X)) is not None
    assert s.drag("other", np.zeros(2)) is None  # another gesture's drag
    d = np.array([0.0, -0.02])  # pull the hem down 2 cm
    out = s.drag("e1", d)
    assert out is not None and out.edit_id == "e1" and out.mesh_generation == 1 and out.generation == 1
    np.testing.assert_array_equal(out.d, d)
    assert out.method in ("linear", "gmls") and out.error_estimate is None and not out.release
    dy = out.x[:, 1] - x_eq[:, 1]
    assert dy[mesh.pinned].max() == 0.0 and dy.min() < -0.005  # the free part moves down, pins stay
    assert s.readiness().regularization == "none"  # the exact linearisation factored as it is
    est = s.estimate(out)
    assert est is not None and np.isfinite(est.error_estimate) and est.error_estimate < 0.1
    # and its distance estimate [m], which the UI shows in mm
    assert est.error_estimate_m is not None and 0.0 < est.error_estimate_m < 0.1
    newer = s.drag("e1", 2 * d)
    assert s.estimate(out) is None and newer is not None  # superseded
    # a solver drape during the gesture does not move the equilibrium
    assert s.equilibrium(1, x_eq + 0.01) is None
    r = s.release("e1", d)
    assert r is not None and r.prediction is not None and r.prediction.release and r.design is None
    assert s.gesture is None and s.drag("e1", d) is None


def test_sensitivity_pause_enriches_the_cache(equilibrium):
    mesh, _ = equilibrium
    clock = Clock()
    s = ready_service(equilibrium, clock, pause_s=0.3, enrich_tol=1e-8)
    s.press(Press(edit_id="e2", element="cv:front:hem:0", generation=1))
    s.psi("e2", stretch_psi(mesh.X))
    d = np.array([0.0, -0.05])
    assert s.moved("e2") and s.drag("e2", d) is not None
    clock.t += 0.1
    assert s.pause() is None  # still moving
    clock.t += 0.3
    g = s.pause()
    assert g is not None and s.pause() is None  # one idle solve per rest
    before = len(s.predictor.cache)
    out = s.enrich(g)
    assert out is not None and len(s.predictor.cache) == before + 1
    assert out.error_estimate is not None and out.error_estimate < 1e-6
    assert s.release("e2", d) is not None and s.enrich(g) is None  # the gesture is over


def test_sensitivity_without_equilibrium_says_so():
    s = SensitivityService(clock=Clock())
    assert s.press(Press(edit_id="e3", element="cv:front:hem:0", generation=1)) is None  # no mesh held at all
    s.offer_design(1, design())
    s.take(s.offer_mesh(1, 1, sheet()).matched)
    assert s.press(Press(edit_id="e3", element="cv:front:hem:0", generation=1)) is not None
    with pytest.raises(NoEquilibrium):
        s.psi("e3", np.zeros((5, 2, 2)))  # Ψ of another mesh


def test_sensitivity_holds_a_press_until_its_equilibrium(equilibrium):
    """A press, its drags and its release that come before the drape's
    refactorization wait for it (only the latest drag kept); once the
    equilibrium is there the held gesture is predicted and released. One
    held past hold_s is given up and counted."""
    mesh, x_eq = equilibrium
    clock, counted = Clock(), []
    s = SensitivityService(SensitivityConfig(hold_s=2.0), clock=clock, count=counted.append)
    s.offer_design(1, design())
    s.take(s.offer_mesh(1, 1, mesh).matched)
    assert not s.readiness().ready
    g = s.press(Press(edit_id="h1", element="cv:front:hem:0", generation=1))
    assert g is not None and counted == ["gestures_held"]
    assert s.psi("h1", stretch_psi(mesh.X)) is g and not g.ready  # held, not an error
    assert s.drag("h1", np.array([0.0, -0.01])) is None
    d = np.array([0.0, -0.02])
    assert s.drag("h1", d) is None  # the latest drag is the one kept
    assert s.resume() is None  # still no equilibrium
    clock.t += 1.0
    assert s.expire() is None  # within hold_s
    assert s.equilibrium(1, x_eq) is not None  # the gesture has no columns yet: the drape is taken
    r = s.readiness()
    assert r.ready and r.generation == 1 and r.mesh_generation == 1
    out = s.resume()
    assert isinstance(out, PredictionOut) and out.edit_id == "h1" and g.ready
    np.testing.assert_array_equal(out.d, d)
    dy = out.x[:, 1] - x_eq[:, 1]
    assert dy[mesh.pinned].max() == 0.0 and dy.min() < -0.005  # pulled down, as the held drag asked
    assert s.resume() is None  # nothing more waits
    # the designer's release came while held: it ends the gesture once served
    s2 = SensitivityService(SensitivityConfig(hold_s=2.0), clock=clock)
    s2.offer_design(1, design())
    s2.take(s2.offer_mesh(1, 1, mesh).matched)
    s2.press(Press(edit_id="h2", element="cv:front:hem:0", generation=1))
    s2.psi("h2", stretch_psi(mesh.X))
    assert s2.release("h2", d) is None and s2.gesture is not None  # waits
    s2.equilibrium(1, x_eq)
    rel = s2.resume()
    assert isinstance(rel, ReleaseOut) and rel.prediction is not None and rel.prediction.release
    np.testing.assert_array_equal(rel.prediction.d, d)
    assert s2.gesture is None
    # no equilibrium within hold_s: given up, counted, and a later drape is taken
    g3 = s.press(Press(edit_id="h3", element="cv:front:hem:0", generation=1))
    assert g3 is not None and g3.held_since is None  # ready: not held
    s.offer_design(2, design(stretch=30.0))
    s.take(s.offer_mesh(2, 2, sheet(generation=2)).matched)  # a newer design is meshed
    assert not s.readiness().ready
    g4 = s.press(Press(edit_id="h4", element="cv:front:hem:0", generation=2))
    assert g4 is not None and counted.count("gestures_held") == 2
    s.release("h4", d)
    clock.t += 2.5
    assert s.expire() is g4 and s.gesture is None and counted[-1] == "gestures_expired"
    assert s.resume() is None and s.expire() is None


def camera() -> tuple[np.ndarray, tuple[int, int]]:
    """A camera 2 m in front of the sheet (+z), looking at it; y up."""
    f, near, far = 1.0 / np.tan(np.deg2rad(25.0)), 0.1, 10.0
    proj = np.array(
        [[f, 0, 0, 0], [0, f, 0, 0], [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)], [0, 0, -1, 0]]
    )
    view = np.eye(4)
    view[:3, 3] = [-SIZE / 2, SIZE / 2, -2.0]
    return proj @ view, (800, 800)


def test_sensitivity_3d_tug_commits_through_apply_edit(equilibrium):
    """A tug drives the skirt's length: Δg = ŝ·Δd/|ŝ|² while dragging, and the
    release commits the design edit param:length by Δg, held to the option's range."""
    mesh, _ = equilibrium
    s = ready_service(equilibrium)
    vp, viewport = camera()
    bottom = int(np.argmin(mesh.X[:, 1] + 1e-3 * np.abs(mesh.X[:, 0] - SIZE / 2)))
    psi = np.zeros((mesh.n_vertices, 2, 2))
    psi[:, 1, 0] = -(SIZE - mesh.X[:, 1]) / SIZE  # a longer skirt: the hem goes down
    s.press(Press(edit_id="t1", generation=1, param="length", picked_vertex=bottom, view_proj=vp, viewport=viewport))
    g = s.psi("t1", psi)
    assert g is not None and g.s_point is not None and g.s_point[1] < 0
    J = project_jacobian(vp, viewport, s.predictor.x_eq[bottom])
    sh = J @ g.s_point
    drag_px = 20.0 * sh / np.linalg.norm(sh)  # 20 px along the screen direction of ∂x/∂g
    out = s.drag("t1", drag_px)
    assert out is not None and out.d[1] == 0.0
    assert out.d[0] == pytest.approx(20.0 / np.linalg.norm(sh))
    base = next(o for o in SLOPERS["skirt"].options if o.name == "length")
    r = s.release("t1", drag_px)
    assert r is not None and r.design is not None and r.generation == 2
    assert r.design.sloper.params["length"] == pytest.approx(base.default + out.d[0])
    # a huge tug: the same edit path holds the option to its range
    s.press(Press(edit_id="t2", generation=1, param="length", picked_vertex=bottom, view_proj=vp, viewport=viewport))
    s.psi("t2", psi)
    r = s.release("t2", 1e6 * sh / np.linalg.norm(sh))
    assert r is not None and r.design is not None
    assert r.design.sloper.params["length"] == base.max


def test_sensitivity_rejects_edits_of_other_designs_and_a_tug_overtaken_by_a_new_design(equilibrium):
    """A press made on another design than the mesh held opens no gesture
    (counted stale / foreign); a 3D tug during which a newer design was
    meshed publishes no design edited from the stale one."""
    mesh, _ = equilibrium
    counted: list[str] = []
    s = ready_service(equilibrium)
    s.count = counted.append
    assert s.press(Press(edit_id="old", element="hem", generation=0)) is None
    assert s.press(Press(edit_id="rogue", element="hem", generation=2**62)) is None
    assert counted == ["stale_edits", "foreign_edits"] and s.gesture is None
    vp, viewport = camera()
    bottom = int(np.argmin(mesh.X[:, 1]))
    psi = np.zeros((mesh.n_vertices, 2, 2))
    psi[:, 1, 0] = -(SIZE - mesh.X[:, 1]) / SIZE
    assert s.press(
        Press(edit_id="t", generation=1, param="length", picked_vertex=bottom, view_proj=vp, viewport=viewport)
    )
    s.psi("t", psi)
    # meanwhile another client's design is numbered 2 and its mesh matched
    s.offer_design(7, design(length=0.7), "other")
    assert s.offer_mesh(2, 2, sheet(generation=2), "other").status == "matched"
    r = s.release("t", np.array([0.0, 40.0]))
    assert r is not None and r.prediction is not None and r.design is None
    assert counted[-1] == "stale_edits"


def test_sensitivity_mesh_matching_follows_designs(equilibrium):
    """Two designs in a row: the second mesh gets the second fabric; a stale mesh is dropped."""
    mesh, _ = equilibrium
    s = SensitivityService(clock=Clock())
    s.offer_design(1, design())
    s.offer_design(2, design(stretch=200.0))
    s.take(s.offer_mesh(1, 1, mesh).matched)
    assert s.model.mu == pytest.approx(20.0 / 2.6)
    out = s.offer_mesh(2, 2, sheet(generation=2))
    s.take(out.matched)
    assert s.mesh_generation == 2 and s.generation == 2 and s.model.mu == pytest.approx(200.0 / 2.6)
    assert s.offer_mesh(1, 1, mesh).status == "stale"


# -- design numbering: one owner (the remesher), designs named by their publishers --------


def test_remesher_numbers_designs_whatever_publishers_ask():
    from couture.designs import MAX_AHEAD
    from couture.remesh.service import RemeshService

    small = msgspec_replace_resolution(design(), 120, 240)
    s = RemeshService()
    assert s.next_generation(1) == 1  # a fresh number is given as asked
    s.set_design(small, 1, "a")
    assert s.next_generation(1) == 2  # a second client (or a restarted one) asks for 1 again
    assert s.request_verdict(1, 2) == "stale"
    assert s.next_generation(3) == 3  # a little ahead (a UI's superseded designs): granted
    for hostile in (1000, 2**62, 2**64 - 1):  # far ahead: the next number instead, the count stays
        assert s.next_generation(hostile) == 2 and s.request_verdict(hostile, 2) == "foreign"
    assert s.next_generation(1 + MAX_AHEAD) == 1 + MAX_AHEAD and s.next_generation(2 + MAX_AHEAD) == 2
    # a restarted remesher numbers above what the session's meshes and drapes show
    fresh = RemeshService()
    assert fresh.observe(7, mesh_generation=8)
    assert not fresh.observe(2**62)  # never a number no remesher gives
    assert fresh.next_generation(1) == 8
    (up, *_) = fresh.set_design(small, 8, "c")
    assert up.mesh_generation == 9 and up.mesh.generation == 8 and fresh.design_id == "c"
    # once it numbers designs itself, a number above its own is foreign: the count stays
    assert fresh.observe(8) and not fresh.observe(9) and not fresh.observe(1000)
    assert fresh.next_generation(9) == 9


def msgspec_replace_resolution(d: Design, coarse: int, fine: int) -> Design:
    import msgspec

    from schemas.design import Resolution

    return msgspec.structs.replace(d, resolution=Resolution(coarse_vertices=coarse, fine_vertices=fine))


def test_meshes_match_their_design_by_id_when_renumbered():
    m: MeshMatcher[str] = MeshMatcher()
    d_a, d_b = design(length=0.5), design(length=0.6)
    m.add_design(1, d_a, "a")
    m.add_design(1, d_b, "b")  # a second client asked for the same number
    out = m.add_mesh(MeshArrival("fine", 2, 2, "fine2", "b"))  # the remesher numbered b 2
    assert out.matched is not None and out.matched.design is d_b
    assert m.add_mesh(MeshArrival("fine", 3, 3, "fine3", "c")).status == "parked"  # c not here yet
    (r,) = m.add_design(5, d_c := design(length=0.7), "c")
    assert r.design is d_c and r.mesh.generation == 3


def test_own_designs_learn_the_given_generation():
    from couture.designs import OwnDesigns

    own = OwnDesigns()
    own.add("mine", 1)
    assert own.is_own(1) and own.given(1) is None and not own.is_own(2)
    assert not own.meshed("someone-else", 1)
    assert own.meshed("mine", 7) and own.given(1) == 7
    own.add("mine-again", 1)  # the same number asked for again: the newest design is the one waited for
    assert own.given(1) is None and own.meshed("mine-again", 9) and own.given(1) == 9


def prolongation(coarse: GarmentMesh, fine: GarmentMesh) -> tuple[np.ndarray, np.ndarray]:
    """Each fine vertex's coarse triangle (by its 2D rest position) and barycentrics."""
    P = coarse.X[coarse.tris]  # (t, 3, 2)
    parent = np.zeros(fine.n_vertices, np.int32)
    bary = np.zeros((fine.n_vertices, 3))
    for i, q in enumerate(fine.X):
        T = np.stack([P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]], axis=-1)  # (t, 2, 2)
        uv = np.linalg.solve(T, (q - P[:, 0])[..., None])[..., 0]
        b = np.column_stack([1.0 - uv.sum(1), uv])
        t = int(np.argmax(b.min(1)))
        parent[i], bary[i] = t, b[t]
    return parent, bary


@pytest.mark.parametrize("extend_by", [0.0, 1e5])
def test_a_level_that_needs_more_than_its_cap_gets_it_or_the_next_level_says_so(extend_by):
    """A coarse level stopped by its time cap goes on (``extend_by`` caps more)
    and says so in its diagnosis; with no extension the fine level's start names
    the unconverged coarse drape it was prolongated from."""
    s = SolveService(method="newton", extend_by=extend_by)
    s.max_seconds = {"coarse": 1e-4, "fine": 60.0}
    s.set_design(design())
    coarse, fine = sheet("coarse", 1, 5), sheet("fine", 1, 7)
    s.set_mesh("coarse", coarse, 1)
    s.set_mesh("fine", fine, 1, prolongation(coarse, fine))
    runs = s.run()
    c, f = runs[0], runs[1]
    assert f.result.converged
    if extend_by:
        assert c.result.converged and c.result.iterations > 0
        assert "needed more than its 0.0001 s cap" in c.result.diagnosis
        assert c.result.stats["extended"] and f.warm_start == "prolongated"
    else:
        assert not c.result.converged and "max_seconds" in c.result.diagnosis
        assert f.warm_start.startswith("prolongated from an unconverged coarse drape (residual ")

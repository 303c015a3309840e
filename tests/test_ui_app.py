"""CoutureUI without a browser: controls → callbacks, coalescing, liveness,
tools → strokes couture.pattern accepts, exports that re-import, and the bus
adapter on a real (loopback) Zenoh session."""

from __future__ import annotations

import time

import numpy as np
import pytest

from couture.bus import free_port
from couture.ui import CoutureUI, UIConfig
from couture.ui.demo import demo_sheet


def wait_for(cond, timeout=10.0):
    t0 = time.time()
    while time.time() - t0 < timeout:
        if cond():
            return True
        time.sleep(0.02)
    return False


@pytest.fixture(scope="module")
def ui(tmp_path_factory):
    ui = CoutureUI(UIConfig(port=free_port(), export_dir=tmp_path_factory.mktemp("exports"), draft_locally=False))
    ui.start()
    mesh, pattern = demo_sheet(1500)
    ui.show_pattern(pattern)
    ui.show_mesh(mesh)
    ui.show_drape(mesh.x0, "fine", "demo", residual=1e-3)
    assert wait_for(lambda: ui.frames_pushed >= 1)
    ui.demo_mesh = mesh
    yield ui
    ui.stop()


def test_slider_change_is_a_design_change(ui):
    got = []
    ui.on_design_changed = got.append
    name, h = next(iter(ui.controls.params.items()))
    h.value = float(h.value) + 0.01
    assert not got, "a value the code assigns is not a design change"
    ui.controls.param_changed(name)  # what the slider's on_update runs when the browser moves it
    assert got and got[-1].sloper.params[name] == pytest.approx(float(h.value))
    ui.on_design_changed = None


def test_fabric_preset_sets_table1_values(ui):
    got = []
    ui.on_design_changed = got.append
    ui.controls.preset.value = "stiff"
    ui.controls.preset_chosen()
    f = got[-1].fabric
    assert (f.name, f.bend_stiffness, f.stretch_stiffness, f.area_density) == ("stiff", 3e-4, 2000.0, 0.08)
    ui.on_design_changed = None


def test_body_choice_is_a_design_change_and_the_view_shows_the_body(ui):
    got = []
    ui.on_design_changed = got.append
    default_top = ui.view3d.body_vertices[:, 1].max()
    ui.controls.body.value = "XL"
    ui.controls.body_chosen()  # what the dropdown's on_update runs when the browser picks it
    assert got and got[-1].body.name == "XL" and got[-1].sloper == ui.design.sloper
    assert ui.view3d.body_name == "XL" and ui.view3d.body_vertices[:, 1].max() != default_top
    ui.controls.body.value = "default"
    ui.controls.body_chosen()
    assert got[-1].body.name == "default" and ui.view3d.body_name == "default"
    ui.on_design_changed = None


def test_drapes_are_coalesced_and_newest_wins(ui):
    x0 = ui.demo_mesh.x0
    n0 = ui.frames_pushed
    for k in range(200):
        ui.show_drape(x0 + [0.0, 0.0, 1e-4 * k], "predicted", "gmls", error_estimate=0.01, tag=k)
    assert wait_for(lambda: ui.on_screen is not None and ui.on_screen.tag == 199)
    assert ui.frames_pushed - n0 < 100  # bursts collapse into few renders
    np.testing.assert_allclose(ui.view3d.x, x0 + [0.0, 0.0, 0.0199])


def test_dead_node_is_shown_and_last_drape_stays(ui):
    ui.set_live_nodes({"solver-kinetic": True})
    ui.set_node_status("solver-kinetic", kind="solver", state="running", rates={"drape": 2.0})
    assert wait_for(lambda: "solver-kinetic" in ui.controls.solver.options)
    on_screen = ui.on_screen
    ui.set_live_nodes({"solver-kinetic": False})
    assert wait_for(lambda: "DEAD" in ui.status.table.content)
    # the options follow on the status loop's next pass (the death may land
    # between its options update and its table refresh)
    assert wait_for(lambda: "solver-kinetic" not in ui.controls.solver.options)
    assert ui.on_screen is on_screen


def test_colour_maps_draw_bands_with_legend(ui):
    for field in ("strain", "stress", "fabric_strain", "bias_strain"):
        ui.controls.field.value = field
        ui.controls.field_chosen()
        assert ui.view3d.scale is not None and "background:rgb" in ui.controls.legend.content
        assert any(h.visible for h in ui.view3d.bands) and not ui.view3d.plain.visible
    share = ui.view3d.field_values()  # the last one: bias stretch over the fabric's bias limit [%]
    assert share is not None and len(share) == ui.view3d.mesh.n_triangles and np.isfinite(share).all()
    assert "% of limit" in ui.controls.legend.content
    ui.controls.field.value = "pressure"
    ui.controls.field_chosen()
    p = ui.view3d.field_values()
    assert p is not None and len(p) == ui.view3d.mesh.n_triangles and (p >= 0).all() and np.isfinite(p).all()
    assert ui.view3d.body_distance is not None and ui.view3d.body_distance.name == ui.view3d.body_name
    ui.controls.field.value = "none"
    ui.controls.field_chosen()
    assert ui.view3d.plain.visible and ui.controls.legend.content == ""


def test_exports_reimport(ui):
    import ezdxf
    import trimesh

    obj = ui.export("drape", "obj")
    m = trimesh.load(obj, process=False, force="mesh")
    assert len(m.vertices) == ui.demo_mesh.n_vertices and len(m.faces) == ui.demo_mesh.n_triangles
    np.testing.assert_allclose(np.asarray(m.vertices), ui.view3d.x, atol=1e-6)
    glb = ui.export("drape", "glb")
    g = trimesh.load(glb, process=False, force="mesh")
    assert len(g.faces) == ui.demo_mesh.n_triangles
    dxf = ui.export("pattern", "dxf")
    doc = ezdxf.readfile(dxf)
    # couture.pattern's AAMA exporter puts each piece in a block; find the
    # closed polyline that has the outline's vertices, wherever it lives
    outline = ui.pattern.panels[0].outline
    polys = [
        e
        for layout in (doc.modelspace(), *doc.blocks)
        for e in layout
        if e.dxftype() == "POLYLINE" and e.is_closed and len(list(e.vertices)) == len(outline)
    ]
    assert polys
    pts = np.array([tuple(v.dxf.location)[:2] for v in polys[0].vertices])
    np.testing.assert_allclose(pts.max(0) - pts.min(0), np.ptp(outline, axis=0) * 1000, rtol=1e-6)
    assert ui.export("pattern", "svg").read_text().startswith("<svg")
    assert ui.export("pattern", "pdf").read_bytes().startswith(b"%PDF")


def test_tools_make_strokes_the_pattern_model_accepts(tmp_path):
    from couture.pattern import draft
    from schemas.design import Design

    ui = CoutureUI(UIConfig(port=free_port(), export_dir=tmp_path, show_body=False, draft_locally=False))
    ui.start()
    try:
        pat = draft(Design())
        ui.show_pattern(pat)
        got = []
        ui.on_design_changed = got.append
        gore = pat.panels[0]
        hem = next(s for s in gore.segments if s.name == "hem")
        p_hem = ui.view2d.display(gore.name, gore.outline[(hem.start + hem.stop) // 2])
        ui.tools.arm("dart")
        ui.tools.click(p_hem + [0.0, 0.001], gore.name)
        dart = got[-1].strokes[-1]
        assert (dart.kind, dart.panel, dart.params["segment"]) == ("dart", gore.name, "hem")
        drafted = draft(got[-1])
        assert len(drafted.panel(gore.name).outline) > len(gore.outline)  # the dart is in the outline
        ui.tools.arm("seam")
        ui.tools.click(p_hem, gore.name)
        assert len(got) == 1  # the first pick alone changes nothing
        other = pat.panels[1]
        oh = next(s for s in other.segments if s.name == "hem")
        ui.tools.click(ui.view2d.display(other.name, other.outline[(oh.start + oh.stop) // 2]), other.name)
        seam = got[-1].strokes[-1]
        assert seam.kind == "seam" and {seam.params["a_panel"], seam.params["b_panel"]} == {gore.name, other.name}
        # a picked pattern point without a tool is located on the mesh
        ui.tools.arm(None)
        assert ui.tools.armed is None
    finally:
        ui.stop()


@pytest.mark.slow
def test_bus_adapter_roundtrip(tmp_path):
    """The ui node's adapter on a real loopback Zenoh session: a drape message
    reaches the screen, a design change and a drag go out as messages."""
    from couture.bus import BusConfig, Node, open_session
    from nodes.ui.main import UIAdapter
    from schemas.convert import mesh_to_msg
    from schemas.messages import DrapeMsg, EditMsg, PatternMsg

    port = free_port()
    session = f"uitest{port}"
    ui = CoutureUI(UIConfig(port=free_port(), export_dir=tmp_path, show_body=False, draft_locally=False))
    ui.start()
    try:
        with (
            Node(
                "ui", BusConfig(session=session, listen=[f"tcp/127.0.0.1:{port}"]), kind="ui", install_signals=False
            ) as node,
            open_session(BusConfig(session=session, connect=[f"tcp/127.0.0.1:{port}"], listen=[])) as peer,
        ):
            UIAdapter(node, ui, "ui")
            patterns, edits = [], []
            peer.subscribe("pattern", patterns.append)
            peer.subscribe("edit", edits.append)
            mesh_pub = peer.publisher("mesh/fine", type(mesh_to_msg(demo_sheet(300)[0])))
            drape_pub = peer.publisher("drape/fine", DrapeMsg)
            time.sleep(0.5)
            mesh, pattern = demo_sheet(300)
            ui.show_pattern(pattern)
            mesh_pub.put(mesh_to_msg(mesh))
            assert wait_for(lambda: "fine" in ui.meshes)
            drape_pub.put(DrapeMsg(level="fine", x=mesh.x0 + 0.01, residual=2e-4, solver="kinetic", method="kinetic"))
            assert wait_for(lambda: ui.on_screen is not None and ui.on_screen.method == "kinetic")
            np.testing.assert_allclose(ui.view3d.x, mesh.x0 + 0.01)
            name = next(iter(ui.controls.params))
            ui.controls.params[name].value = float(ui.controls.params[name].value) + 0.01
            ui.controls.param_changed(name)
            assert wait_for(lambda: any(isinstance(m, PatternMsg) and m.source == "ui" for m in patterns))
            from couture.ui.handles import Handle

            # a handle is a couture.pattern element; d is in its convention (param: the option change)
            h = Handle("param:length", "gore0", 0, "param")
            length0 = float(ui.design.sloper.params.get("length", 0.60))
            n_patterns = len(patterns)
            ui.gestures.handle_drag("press", h, np.zeros(2))
            ui.gestures.handle_drag("drag", h, np.array([0.01, 0.0]))
            ui.gestures.handle_drag("release", h, np.array([0.02, 0.0]))
            assert wait_for(lambda: len(edits) == 3)
            assert [e.phase for e in edits] == ["press", "drag", "release"]
            assert isinstance(edits[-1], EditMsg) and edits[-1].element == h.element
            np.testing.assert_allclose(edits[-1].d.numpy(), [0.02, 0.0])
            # the release commits apply_edit(design, element, d): one new pattern, one generation more
            # (a late echo of the slider's pattern may still arrive first)
            assert wait_for(lambda: any("length" in p.design.sloper.params for p in patterns[n_patterns:]))
            i = next(i for i, p in enumerate(patterns) if i >= n_patterns and "length" in p.design.sloper.params)
            assert patterns[i].design.sloper.params["length"] == pytest.approx(length0 + 0.02)
            assert patterns[i].generation == max(p.generation for p in patterns[:i]) + 1
    finally:
        ui.stop()


@pytest.mark.slow
def test_adapter_solver_choice_and_record_toggle(tmp_path):
    """On a real loopback bus: with two solvers publishing, choosing one shows only its
    drapes (its newest at once); a sensitivity node that leaves turns on the
    "predictions are off" note; the record toggle starts a recorder process that
    writes what crosses the bus into an MCAP file, finalized when toggled off; a
    rejected design is shown at the top of the status until a later mesh."""
    from mcap.reader import make_reader

    from couture.bus import BusConfig, Node, open_session
    from nodes.ui.main import UIAdapter
    from schemas.convert import mesh_to_msg
    from schemas.messages import DrapeMsg, RejectedMsg, decode

    port = free_port()
    session = f"uirec{port}"
    bus_cfg = BusConfig(session=session, listen=[f"tcp/127.0.0.1:{port}"])
    ui = CoutureUI(UIConfig(port=free_port(), export_dir=tmp_path, show_body=False, draft_locally=False))
    ui.start()
    adapter = None
    try:
        with (
            Node("ui", bus_cfg, kind="ui", install_signals=False) as node,
            open_session(BusConfig(session=session, connect=[f"tcp/127.0.0.1:{port}"], listen=[])) as peer,
        ):
            adapter = UIAdapter(node, ui, "ui", bus_config=bus_cfg, record_dir=tmp_path / "rec")
            mesh, pattern = demo_sheet(300)
            mesh_pub = peer.publisher("mesh/fine", type(mesh_to_msg(mesh)))
            drape_pub = peer.publisher("drape/fine", DrapeMsg)
            time.sleep(0.5)
            ui.show_pattern(pattern)
            mesh_pub.put(mesh_to_msg(mesh, generation=3))  # the remesher numbered it 3: drapes up to 3 show
            assert wait_for(lambda: "fine" in ui.meshes)

            def drape(solver, dz, gen):
                return DrapeMsg(
                    level="fine",
                    x=mesh.x0 + [0.0, 0.0, dz],
                    residual=1e-5,
                    solver=solver,
                    method=solver.split("-")[1],
                    generation=gen,
                    converged=True,
                )

            def on_screen(dz):
                return ui.view3d.x is not None and np.allclose(ui.view3d.x, mesh.x0 + [0.0, 0.0, dz])

            drape_pub.put(drape("solver-newton", 0.02, 1))
            drape_pub.put(drape("solver-kinetic", 0.01, 1))
            assert wait_for(lambda: on_screen(0.01))  # 'any': the newest drape shows
            ui.select_solver("solver-newton")  # what the solver dropdown calls
            assert wait_for(lambda: on_screen(0.02)), "choosing a solver did not show its newest drape"
            drape_pub.put(drape("solver-kinetic", 0.03, 2))
            drape_pub.put(drape("solver-newton", 0.04, 2))
            assert wait_for(lambda: on_screen(0.04))
            drape_pub.put(drape("solver-kinetic", 0.05, 3))
            # a drape numbered above every mesh (a rogue's) is held, and hides nothing
            drape_pub.put(drape("solver-newton", 0.06, 2**62))
            drape_pub.put(drape("solver-newton", 0.07, 3))
            assert wait_for(lambda: on_screen(0.07)), "a foreign generation hid the chosen solver's next drape"
            time.sleep(1.0)
            assert on_screen(0.07), "a drape of the solver not chosen (or a foreign one) replaced the chosen one"
            assert wait_for(lambda: adapter.node.bus.stats.snapshot().get("held_drapes", 0) >= 1)

            # a sensitivity node comes and goes (a real liveliness token on the peer's bus):
            # while it is gone the status says predictions are off
            off = "Predictions are off"
            with Node(
                "sensitivity",
                BusConfig(session=session, connect=[f"tcp/127.0.0.1:{port}"], listen=[]),
                kind="sensitivity",
                install_signals=False,
            ):
                assert wait_for(
                    lambda: adapter.live.get("sensitivity") and not any(off in n for n in ui.status.notes), 20
                )
            assert wait_for(lambda: any(off in n for n in ui.status.notes), 20), ui.status.notes

            # record toggle: a recorder process joins this bus and writes an MCAP file
            ui.on_record(True)  # what the record checkbox calls
            path = adapter.record_path
            assert path is not None and adapter.recorder.poll() is None
            assert wait_for(lambda: adapter.live.get("ui-recorder"), 30), "the recorder never came up"
            for k in range(5):
                drape_pub.put(drape("solver-newton", 0.001 * k, 10 + k))
            time.sleep(1.0)
            ui.on_record(False)
            assert adapter.recorder is None and "recorded" in ui.session.record_note.content
            with open(path, "rb") as f:
                reader = make_reader(f)
                schemas = {s.name for s in reader.get_summary().schemas.values()}
                gens = [
                    decode(m.data, DrapeMsg).generation
                    for _, ch, m in reader.iter_messages()
                    if ch.topic.endswith("drape/fine")
                ]
            assert "couture/drape/v1" in schemas, schemas
            assert set(range(10, 15)) <= set(gens), f"recorded generations {gens}, expected 10..14"

            # a design a node rejected: named at the top of the status until a later design is meshed
            reason = "fabric.area_density: 0 kg/m^2 is outside the allowed range [0.001, 10] kg/m^2"
            peer.publisher("rejected", RejectedMsg).put(
                RejectedMsg(node="remesher", generation=20, element="fabric.area_density", reason=reason, name="bad")
            )
            assert wait_for(lambda: ui.status.table.content.startswith("**Design rejected**: remesher")), (
                ui.status.table.content[:300]
            )
            assert ui.status.rejection == "remesher rejected design 'bad': " + reason
            assert (
                "fabric.area_density: 0 kg/m^2 is outside the allowed range \\[0.001, 10\\]" in ui.status.table.content
            )
            mesh_pub.put(mesh_to_msg(mesh))
            assert wait_for(lambda: "Design rejected" not in ui.status.table.content), ui.status.table.content[:300]
    finally:
        if adapter is not None:
            adapter.close()
        ui.stop()


def test_same_mesh_resent_keeps_the_drape_on_screen(ui):
    """A mesh message equal to the one on screen (the remesher re-sends it with
    Ψ on a press) neither re-uploads triangles nor resets the drape to x0."""
    import dataclasses

    mesh = ui.demo_mesh
    draped = mesh.x0 + [0.0, -0.01, 0.02]
    ui.show_drape(draped, "fine", "demo", tag="draped")
    assert wait_for(lambda: ui.on_screen is not None and ui.on_screen.tag == "draped")
    uploads = ui.view3d.mesh_uploads
    resent = dataclasses.replace(mesh, X=mesh.X.copy(), tris=mesh.tris.copy(), x0=mesh.x0.copy(), generation=7)
    ui.show_mesh(resent)
    assert ui.view3d.mesh_uploads == uploads
    np.testing.assert_array_equal(ui.view3d.x, draped)
    assert ui.view3d.mesh is resent
    # a different mesh is a new one: uploaded, shown at its initial positions
    other = dataclasses.replace(mesh, X=mesh.X * 1.01, x0=mesh.x0 + 0.1)
    ui.show_mesh(other)
    assert ui.view3d.mesh_uploads == uploads + 1
    np.testing.assert_allclose(ui.view3d.x, other.x0)
    ui.show_mesh(mesh)
    ui.show_drape(mesh.x0, "fine", "demo", tag="restored")
    assert wait_for(lambda: ui.on_screen is not None and ui.on_screen.tag == "restored")


def test_handle_drag_gives_typed_edits_and_commits_on_release(tmp_path):
    from couture.pattern import draft
    from couture.ui.gestures import Edit
    from couture.ui.handles import Handle
    from schemas.design import Design

    ui = CoutureUI(UIConfig(port=free_port(), export_dir=tmp_path, show_body=False, draft_locally=False))
    ui.start()
    try:
        ui.show_pattern(draft(Design()))
        edits, designs = [], []
        ui.on_edit, ui.on_design_changed = edits.append, designs.append
        h = Handle("param:length", "gore0", 0, "param")
        length0 = float(ui.design.sloper.params.get("length", 0.60))
        for phase, d in (("press", 0.0), ("drag", 0.01), ("release", 0.03)):
            ui.gestures.handle_drag(phase, h, np.array([d, 0.0]))
        assert all(isinstance(e, Edit) for e in edits) and [e.phase for e in edits] == ["press", "drag", "release"]
        assert len({e.edit_id for e in edits}) == 1 and edits[-1].dofs == ("length",) and edits[-1].pick is None
        assert len(designs) == 1 and designs[0].sloper.params["length"] == pytest.approx(length0 + 0.03)
        assert ui.controls.params["length"].value == pytest.approx(length0 + 0.03)  # the slider follows
        # an edit made by another client (a replay) moves its handle and the outlines, commits nothing
        from couture.ui.handles import plan_handles

        pattern = draft(ui.design)
        ui.show_pattern(pattern)
        ui.view2d.set_handles(plan_handles(ui.design, pattern))
        i = next(i for i, h in enumerate(ui.view2d.handles) if h.element == "param:length")
        at_rest = ui.view2d.handle_positions()[i]
        ui.preview_remote_edit("param:length", np.array([0.05, 0.0]))
        moved = np.asarray(ui.view2d._handle_node.batched_positions)[i]
        assert np.linalg.norm(moved[:2] - at_rest[:2]) > 0.03 and len(designs) == 1
        ui.view2d.restore()
        # an edit couture.pattern refuses is said so; nothing is committed
        gone = Handle("cv:gore0:no-such-segment:0", "gore0", 0, "cv")
        for phase in ("press", "release"):
            ui.gestures.handle_drag(phase, gone, np.array([0.01, 0.0]))
        assert len(designs) == 1 and "rejected" in ui.tools.help.content
    finally:
        ui.stop()


def test_a_library_fabric_preset_brings_the_whole_fabric_and_custom_is_isotropic(ui):
    """Choosing a library fabric hands the design that fabric whole
    (directional values, density, skin friction); editing a number after it
    makes a custom, isotropic fabric (its directional values cleared)."""
    from couture import fabrics

    got = []
    before = ui.design
    ui.on_design_changed = got.append
    assert "denim" in ui.controls.preset.options and "custom" in ui.controls.preset.options
    ui.controls.preset.value = "denim"
    ui.controls.preset_chosen()
    assert got[-1].fabric == fabrics.get("denim")
    assert float(ui.controls.stretch.value) == pytest.approx(fabrics.get("denim").stretch_stiffness)
    ui.controls.stretch.value = 900.0
    ui.controls.fabric_changed()
    f = got[-1].fabric
    assert f.name == "custom" and f.stretch_stiffness == 900.0 and f.warp_stiffness is None and f.bend_bias is None
    assert f.area_density == fabrics.get("denim").area_density  # the rest of the fabric stays
    ui.on_design_changed = None
    ui.design = before


def test_fabric_presets_are_the_design_fabric():
    from couture.ui.state import FABRIC_PRESETS
    from schemas.design import Fabric

    assert all(isinstance(f, Fabric) and f.name == name for name, f in FABRIC_PRESETS.items())
    # the library and SC's three
    assert {"denim", "chiffon", "jersey", "silk-like", "cotton", "stiff"} <= set(FABRIC_PRESETS)


def test_client_framing_follows_the_canvas_until_the_designer_moves_the_camera():
    """Each browser is framed for its own canvas shape; a resize reframes it,
    also when the browser's report crossed the framing on its way; once the
    designer has moved the camera, a resize leaves it alone."""
    import contextlib
    from types import SimpleNamespace

    from couture.ui.widgets import ClientFraming

    class Camera:
        def __init__(self):
            self.image_width = self.image_height = 0
            self.position, self.look_at, self.up_direction = (0.0, 0.0, 9.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)
            self.callbacks = []

        def on_update(self, cb):
            self.callbacks.append(cb)

        def report(self, width, height, position=None):
            self.image_width, self.image_height = width, height
            if position is not None:
                self.position = position
            for cb in self.callbacks:
                cb(self)

    cam = Camera()
    client = SimpleNamespace(client_id=1, camera=cam, atomic=contextlib.nullcontext)
    connected = []
    server = SimpleNamespace(
        on_client_connect=connected.append,
        get_clients=lambda: {1: client},
        initial_camera=SimpleNamespace(position=(0.0, 0.0, 9.0)),
    )
    framing = ClientFraming(server, lambda aspect: ((0.0, 0.0, 1.0 / aspect), (0.0, 0.0, 0.0)))
    connected[0](client)
    cam.report(800, 800)
    assert wait_for(lambda: cam.position == (0.0, 0.0, 1.0))
    cam.report(400, 800, position=(0.0, 0.0, 9.0))  # a stale report: still at the initial camera
    assert cam.position == (0.0, 0.0, 2.0)
    cam.report(400, 800, position=(0.3, 0.0, 2.5))  # the designer orbits
    cam.report(800, 800)
    assert cam.position == (0.3, 0.0, 2.5)
    framing.reframe()  # new content frames again
    assert cam.position == (0.0, 0.0, 1.0)


def test_a_tug_edit_becomes_an_edit_message():
    from couture.ui.gestures import Edit, ScreenPick
    from nodes.ui.main import edit_msg
    from schemas.messages import EditMsg, decode, encode

    vp = np.arange(16.0).reshape(4, 4)
    pick = ScreenPick(vertex=12, tri=40, bary=np.array([0.2, 0.3, 0.5]), view_proj=vp, viewport_px=(640, 480))
    edit = Edit("e1", "drag", "param:length", ("length",), np.array([30.0, -4.0]), "length", pick)
    msg = decode(encode(edit_msg(edit, generation=3)), EditMsg)
    assert (msg.generation, msg.edit_id, msg.phase, msg.element, msg.dofs, msg.param) == (
        3,
        "e1",
        "drag",
        "param:length",
        ["length"],
        "length",
    )
    assert (msg.picked_vertex, msg.picked_tri, msg.viewport_px) == (12, 40, [640, 480])
    np.testing.assert_array_equal(msg.d.numpy(), [30.0, -4.0])
    np.testing.assert_array_equal(msg.view_proj.numpy(), vp)
    np.testing.assert_array_equal(msg.picked_bary.numpy(), [0.2, 0.3, 0.5])
    plain = edit_msg(Edit("e2", "press", "cv:gore0:hem:0", ("x", "y"), np.zeros(2)), generation=1)
    assert plain.picked_vertex == -1 and plain.view_proj is None and plain.viewport_px == []


def test_page_port_taken_falls_back_or_fails_naming_it():
    """The page binds first: a taken port is an error naming it, or with
    fallback the next free one, and the URL it reports is its own."""
    import urllib.request

    from couture.ui.page import PageServer, PortInUse

    first = PageServer("127.0.0.1", free_port(), 1, 2)
    try:
        with pytest.raises(PortInUse, match=f"port {first.port} on 127.0.0.1 is already in use"):
            PageServer("127.0.0.1", first.port)
        second = PageServer("127.0.0.1", first.port, fallback=True)
        try:
            assert second.port != first.port and second.url == f"http://127.0.0.1:{second.port}/"
            with pytest.raises(urllib.error.HTTPError) as e:  # views not started yet: 503, not a wrong page
                urllib.request.urlopen(second.url, timeout=10)
            assert e.value.code == 503
            second.set_views(7001, 7002)
            with urllib.request.urlopen(second.url, timeout=10) as page:
                assert b":7001/" in page.read()
        finally:
            second.stop()
    finally:
        first.stop()


def test_a_prediction_shows_its_distance_estimate_in_mm():
    from couture.ui.state import DrapeFrame
    from couture.ui.status import describe_frame

    f = DrapeFrame(np.zeros((3, 3)), "predicted", "gmls", error_estimate=0.02, error_estimate_m=0.0012)
    assert "about 1.2 mm from equilibrium" in describe_frame(f)
    pending = DrapeFrame(np.zeros((3, 3)), "predicted", "gmls")
    assert "error estimate pending" in describe_frame(pending)


def test_tryon_buttons_make_tryon_messages(ui):
    """The Try-on folder: the panels of the mesh on screen, each button one
    ``couture/tryon/v1`` op (a panel op without a panel sends nothing)."""
    from couture.tryon import TORSO_AXIS_POINT
    from nodes.ui.main import tryon_msg
    from schemas.messages import TryOnMsg, decode, encode

    sent: list[dict] = []
    ui.on_tryon = sent.append
    names = list(ui.demo_mesh.panel_names)
    assert tuple(ui.tryon.panel.options) == ("(none)", *names)
    ui.tryon.panel.value = "(none)"
    assert ui.tryon.click("Drag around +") is None and not sent and "pick a panel" in ui.tryon.help.content
    ui.tryon.panel.value = names[0]
    ui.tryon.angle_deg.value = 30.0
    ui.tryon.step_cm.value = 4.0
    ui.tryon.click("Drag around -")
    ui.tryon.click("Drag down")
    ui.tryon.click("Move out")
    ui.tryon.click("Rotate +")
    ui.tryon.click("Sew next seam")
    ui.tryon.click("Start sequential sewing")
    assert [s["op"] for s in sent] == ["drag", "drag", "move", "rotate", "sew", "start"]
    ui.set_tryon_note("solver-newton: try-on move refused: no panel 'x'")
    assert "refused" in ui.tryon.help.content and "no panel 'x'" in ui.tryon.help.content
    msgs = [decode(encode(tryon_msg(s, generation=4)), TryOnMsg) for s in sent]
    assert msgs[0].panel == names[0] and msgs[0].angle == pytest.approx(-np.pi / 6)
    np.testing.assert_allclose(msgs[1].vector.numpy(), [0.0, -0.04, 0.0])
    out = msgs[2].vector.numpy()
    # outward: horizontal, 4 cm, from the torso axis towards the panel's centroid on screen
    from couture.tryon import panel_vertices

    c = ui.view3d.x[panel_vertices(ui.demo_mesh, names[0])].mean(axis=0) - TORSO_AXIS_POINT
    assert out[1] == 0.0 and np.linalg.norm(out) == pytest.approx(0.04)
    assert out[[0, 2]] @ c[[0, 2]] > 0
    # rotate: in the panel's plane, about the same outward direction
    np.testing.assert_allclose(msgs[3].vector.numpy(), out)
    assert msgs[3].angle == pytest.approx(np.pi / 6)
    assert msgs[4].seam == -1 and msgs[5].sewn is False and all(m.generation == 4 for m in msgs)
    ui.on_tryon = None


def test_a_click_on_the_body_is_a_try_on_drag_target(ui):
    """A ray on the body (what viser reports for a click on it) picks a point
    through the body's proxy; "Drag to picked point" sends the drag that turns
    the panel's centroid to the point's azimuth about the torso axis and
    raises it to its height (checked by turning the centroid with the op); a
    ray past the body picks nothing and the button then sends nothing."""
    from couture.tryon import TORSO_AXIS_POINT, UP, panel_vertices, rotation_matrix
    from couture.ui.geometry import ray_hit

    sent: list[dict] = []
    ui.on_tryon = sent.append
    assert ui.view3d.body_name == "default"
    eye, d = np.array([0.8, 0.3, 2.5]), np.array([-0.8, 0.0, -2.5])
    pick = ui.pick_body(eye, d)
    assert pick is not None and pick.region == "torso" and ui.tryon.target is pick
    assert ui.view3d.body_marker.visible
    t_mesh = ray_hit(ui.view3d.body_vertices, ui.view3d.body_faces, eye, d / np.linalg.norm(d))[1]
    assert t_mesh - 0.05 < pick.t <= t_mesh + 1e-3  # on the proxy, just before the body
    name = ui.demo_mesh.panel_names[0]
    ui.tryon.panel.value = name
    op = ui.tryon.click("Drag to picked point")
    assert sent == [op] and op["op"] == "drag" and op["panel"] == name
    c = ui.view3d.x[panel_vertices(ui.demo_mesh, name)].mean(axis=0)
    moved = (c - TORSO_AXIS_POINT) @ rotation_matrix(UP, op["angle"]).T + TORSO_AXIS_POINT
    moved[1] += op["vector"][1]
    r_moved, r_pick = moved - TORSO_AXIS_POINT, pick.point - TORSO_AXIS_POINT
    assert np.arctan2(r_moved[0], r_moved[2]) == pytest.approx(np.arctan2(r_pick[0], r_pick[2]), abs=1e-9)
    assert moved[1] == pytest.approx(pick.point[1], abs=1e-12)
    assert ui.pick_body(eye, -d) is None and ui.tryon.target is None and not ui.view3d.body_marker.visible
    assert ui.tryon.click("Drag to picked point") is None and len(sent) == 1
    assert "click the body first" in ui.tryon.help.content
    ui.on_tryon = None


def test_drag_to_an_arrangement_point(ui):
    """ "Drag to arrangement point" sends the drag that takes the panel's
    centroid to the chosen landmark's azimuth and height on the body shown
    (couture.pattern.landmarks); with none chosen it sends nothing and says why."""
    from couture.pattern.landmarks import arrangement_point
    from couture.tryon import TORSO_AXIS_POINT, UP, panel_vertices, rotation_matrix

    sent: list[dict] = []
    ui.on_tryon = sent.append
    name = ui.demo_mesh.panel_names[0]
    ui.tryon.panel.value = name
    ui.tryon.point.value = "(none)"
    assert ui.tryon.click("Drag to arrangement point") is None and not sent
    assert "choose an arrangement point" in ui.tryon.help.content
    assert "back_neck" in ui.tryon.point.options and "left_upper_arm" in ui.tryon.point.options
    ui.tryon.point.value = "back_waist"
    op = ui.tryon.click("Drag to arrangement point")
    assert sent == [op] and op["op"] == "drag" and op["panel"] == name
    target = arrangement_point(ui.view3d.body_name, "back_waist").position
    c = ui.view3d.x[panel_vertices(ui.demo_mesh, name)].mean(axis=0)
    moved = (c - TORSO_AXIS_POINT) @ rotation_matrix(UP, op["angle"]).T + TORSO_AXIS_POINT
    moved[1] += op["vector"][1]
    r_moved, r_t = moved - TORSO_AXIS_POINT, target - TORSO_AXIS_POINT
    assert np.arctan2(r_moved[0], r_moved[2]) == pytest.approx(np.arctan2(r_t[0], r_t[2]), abs=1e-9)
    assert abs(abs(np.arctan2(r_t[0], r_t[2])) - np.pi) < 1e-6  # the back: behind the torso axis
    assert moved[1] == pytest.approx(target[1], abs=1e-12)
    ui.on_tryon = None


def test_body_fitted_sloper_sliders_show_the_bodys_measurements(ui):
    """A waist-seamed dress on XL drafts from XL's measured girths: the option
    sliders show them (not the mannequin's defaults), and a design's own value wins."""
    from couture import bodies
    from schemas.design import Body, Design, Sloper

    before = ui.design
    xl = next(r for r in bodies.table() if r["name"] == "XL")["measured"]
    try:
        d = Design(sloper=Sloper(kind="dress_waist", params={"hip_girth": 1.2}), body=Body(name="XL"))
        ui.controls.show_design(d)
        step = ui.controls.params["waist_girth"].step
        assert float(ui.controls.params["waist_girth"].value) == pytest.approx(xl["waist_girth"], abs=step)
        assert float(ui.controls.params["bust_girth"].value) == pytest.approx(xl["bust_girth"], abs=step)
        assert float(ui.controls.params["hip_girth"].value) == pytest.approx(1.2, abs=step)
    finally:
        ui.controls.show_design(before)


def test_adjust_loop_anchor_and_amount_on_a_cylinder():
    """The waist handle sits on the front of the garment at the waist and
    slides radially; a radial offset d is a girth change 2πd (a cylinder
    round the torso axis: closed form). The hem handle slides up: shorter."""
    from couture.pattern.mannequin import TORSO_AXIS_Z, WAIST_Y
    from couture.ui.adjust_panel import amount_of, loop_anchor

    a = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    ys = np.linspace(WAIST_Y - 0.5, WAIST_Y + 0.05, 12)
    R = 0.15
    x = np.array([[R * np.sin(t), y, TORSO_AXIS_Z + R * np.cos(t)] for y in ys for t in a])
    p, u = loop_anchor(x, "waist")
    assert abs(p[1] - WAIST_Y) <= 0.02 and p[2] == pytest.approx(TORSO_AXIS_Z + R)
    np.testing.assert_allclose(u, [0.0, 0.0, 1.0], atol=1e-12)
    assert amount_of("waist", 0.01 * u, u) == pytest.approx(2 * np.pi * 0.01)
    p, u = loop_anchor(x, "hem")
    assert p[1] == pytest.approx(ys[0]) and p[2] == pytest.approx(TORSO_AXIS_Z + R)
    assert amount_of("hem", np.array([0.0, 0.07, 0.0]), u) == pytest.approx(-0.07)
    with pytest.raises(ValueError, match="does not go round the waist"):
        loop_anchor(x - [0.0, 1.0, 0.0], "waist")


def test_adjust_folder_drag_release_sends_a_request_and_shows_progress(ui):
    """Dragging the hem handle up 8 cm and releasing asks for a hem 8 cm
    shorter; a drag down is refused (nothing sent, the folder says why);
    progress and failures show in the folder; undo puts the design back."""
    from nodes.ui.main import adjust_msg
    from schemas.messages import AdjustMsg, decode, encode

    sent: list[tuple[str, float]] = []
    designs: list = []
    ui.on_adjust = lambda loop, amount: sent.append((loop, amount))
    ui.on_design_changed = designs.append
    panel = ui.adjust
    panel.loop.value = "hem"
    assert panel.place() and panel.handle.visible
    x = ui.view3d.x
    assert panel.anchor[1] == pytest.approx(x[:, 1].min())
    # what the browser's drag does: drag start, position updates, drag end
    panel._drag_start()
    panel.handle.position = tuple(panel.anchor + [0.0, 0.08, 0.0])
    panel._moved()
    assert panel.amount_cm.value == pytest.approx(-8.0)
    panel._released()
    assert sent == [("hem", pytest.approx(-0.08))]
    assert "waiting for the adjust node" in panel.progress.content
    before = panel.before
    panel._drag_start()
    panel.handle.position = tuple(panel.anchor - [0.0, 0.05, 0.0])
    panel._released()
    assert sent[1:] == [("hem", pytest.approx(0.05))]  # down: longer
    # progress from the adjust node, then done: undo becomes possible
    ui.show_adjust_status("iteration", 1, "iteration 1: Hausdorff 1.9 % of height")
    assert "iteration 1" in panel.progress.content
    ui.show_adjust_status("done", 1, "hem -0.080 m: design options: length 0.600 -> 0.520")
    assert "**done**" in panel.progress.content and not panel.undo.disabled
    # the verdict the node's done status carries: met or not, its reasons in the text
    ui.show_adjust_status("done", 1, "hem -0.080 m; goal met: Hausdorff 0.80 % of height", goal_met=True)
    assert panel.progress.content.startswith("**done**, **goal met**: hem")
    ui.show_adjust_status("done", 1, "goal NOT met (...): Hausdorff 1.40 % > 1 %: at the hem", goal_met=False)
    assert "**done**, **goal NOT met**" in panel.progress.content and "at the hem" in panel.progress.content
    n = len(designs)
    assert panel.undo_last() is before and designs[n:] == [before] and panel.undo.disabled
    ui.show_adjust_status("failed", 0, "", "no solver node is live in this session")
    assert "the design is unchanged" in panel.progress.content and "no solver node" in panel.progress.content
    # no bus: the folder says so instead of failing silently
    ui.on_adjust = None
    panel.amount_cm.value = -5.0
    assert panel.request() is None and "not on a bus" in panel.progress.content
    # the message the adapter makes of it
    m = decode(encode(adjust_msg("hem", -0.08, ui.design, "d1", 3)), AdjustMsg)
    assert m.edit == "hem" and m.amount == -0.08 and m.generation == 3 and m.design_id == "d1"
    assert m.max_iters is None  # the adjust node's settings, those of `couture adjust`
    assert decode(encode(adjust_msg("hem", 0.08, ui.design, "d1", 3)), AdjustMsg).amount == 0.08
    ui.on_design_changed = None


def test_a_drape_before_its_mesh_is_shown_when_the_mesh_comes(tmp_path):
    """A late joiner gets the session's meshes and drapes on separate
    subscriptions, in any order: a fine drape taken before the fine mesh is
    held and shown (the page's frame marker set) once that mesh arrives, not
    dropped (the solve is over: no other drape comes, and the page's marker
    would stay at data-seq 0). A held fine drape outlives its own design's
    coarse drape shown meanwhile; a newer drape of its level wins over it."""
    import dataclasses

    ui = CoutureUI(UIConfig(port=free_port(), export_dir=tmp_path, show_body=False, draft_locally=False))
    ui.start()
    try:
        coarse, _ = demo_sheet(300)
        fine, _ = demo_sheet(1200)
        coarse, fine = dataclasses.replace(coarse, level="coarse"), dataclasses.replace(fine, level="fine")
        assert coarse.n_vertices != fine.n_vertices
        ui.show_mesh(coarse)
        ui.show_drape(fine.x0 + [0.0, 0.0, 0.01], "fine", "newton", residual=1e-6, tag="fine drape")
        time.sleep(0.3)
        assert ui.frames_pushed == 0 and 'data-seq="0"' in ui.status.frame_html.content
        ui.show_mesh(fine)
        assert wait_for(lambda: ui.on_screen is not None and ui.on_screen.tag == "fine drape")
        assert 'data-seq="1"' in ui.status.frame_html.content
        np.testing.assert_allclose(ui.view3d.x, fine.x0 + [0.0, 0.0, 0.01])
        # a held fine drape outlives a coarse drape of its own design shown meanwhile
        fine2, _ = demo_sheet(900)
        fine2 = dataclasses.replace(fine2, level="fine", generation=2)
        ui.show_drape(fine2.x0 + [0.0, 0.0, 0.02], "fine", "newton", generation=2, tag="fine 2")
        time.sleep(0.3)
        ui.show_drape(coarse.x0, "coarse", "newton", generation=2, tag="coarse 2")
        assert wait_for(lambda: ui.on_screen.tag == "coarse 2")
        assert ui.frames_pushed == 2 and ui.renderer.waiting.tag == "fine 2"  # its mesh is not here yet
        ui.show_mesh(fine2)
        assert wait_for(lambda: ui.on_screen.tag == "fine 2")
        # held, then overtaken: a drape of the same level is newer, the held one is dropped
        other, _ = demo_sheet(600)
        other = dataclasses.replace(other, level="coarse")
        assert other.n_vertices not in (coarse.n_vertices, fine.n_vertices, fine2.n_vertices)
        ui.show_drape(other.x0, "coarse", "newton", tag="held")
        time.sleep(0.3)
        assert ui.renderer.waiting is not None and ui.renderer.waiting.tag == "held"
        ui.show_drape(fine2.x0, "fine", "newton", generation=2, tag="newer")
        assert wait_for(lambda: ui.on_screen.tag == "newer")
        ui.show_mesh(other)
        time.sleep(0.3)
        assert ui.on_screen.tag == "newer" and ui.renderer.waiting is None
    finally:
        ui.stop()

"""CoutureUI: the designer's web page (two viser servers + a page showing both).

Pure UI: no bus import. The bus adapter (``nodes/ui/main.py``) connects the
callbacks (what the user did → messages) and the ``show_*`` / ``set_*``
methods (messages → screen). Those methods only store the newest value and
return at once; a render thread pushes the newest drape to the browser at most
``max_fps`` times a second, so a burst of predictions costs one render and a
slow or dead solver never blocks the page.

    ui = CoutureUI(UIConfig(port=8080))
    ui.on_design_changed = lambda design: ...
    ui.on_edit = lambda edit: ...          # dict with EditMsg's fields
    ui.start(); print(ui.page_url)
    ui.show_mesh(mesh); ui.show_drape(x, "fine", "kinetic", residual=1e-4)
"""

from __future__ import annotations

import itertools
import logging
import math
import threading
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

import msgspec
import numpy as np
import viser

from couture.mesh import GarmentMesh
from couture.pattern.drafted import DraftedPattern
from couture.ui import colormaps, export
from couture.ui.drape_view import DrapeView
from couture.ui.geometry import CameraState, MaterialPoint
from couture.ui.page import PageServer
from couture.ui.handles import Handle, plan_handles
from couture.ui.pattern_view import PatternView
from couture.ui.state import (
    FABRIC_PRESETS,
    DrapeFrame,
    LatestSlot,
    NodeInfo,
    sloper_kinds,
    sloper_options,
)
from schemas.design import Design, Fabric, Stroke

log = logging.getLogger("couture.ui")


@dataclass
class UIConfig:
    host: str = "127.0.0.1"
    """bind address of all three servers (loopback by default)"""
    port: int = 8080
    """the combined page (what users open); the 3D view is port + 1, the pattern view port + 2"""
    export_dir: Path = Path("out/exports")
    max_fps: float = 60.0
    """upper bound on drape pushes to the browser [1/s]"""
    show_body: bool = True
    n_bands: int = 9
    """colour bands of the strain/stress/pressure maps"""
    draft_locally: bool = True
    """draft the design with couture.pattern.draft (when it exists) to show the pattern"""


class CoutureUI:
    def __init__(self, config: UIConfig | None = None, design: Design | None = None):
        self.config = config or UIConfig()
        self.design: Design = design or Design()
        self.generation = 0
        # callbacks the bus adapter sets
        self.on_design_changed: Callable[[Design], None] | None = None
        self.on_edit: Callable[[dict], None] | None = None
        self.on_solver_selected: Callable[[str], None] | None = None
        self.on_record: Callable[[bool], None] | None = None
        """cb(on); the adapter answers with :meth:`set_record_note`"""
        self.on_pick: Callable[[MaterialPoint], None] | None = None

        self.meshes: dict[str, GarmentMesh] = {}
        self.pattern: DraftedPattern | None = None
        self.nodes: dict[str, NodeInfo] = {}
        self.on_screen: DrapeFrame | None = None
        self.selected_solver = "any"
        """solver node whose drapes are shown ('any': every solver's)"""
        self.handles_for: Design | None = None
        """the design the pattern view's handles were planned for"""
        self.notes: list[str] = []
        """extra status lines from the adapter (e.g. predictions off)"""
        self.frames_pushed = 0
        self.last_edit_stamp = 0.0
        self._drape_slot: LatestSlot[DrapeFrame] = LatestSlot()
        self._design_slot: LatestSlot[Design] = LatestSlot()
        self._status_dirty = threading.Event()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._suppress = 0
        self._armed: dict | None = None
        self._stroke_ids = itertools.count(1)
        self._started = False
        self.server3d: viser.ViserServer | None = None
        self.server2d: viser.ViserServer | None = None
        self.page: PageServer | None = None

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> str:
        """Start the servers and the render thread; returns the page URL."""
        c = self.config
        self.server3d = viser.ViserServer(host=c.host, port=c.port + 1, label="couture 3D", verbose=False)
        self.server2d = viser.ViserServer(host=c.host, port=self.server3d.get_port() + 1, label="couture pattern",
                                          verbose=False)
        for s in (self.server3d, self.server2d):
            s.gui.configure_theme(show_share_button=False, control_width="medium", show_logo=False)
        # 3D: controls docked right, the canvas takes the rest of the width, so the panel
        # never covers the mannequin (floating, it hid an arm); the wide pattern layout
        # keeps the whole width and its small floating tool panel
        self.server3d.gui.main_panel.dock_right()
        self.view3d = DrapeView(self.server3d, n_bands=c.n_bands, show_body=c.show_body)
        self.view2d = PatternView(self.server2d)
        self.view3d.on_tug = self._on_tug
        self.view3d.on_pick = self._on_pick_3d
        self.view2d.on_handle_drag = self._on_handle_drag
        self.view2d.on_click = self._on_pattern_click
        self._build_controls()
        self._build_tools()
        self.page = PageServer(c.host, c.port, self.server3d.get_port(), self.server2d.get_port())
        self._started = True
        self._threads = [threading.Thread(target=self._render_loop, name="couture-render", daemon=True),
                         threading.Thread(target=self._design_loop, name="couture-draft", daemon=True)]
        for t in self._threads:
            t.start()
        self._design_slot.put(self.design)
        return self.page.url

    def stop(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=2.0)
        if self.page is not None:
            self.page.stop()
        for s in (self.server3d, self.server2d):
            if s is not None:
                s.stop()

    def __enter__(self) -> "CoutureUI":
        if not self._started:
            self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def page_url(self) -> str:
        return self.page.url

    @property
    def url3d(self) -> str:
        return f"http://{self.config.host}:{self.server3d.get_port()}/"

    @property
    def url2d(self) -> str:
        return f"http://{self.config.host}:{self.server2d.get_port()}/"

    # ------------------------------------------------------------------ data in (thread-safe, non-blocking)

    def show_mesh(self, mesh: GarmentMesh) -> None:
        """A new simulation mesh (per level). The drape view switches to it
        when the first drape on it arrives (the fine mesh is shown at once
        with its x0 if nothing is on screen)."""
        self.meshes[mesh.level] = mesh
        if self.view3d.mesh is None or mesh.level == "fine" or self.view3d.mesh.level == mesh.level:
            self.view3d.set_mesh(mesh)
            self.view2d.set_mesh(mesh)

    def show_drape(self, x: np.ndarray, level: str, method: str = "", residual: float = float("nan"),
                   error_estimate: float | None = None, *, generation: int = 0, tag: Any = None,
                   solver: str = "", converged: bool | None = None, diagnosis: str = "", final: bool = True,
                   edit_id: str = "") -> None:
        """Store a drape to render; returns at once (the newest one wins)."""
        self._drape_slot.put(DrapeFrame(np.asarray(x), level, method, residual, error_estimate, generation, tag,
                                        solver=solver, converged=converged, diagnosis=diagnosis, final=final,
                                        edit_id=edit_id))

    def show_pattern(self, pattern: DraftedPattern) -> None:
        self.pattern = pattern
        self.view2d.set_pattern(pattern, list(self.design.strokes))

    def set_live_nodes(self, nodes: dict[str, bool] | Iterable[str]) -> None:
        """Liveliness: name -> alive (or the names alive now; others are dead).
        A dead node stays listed as dead; its last drape stays on screen."""
        alive = dict(nodes) if isinstance(nodes, dict) else {n: True for n in nodes}
        if not isinstance(nodes, dict):
            for n in self.nodes:
                alive.setdefault(n, False)
        for n, a in alive.items():
            info = self.nodes.setdefault(n, NodeInfo(n))
            info.alive = bool(a)
            if a:
                info.seen = time.time()
        self._status_dirty.set()

    def set_node_status(self, name: str, *, kind: str = "", state: str = "", rates: dict | None = None,
                        last_error: str = "") -> None:
        info = self.nodes.setdefault(name, NodeInfo(name))
        info.kind, info.state, info.rates, info.last_error = kind, state, dict(rates or {}), last_error
        info.seen = time.time()
        self._status_dirty.set()

    def set_status_notes(self, notes: list[str]) -> None:
        """Extra lines under the status table (the adapter's view of the pipeline)."""
        if notes != self.notes:
            self.notes = list(notes)
            self._status_dirty.set()

    def set_record_note(self, text: str, on: bool | None = None) -> None:
        """What the record toggle did (file path, or why not); ``on`` moves the toggle."""
        self.gui_record_note.content = text
        if on is not None and bool(self.gui_record.value) != on:
            self._suppress += 1
            try:
                self.gui_record.value = on
            finally:
                self._suppress -= 1

    def set_design(self, design: Design, *, emit: bool = False) -> None:
        """Adopt a design (from the bus or a replay): controls follow, nothing
        is published unless ``emit``."""
        self.design = design
        self._suppress += 1
        try:
            self._sync_controls()
        finally:
            self._suppress -= 1
        self._design_slot.put(design)
        if emit:
            self._emit_design()

    def apply_edit(self, edit: dict) -> None:
        """Show an edit that came from elsewhere (replay): the handle moves."""
        el = str(edit.get("element", ""))
        for i, h in enumerate(self.view2d.handles):
            if h.element == el:
                self.view2d.preview(h, np.asarray(edit.get("d", (0.0, 0.0)), np.float64).reshape(2), i)
                return

    # ------------------------------------------------------------------ render side

    def _render_loop(self) -> None:
        min_dt = 1.0 / max(self.config.max_fps, 1.0)
        last_push = 0.0
        last_status = 0.0
        while not self._stop.is_set():
            frame = self._drape_slot.take(timeout=0.05)
            if frame is not None:
                wait = last_push + min_dt - time.perf_counter()
                if wait > 0:
                    time.sleep(wait)
                    newer = self._drape_slot.take()
                    frame = newer if newer is not None else frame
                try:
                    self._push_frame(frame)
                except Exception:
                    log.exception("drawing a drape failed")
                last_push = time.perf_counter()
            now = time.perf_counter()
            if self._status_dirty.is_set() or now - last_status > 0.5:
                self._status_dirty.clear()
                last_status = now
                try:
                    self._refresh_status()
                except Exception:
                    log.exception("status refresh failed")

    def _push_frame(self, frame: DrapeFrame) -> None:
        n = len(frame.x)
        if self.view3d.mesh is None or self.view3d.mesh.n_vertices != n:
            mesh = next((m for m in self.meshes.values() if m.n_vertices == n), None)
            if mesh is None:
                return  # a drape for a mesh we do not have (yet): drop
            self.view3d.set_mesh(mesh)
        self.view3d.set_x(frame.x)
        self.on_screen = frame
        self.frames_pushed += 1
        self._update_frame_marker(frame)

    def _update_frame_marker(self, frame: DrapeFrame) -> None:
        import html
        import json

        tag = html.escape(json.dumps(frame.tag)) if frame.tag is not None else ""
        self.gui_frame.content = (
            f'<div id="couture-frame" data-seq="{self.frames_pushed}" data-tag="{tag}" '
            f'data-level="{frame.level}" data-generation="{frame.generation}" '
            f'style="font-size:12px">on screen: {html.escape(describe_frame(frame))}</div>'
        )
        scale = self.view3d.scale
        self.gui_legend.content = scale.legend_html() if scale is not None else ""

    def _design_loop(self) -> None:
        while not self._stop.is_set():
            design = self._design_slot.take(timeout=0.1)
            if design is None or not self.config.draft_locally:
                continue
            try:
                from couture.pattern import draft  # type: ignore[attr-defined]
            except ImportError:
                continue
            try:
                pattern = draft(design)
                self.show_pattern(pattern)
            except Exception as e:
                log.warning("drafting the design failed: %s", e)
                continue
            if self._design_slot.peek() is not design:
                continue  # a newer design is waiting: plan its handles instead
            try:
                handle_set = plan_handles(design, pattern)
            except Exception:
                log.exception("planning the pattern handles failed")
                continue
            if self._design_slot.peek() is design and self.pattern is pattern:
                self.view2d.set_handles(handle_set)
                self.handles_for = design

    def _refresh_status(self) -> None:
        rows = ["| node | state | rates |", "|---|---|---|"]
        for n in sorted(self.nodes):
            info = self.nodes[n]
            state = (info.state or "alive") if info.alive else "**DEAD**"
            if info.alive and info.last_error:
                state += f" (last error: {info.last_error[:80]})"
            rates = ", ".join(f"{k} {v:.3g}/s" for k, v in useful_rates(info.rates)[:3])
            rows.append(f"| {n} | {state} | {rates} |")
        if len(rows) == 2:
            rows.append("| (none) | | |")
        f = self.on_screen
        if f is not None:
            age = time.time() - f.received
            rows += ["", f"**On screen**: {describe_frame(f)}, {age:.1f} s old"]
        if self.notes:
            rows += [""] + [f"- {n}" for n in self.notes]
        self.gui_status.content = "\n".join(rows)
        solvers = sorted(n for n, i in self.nodes.items() if i.alive and (i.kind == "solver" or n.startswith("solver")))
        opts = ("any", *solvers)
        if self.selected_solver not in opts:
            opts = (*opts, self.selected_solver)  # a chosen solver that died stays chosen (its last drape stays)
        if tuple(self.gui_solver.options) != opts:
            self._suppress += 1
            try:
                self.gui_solver.options = opts
                self.gui_solver.value = self.selected_solver
            finally:
                self._suppress -= 1

    # ------------------------------------------------------------------ controls (3D server)

    def _build_controls(self) -> None:
        gui = self.server3d.gui
        with gui.add_folder("Garment"):
            kinds = sloper_kinds()
            kind = self.design.sloper.kind if self.design.sloper.kind in kinds else kinds[0]
            self.gui_sloper = gui.add_dropdown("sloper", tuple(kinds), initial_value=kind)
            self.gui_sloper.on_update(lambda _: self._on_sloper_kind())
            self._slider_folder = gui.add_folder("options")
            self.gui_params: dict[str, Any] = {}
            self.gui_tug_param = gui.add_dropdown("3D drag drives", ("(none)",), initial_value="(none)")
        with gui.add_folder("Fabric", expand_by_default=False):
            names = (*FABRIC_PRESETS, "custom")
            f = self.design.fabric
            self.gui_preset = gui.add_dropdown("preset", names, initial_value=f.name if f.name in names else "custom")
            self.gui_bend = gui.add_number("bending [N·m]", f.bend_stiffness, min=1e-9, max=1e-2, step=1e-9)
            self.gui_stretch = gui.add_number("stretching [N/m]", f.stretch_stiffness, min=1.0, max=1e4, step=1.0)
            self.gui_density = gui.add_number("density [kg/m²]", f.area_density, min=0.01, max=1.0, step=0.01)
            self.gui_preset.on_update(lambda _: self._on_preset())
            for h in (self.gui_bend, self.gui_stretch, self.gui_density):
                h.on_update(lambda _: self._on_fabric())
        with gui.add_folder("Simulation", expand_by_default=False):
            self.gui_solver = gui.add_dropdown("solver", ("any",), initial_value="any")
            self.gui_solver.on_update(lambda _: self._on_solver())
            r = self.design.resolution
            # small meshes (tests, slow machines) are legitimate: the range widens to the value
            self.gui_coarse = gui.add_slider("coarse vertices", min(100, r.coarse_vertices), 5000, 100,
                                             min(r.coarse_vertices, 5000))
            self.gui_fine = gui.add_slider("fine vertices", min(300, r.fine_vertices), 40000, 100,
                                           min(r.fine_vertices, 40000))
            for h in (self.gui_coarse, self.gui_fine):
                h.on_update(lambda _: self._on_resolution())
            self.gui_field = gui.add_dropdown("colour map", colormaps.FIELDS, initial_value="none")
            self.gui_field.on_update(lambda _: self._on_field())
            self.gui_legend = gui.add_html("")
        with gui.add_folder("Status"):
            self.gui_frame = gui.add_html('<div id="couture-frame" data-seq="0">on screen: nothing yet</div>')
            self.gui_status = gui.add_markdown("| node | state | rates |\n|---|---|---|\n| (none) | | |")
        with gui.add_folder("Session", expand_by_default=False):
            self.gui_record = gui.add_checkbox("record", False)
            self.gui_record.on_update(lambda _: self._emit(self.on_record, bool(self.gui_record.value)))
            self.gui_record_note = gui.add_markdown("")
            self.gui_exp_pattern = gui.add_button_group("export pattern", export.PATTERN_FORMATS)
            self.gui_exp_pattern.on_click(lambda ev: self._export_pattern(ev.target.value, ev.client))
            self.gui_exp_drape = gui.add_button_group("export drape", export.DRAPE_FORMATS)
            self.gui_exp_drape.on_click(lambda ev: self._export_drape(ev.target.value, ev.client))
            self.gui_export_note = gui.add_markdown("")
        self._rebuild_sliders()

    def _rebuild_sliders(self) -> None:
        for h in self.gui_params.values():
            h.remove()
        self.gui_params = {}
        kind = self.design.sloper.kind
        opts = sloper_options(kind)
        with self._slider_folder:
            for o in opts:
                val = float(self.design.sloper.params.get(o.name, o.default))
                step = o.step or _nice_step(o.max - o.min)
                label = f"{o.name} [{o.unit}]" if o.unit else o.name
                h = self.server3d.gui.add_slider(label, o.min, o.max, step, min(max(val, o.min), o.max))
                h.on_update(lambda _, name=o.name: self._on_param(name))
                self.gui_params[o.name] = h
        names = tuple(o.name for o in opts) or ("(none)",)
        self.gui_tug_param.options = names
        # a style option by default (the body measurements come first in the tables)
        self.gui_tug_param.value = "length" if "length" in names else names[0]

    def _sync_controls(self) -> None:
        d = self.design
        if self.server3d is None:
            return
        if self.gui_sloper.value != d.sloper.kind and d.sloper.kind in self.gui_sloper.options:
            self.gui_sloper.value = d.sloper.kind
            self._rebuild_sliders()
        for name, h in self.gui_params.items():
            if name in d.sloper.params:
                h.value = float(d.sloper.params[name])
        f = d.fabric
        self.gui_preset.value = f.name if f.name in FABRIC_PRESETS else "custom"
        self.gui_bend.value, self.gui_stretch.value, self.gui_density.value = (
            f.bend_stiffness, f.stretch_stiffness, f.area_density)
        for h, v in ((self.gui_coarse, d.resolution.coarse_vertices), (self.gui_fine, d.resolution.fine_vertices)):
            h.value = min(max(v, h.min), h.max)

    # -- control callbacks: every user action becomes a design change or an edit

    def _emit(self, cb: Callable | None, *args: Any) -> None:
        if cb is not None and not self._suppress:
            try:
                cb(*args)
            except Exception:
                log.exception("UI callback failed")

    def _emit_design(self) -> None:
        self.generation += 1
        self._design_slot.put(self.design)
        self._emit(self.on_design_changed, self.design)

    def _on_solver(self) -> None:
        if self._suppress:
            return
        self.select_solver(str(self.gui_solver.value))

    def select_solver(self, name: str) -> None:
        """Show only ``name``'s drapes ('any': every solver's); predictions always show."""
        self.selected_solver = name
        self._status_dirty.set()
        self._emit(self.on_solver_selected, name)

    def _on_sloper_kind(self) -> None:
        if self._suppress:
            return
        kind = self.gui_sloper.value
        self.design = msgspec.structs.replace(self.design, sloper=msgspec.structs.replace(
            self.design.sloper, kind=kind, params={}))
        self._rebuild_sliders()
        self._emit_design()

    def _on_param(self, name: str) -> None:
        if self._suppress:
            return
        params = dict(self.design.sloper.params)
        params[name] = float(self.gui_params[name].value)
        self.design = msgspec.structs.replace(self.design, sloper=msgspec.structs.replace(
            self.design.sloper, params=params))
        self._emit_design()

    def _on_preset(self) -> None:
        if self._suppress:
            return
        p = FABRIC_PRESETS.get(self.gui_preset.value)
        if p is None:
            return
        self._suppress += 1
        try:
            self.gui_bend.value, self.gui_stretch.value, self.gui_density.value = (
                p.bend_stiffness, p.stretch_stiffness, p.area_density)
        finally:
            self._suppress -= 1
        self._set_fabric(name=p.name, bend_stiffness=p.bend_stiffness, stretch_stiffness=p.stretch_stiffness,
                         area_density=p.area_density)

    def _on_fabric(self) -> None:
        if self._suppress:
            return
        self._suppress += 1
        try:
            self.gui_preset.value = "custom"
        finally:
            self._suppress -= 1
        self._set_fabric(name="custom", bend_stiffness=float(self.gui_bend.value),
                         stretch_stiffness=float(self.gui_stretch.value), area_density=float(self.gui_density.value))

    def _set_fabric(self, **kw: Any) -> None:
        fabric: Fabric = msgspec.structs.replace(self.design.fabric, **kw)
        self.design = msgspec.structs.replace(self.design, fabric=fabric)
        self.view3d.fabric_stretch = fabric.stretch_stiffness
        self.view3d.fabric_poisson = fabric.poisson_ratio
        self._emit_design()

    def _on_resolution(self) -> None:
        if self._suppress:
            return
        res = msgspec.structs.replace(self.design.resolution, coarse_vertices=int(self.gui_coarse.value),
                                      fine_vertices=int(self.gui_fine.value))
        self.design = msgspec.structs.replace(self.design, resolution=res)
        self._emit_design()

    def _on_field(self) -> None:
        self.view3d.set_field(self.gui_field.value)
        self._update_legend()

    def _update_legend(self) -> None:
        scale = self.view3d.scale
        self.gui_legend.content = scale.legend_html() if scale is not None else ""

    # -- exports

    def _export_pattern(self, fmt: str, client: viser.ClientHandle | None) -> Path | None:
        if self.pattern is None:
            self.gui_export_note.content = "no pattern to export yet"
            return None
        try:
            path = export.export_pattern(self.pattern, self.config.export_dir / f"pattern.{fmt}")
        except Exception as e:  # shown to the designer; the UI keeps running
            self.gui_export_note.content = f"pattern export to {fmt} failed: {type(e).__name__}: {e}"
            return None
        self._offer(path, client)
        return path

    def _export_drape(self, fmt: str, client: viser.ClientHandle | None) -> Path | None:
        mesh, x = self.view3d.mesh, self.view3d.x
        if mesh is None or x is None:
            self.gui_export_note.content = "no drape to export yet"
            return None
        path = export.export_drape(mesh, x, self.config.export_dir / f"drape.{fmt}")
        self._offer(path, client)
        return path

    def _offer(self, path: Path, client: viser.ClientHandle | None) -> None:
        self.gui_export_note.content = f"wrote `{path}`"
        if client is not None:
            client.send_file_download(path.name, path.read_bytes())

    def export(self, kind: str, fmt: str) -> Path | None:
        """Write an export without a browser ('pattern' or 'drape', format)."""
        return (self._export_pattern if kind == "pattern" else self._export_drape)(fmt, None)

    # ------------------------------------------------------------------ pattern tools (pattern server)

    def _build_tools(self) -> None:
        gui = self.server2d.gui
        with gui.add_folder("Tools"):
            self.gui_tool_help = gui.add_markdown("Drag a handle to edit; click the cloth to find it in 3D.")
            b_curve = gui.add_button("Add a curve point")
            b_dart = gui.add_button("Draw a dart")
            b_sew = gui.add_button("Sew two segments")
            b_sym = gui.add_button("Mark symmetry")
            b_cancel = gui.add_button("Cancel tool")
            b_curve.on_click(lambda _: self.arm_tool("curve"))
            b_dart.on_click(lambda _: self.arm_tool("dart"))
            b_sew.on_click(lambda _: self.arm_tool("seam"))
            b_sym.on_click(lambda _: self.arm_tool("symmetry"))
            b_cancel.on_click(lambda _: self.arm_tool(None))
            self.gui_show_mesh = gui.add_checkbox("show mesh", False)
            self.gui_show_mesh.on_update(lambda _: self.view2d.set_show_mesh(bool(self.gui_show_mesh.value)))

    _TOOL_HELP = {
        "curve": "**Curve point**: click the boundary where the new control point goes; then drag it.",
        "dart": "**Dart**: click the boundary where the dart goes.",
        "seam": "**Sew**: click the first segment, then the second.",
        "symmetry": "**Symmetry**: click the segment the panel is mirrored about.",
    }

    def arm_tool(self, tool: str | None) -> None:
        self._armed = None if tool is None else {"tool": tool, "picks": []}
        self.gui_tool_help.content = self._TOOL_HELP.get(tool or "", "Drag a handle to edit; click the cloth to find it in 3D.")

    def _on_pattern_click(self, p: np.ndarray, panel: str | None) -> None:
        if self._armed is None:
            mp = self.view2d.locate(p)
            if mp is not None:
                self.view2d.show_marker(mp)
                self.view3d.show_marker(mp)
                self._emit(self.on_pick, mp)
            return
        seg = self.view2d.nearest_segment(p)
        if seg is None:
            return
        tool = self._armed["tool"]
        self._armed["picks"].append(seg)
        picks = self._armed["picks"]
        if tool == "seam" and len(picks) < 2:
            self.gui_tool_help.content = f"**Sew**: first is {picks[0][0]}:{picks[0][1]}; click the second segment."
            return
        n = next(self._stroke_ids)
        if tool == "curve":
            # couture.pattern's curve stroke: control points [s, dn] (fraction
            # along the segment, normal displacement [m]); a new point starts at dn = 0
            pn, sn, t = picks[0]
            sid = f"curve-{pn}-{sn}"
            old = next((s for s in self.design.strokes
                        if s.kind == "curve" and s.panel == pn and s.params.get("segment") == sn), None)
            pts = [list(p) for p in (old.params["points"] if old else [])]
            pts = sorted(pts + [[round(min(max(t, 0.02), 0.98), 4), 0.0]])
            stroke = Stroke(id=old.id if old else sid, kind="curve", panel=pn, params={"segment": sn, "points": pts})
        elif tool == "dart":
            pn, sn, t = picks[0]
            # couture.pattern's boundary dart: position along the segment (0..1), width, length [m]
            stroke = Stroke(id=f"dart-{n}", kind="dart", panel=pn,
                            params={"segment": sn, "position": round(min(max(t, 0.05), 0.95), 4),
                                    "width": 0.02, "length": 0.08})
        elif tool == "symmetry":
            pn, sn, _ = picks[0]
            stroke = Stroke(id=f"symmetry-{n}", kind="symmetry", panel=pn, params={"axis": sn})
        else:
            (pa, sa, _), (pb, sb, _) = picks
            stroke = Stroke(id=f"seam-{n}", kind="seam", panel="",
                            params={"a_panel": pa, "a_segment": sa, "b_panel": pb, "b_segment": sb})
        self.add_stroke(stroke)
        self.arm_tool(None)

    def add_stroke(self, stroke: Stroke) -> None:
        strokes = [s for s in self.design.strokes if s.id != stroke.id] + [stroke]
        self.design = msgspec.structs.replace(self.design, strokes=strokes)
        if self.pattern is not None:
            self.view2d.set_pattern(self.pattern, strokes)
        self._emit_design()

    # ------------------------------------------------------------------ drags → edits

    def _on_handle_drag(self, phase: str, handle: Handle, d: np.ndarray) -> None:
        """A handle drag: ``d`` is already in the element's pointer convention
        (couture.ui.handles). press/drag/release go out as edits; the release
        commits ``apply_edit(design, element, d)`` as one new design."""
        if phase == "press":
            self._edit_id = uuid.uuid4().hex[:12]
        self.last_edit_stamp = time.time()
        kind = handle.kind
        dofs = [handle.element.split(":", 1)[1]] if kind == "param" else ["x", "y"]
        self._emit(self.on_edit, {
            "edit_id": self._edit_id, "phase": phase, "element": handle.element, "dofs": dofs,
            "d": [float(d[0]), float(d[1])], "param": handle.element[6:] if kind == "param" else "",
        })
        if phase != "release":
            return
        if not np.any(d):
            if self.pattern is not None:  # nothing moved: put the outline back
                self.view2d.set_pattern(self.pattern, list(self.design.strokes))
                self._design_slot.put(self.design)
            return
        from couture.pattern import apply_edit

        try:
            new = apply_edit(self.design, handle.element, d)
        except Exception as e:  # e.g. a value outside the option's range
            log.warning("edit %s by %s rejected: %s", handle.element, d, e)
            self.gui_tool_help.content = f"**Edit rejected**: {e}"
            self._design_slot.put(self.design)
            return
        self.design = new
        self._suppress += 1
        try:
            self._sync_controls()
        finally:
            self._suppress -= 1
        self._emit_design()

    def _on_tug(self, phase: str, mp: MaterialPoint, vertex: int, p0: tuple[float, float],
                p: tuple[float, float], cam: CameraState | None) -> None:
        if phase == "press":
            self._edit_id = uuid.uuid4().hex[:12]
        self.last_edit_stamp = time.time()
        # the sensitivity node maps the screen drag to this sloper option and,
        # on release, publishes the new design itself: the UI publishes nothing
        param = "" if self.gui_tug_param.value == "(none)" else str(self.gui_tug_param.value)
        edit = {
            "edit_id": self._edit_id, "phase": phase, "element": f"param:{param}" if param else "",
            "dofs": [param] if param else [],
            "d": [p[0] - p0[0], p[1] - p0[1]], "param": param,
            "picked_vertex": int(vertex), "picked_tri": int(mp.tri), "picked_bary": [float(b) for b in mp.bary],
        }
        if cam is not None:
            edit["view_proj"] = cam.view_proj_gl().tolist()
            edit["viewport_px"] = [cam.width, cam.height]
        self._emit(self.on_edit, edit)

    def _on_pick_3d(self, mp: MaterialPoint) -> None:
        self.view2d.show_marker(mp)
        self._emit(self.on_pick, mp)


NOISY_RATE_PREFIXES = ("sent/status", "recv/status")


def useful_rates(rates: dict[str, float]) -> list[tuple[str, float]]:
    """A node's rates worth showing: not the status heartbeat's own traffic, busiest first."""
    keep = [(k, v) for k, v in rates.items() if not k.startswith(NOISY_RATE_PREFIXES) and v > 0]
    return sorted(keep, key=lambda kv: -kv[1])


def describe_frame(f: DrapeFrame) -> str:
    """Which method produced the drape on screen, in words."""
    if f.level == "predicted":
        err = "error estimate pending" if f.error_estimate is None else f"error estimate {f.error_estimate:.2g}"
        return f"prediction ({f.method or '?'}), {err}, generation {f.generation}"
    who = f.solver or f.method or "solver"
    if f.solver and f.method and f.method not in f.solver:
        who += f" ({f.method})"
    res = "" if not math.isfinite(f.residual) else f", residual {f.residual:.2g}"
    if not f.final:
        state = "solving"
    elif f.converged:
        state = "converged"
    elif f.converged is None:
        state = "final"
    else:
        state = "not converged" + (f": {f.diagnosis}" if f.diagnosis else "")
    return f"{f.level} solve by {who}{res}, {state}, generation {f.generation}"


def _nice_step(span: float) -> float:
    if span <= 0:
        return 0.01
    raw = span / 200.0
    return float(10 ** math.floor(math.log10(raw)))

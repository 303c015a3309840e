"""CoutureUI: the designer's web page (two viser servers + a page showing both).

Pure UI: no bus import. Like viser's server, which assembles its scene and
GUI APIs, CoutureUI owns the servers and wires the parts, one job each:

- :class:`~couture.ui.drape_view.DrapeView` (3D scene) and
  :class:`~couture.ui.pattern_view.PatternView` (pattern scene): drawing, picking;
- :class:`~couture.ui.controls.Controls`: design controls → new designs;
- :class:`~couture.ui.tools.PatternTools`: pattern tools → strokes;
- :class:`~couture.ui.seams_panel.SeamsPanel`: the seams' confidence; confirm or drop one;
- :class:`~couture.ui.gestures.Gestures`: drags → typed edits;
- :class:`~couture.ui.exports.SessionPanel`: record toggle, exports;
- :class:`~couture.ui.adjust_panel.AdjustPanel`: a hem or waist loop dragged
  in 3D -> a pattern adjustment request (the adjust node runs it);
- :class:`~couture.ui.status.StatusPanel`: status text;
- :class:`~couture.ui.loops.DrapeRenderer` and :class:`~couture.ui.loops.Drafter`:
  the threads that bring the newest drape and the newest design to the screen.

The bus adapter (``nodes/ui/main.py``) sets the ``on_*`` callbacks (what the
user did → messages) and calls the ``show_*`` / ``set_*`` methods (messages →
screen). Those only store the newest value and return at once, so a slow or
dead solver never blocks the page.

    ui = CoutureUI(UIConfig(port=8080))
    ui.on_design_changed = lambda design: ...
    ui.on_edit = lambda edit: ...          # couture.ui.gestures.Edit
    ui.start(); print(ui.page_url)
    ui.show_mesh(mesh); ui.show_drape(x, "fine", "kinetic", residual=1e-4)
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np
import viser

from couture.mesh import GarmentMesh
from couture.pattern.drafted import DraftedPattern
from couture.ui.adjust_panel import AdjustPanel
from couture.ui.controls import Controls
from couture.ui.drape_view import DrapeView
from couture.ui.exports import SessionPanel
from couture.ui.geometry import MaterialPoint
from couture.ui.gestures import Edit, Gestures
from couture.ui.handles import HandleSet
from couture.ui.loops import Drafter, DrapeRenderer
from couture.ui.page import PageServer
from couture.ui.pattern_view import PatternView
from couture.ui.seams_panel import SeamsPanel
from couture.ui.state import DrapeFrame
from couture.ui.status import StatusPanel
from couture.ui.tools import PatternTools
from couture.ui.tryon_panel import TryOnPanel
from schemas.design import Design

log = logging.getLogger("couture.ui")

PANEL_WIDTH_3D = 300
"""[px] of the design controls (sliders need about this much)"""
PANEL_WIDTH_2D = 220
"""[px] of the pattern tools (a column of buttons)"""


@dataclass
class UIConfig:
    host: str = "127.0.0.1"
    """bind address of all three servers (loopback by default)"""
    port: int = 8080
    """the combined page (what users open); the 3D view is port + 1, the pattern view port + 2
    (each moves up when taken; :attr:`CoutureUI.page_url` says where the page is)"""
    port_fallback: bool = True
    """``port`` taken: serve the page on the next free port (port + 3, ...)
    instead of failing with :class:`couture.ui.page.PortInUse`"""
    export_dir: Path = Path("out/exports")
    max_fps: float = 60.0
    """upper bound on drape pushes to the browser [1/s]"""
    show_body: bool = True
    n_bands: int = 9
    """colour bands of the strain/stress/pressure maps"""
    draft_locally: bool = True
    """draft each design with couture.pattern to show its pattern and handles
    (off: the pattern comes only through :meth:`CoutureUI.show_pattern`)"""


class CoutureUI:
    def __init__(self, config: UIConfig | None = None, design: Design | None = None):
        self.config = config or UIConfig()
        self.design: Design = design or Design()
        self.generation = 0
        """generation of :attr:`design` (the adapter adopts the bus's numbering)"""
        # callbacks the bus adapter sets (user actions out)
        self.on_design_changed: Callable[[Design], None] | None = None
        self.on_edit: Callable[[Edit], None] | None = None
        self.on_record: Callable[[bool], None] | None = None
        """cb(on) of the record toggle; the adapter answers with :meth:`set_record_note`"""
        self.on_solver_selected: Callable[[str], None] | None = None
        self.on_pick: Callable[[MaterialPoint], None] | None = None
        self.on_tryon: Callable[[dict], None] | None = None
        """cb(op) of the Try-on folder's buttons (TryOnMsg's fields); the adapter publishes it"""
        self.on_adjust: Callable[[str, float], object] | None = None
        """cb(loop, amount [m]) of the Adjust pattern folder; the adapter sends an
        ``adjust`` request and answers with :meth:`show_adjust_status`"""
        self.meshes: dict[str, GarmentMesh] = {}
        """newest mesh per level"""
        self.pattern: DraftedPattern | None = None
        self.selected_solver = "any"
        """solver node whose drapes are shown ('any': every solver's)"""
        self.handles_for: Design | None = None
        """the design the pattern view's handles were planned for"""
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self.server3d: viser.ViserServer | None = None
        self.server2d: viser.ViserServer | None = None
        self.page: PageServer | None = None

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> str:
        """Start the servers and the threads; returns the page URL (its own
        port: another when ``config.port`` was taken and ``port_fallback``)."""
        c = self.config
        # the page's port first: it is the URL users open, the views follow it
        self.page = PageServer(c.host, c.port, fallback=c.port_fallback)
        try:
            self._start_views()
        except BaseException:
            self.page.stop()
            raise
        return self.page.url

    def _start_views(self) -> None:
        c = self.config
        assert self.page is not None
        self.server3d = viser.ViserServer(host=c.host, port=self.page.port + 1, label="couture 3D", verbose=False)
        self.server2d = viser.ViserServer(
            host=c.host, port=self.server3d.get_port() + 1, label="couture pattern", verbose=False
        )
        for s in (self.server3d, self.server2d):
            s.gui.configure_theme(show_share_button=False, control_width="medium", show_logo=False)
        # each view's panel is docked on the page's middle line, so no panel
        # ever covers the mannequin or a pattern piece: the canvases keep the rest
        self.server3d.gui.main_panel.dock_right()
        self.server3d.gui.main_panel.set_width(PANEL_WIDTH_3D)
        self.server2d.gui.main_panel.dock_left()
        self.server2d.gui.main_panel.set_width(PANEL_WIDTH_2D)
        self.view3d = DrapeView(self.server3d, n_bands=c.n_bands, show_body=c.show_body)
        self.view2d = PatternView(self.server2d)
        self.view3d.set_fabric(self.design.fabric, self.design.scene.contact_stiffness_scale, self.design.panel_fabrics)
        self.controls = Controls(
            self.server3d.gui,
            lambda: self.design,
            on_design=self.commit,
            on_solver=self.select_solver,
            on_field=self._show_field,
        )
        self.tryon = TryOnPanel(
            self.server3d.gui,
            lambda op: self.on_tryon and self.on_tryon(op),
            drape=lambda: (self.view3d.mesh, self.view3d.x),
            body=lambda: self.view3d.body_name,
        )
        self.adjust = AdjustPanel(
            self.server3d,
            self._request_adjust,
            on_undo=self.commit,
            drape=lambda: self.view3d.x,
            design=lambda: self.design,
        )
        self.status = StatusPanel(self.server3d.gui)
        self.session = SessionPanel(
            self.server3d.gui,
            c.export_dir,
            pattern=lambda: self.pattern,
            drape=lambda: (self.view3d.mesh, self.view3d.x),
            on_record=lambda on: self.on_record and self.on_record(on),
        )
        self.tools = PatternTools(self.server2d.gui, self.view2d, lambda: self.design, self.commit, self._pick)
        self.seams = SeamsPanel(self.server2d.gui, lambda: self.design, self.commit)
        self.gestures = Gestures(
            lambda: self.design,
            self.commit,
            restore_pattern=self.view2d.restore,
            say=self.tools.say,
            tug_option=lambda: self.controls.tug_option,
            on_edit=lambda edit: self.on_edit and self.on_edit(edit),
        )
        self.view3d.on_tug = self.gestures.tug
        self.view3d.on_pick = self._pick
        self.view3d.on_body_click = self.pick_body
        self.view2d.on_handle_drag = self.gestures.handle_drag
        self.view2d.on_click = self.tools.click
        self.renderer = DrapeRenderer(
            self.view3d,
            self.status,
            self.controls,
            meshes=lambda: list(self.meshes.values()),
            selected_solver=lambda: self.selected_solver,
            max_fps=c.max_fps,
        )
        self.renderer.on_pushed = lambda frame: self.adjust.follow(frame.x)
        self.drafter = Drafter(
            show_pattern=self.show_pattern, pattern=lambda: self.pattern, show_handles=self._show_handles
        )
        self.page.set_views(self.server3d.get_port(), self.server2d.get_port())
        workers = [(self.renderer.run, "couture-render")]
        if c.draft_locally:
            workers.append((self.drafter.run, "couture-draft"))
        self._threads = [
            threading.Thread(target=run, args=(self._stop,), name=name, daemon=True) for run, name in workers
        ]
        for t in self._threads:
            t.start()
        # the initial design as any later one: its body on the mannequin (an imported
        # design names the shipped body nearest its measurements), its controls, its draft
        self._adopt(self.design)

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
        if self.page is None:
            self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def page_url(self) -> str:
        if self.page is None:
            raise RuntimeError("CoutureUI.page_url: the UI is not started")
        return self.page.url

    @property
    def on_screen(self) -> DrapeFrame | None:
        """The drape last pushed to the browser."""
        return self.renderer.on_screen

    @property
    def frames_pushed(self) -> int:
        return self.renderer.frames_pushed

    @property
    def url3d(self) -> str:
        if self.server3d is None:
            raise RuntimeError("CoutureUI.url3d: the UI is not started")
        return f"http://{self.config.host}:{self.server3d.get_port()}/"

    @property
    def url2d(self) -> str:
        if self.server2d is None:
            raise RuntimeError("CoutureUI.url2d: the UI is not started")
        return f"http://{self.config.host}:{self.server2d.get_port()}/"

    # ------------------------------------------------------------------ data in (thread-safe, non-blocking)

    def show_mesh(self, mesh: GarmentMesh) -> None:
        """A new simulation mesh (per level). The fine mesh, or one of the
        level on screen, is shown at once; a mesh whose rest positions and
        triangles are those on screen (e.g. re-sent with Ψ on a press) keeps
        the drape on screen instead of its initial positions."""
        self.meshes[mesh.level] = mesh
        self.tryon.set_panels(list(mesh.panel_names))
        shown = self.view3d.mesh
        if shown is None or mesh.level == "fine" or shown.level == mesh.level:
            self.view3d.set_mesh(mesh)
            self.view2d.set_mesh(mesh)

    def show_drape(
        self,
        x: np.ndarray,
        level: str,
        method: str = "",
        residual: float = float("nan"),
        error_estimate: float | None = None,
        *,
        generation: int = 0,
        tag: Any = None,
        solver: str = "",
        converged: bool | None = None,
        diagnosis: str = "",
        final: bool = True,
        edit_id: str = "",
        error_estimate_m: float | None = None,
    ) -> None:
        """Store a drape to render; returns at once (the newest one wins)."""
        self.renderer.slot.put(
            DrapeFrame(
                np.asarray(x),
                level,
                method,
                residual,
                error_estimate,
                generation,
                tag,
                solver=solver,
                converged=converged,
                diagnosis=diagnosis,
                final=final,
                edit_id=edit_id,
                error_estimate_m=error_estimate_m,
            )
        )

    def show_pattern(self, pattern: DraftedPattern) -> None:
        self.pattern = pattern
        self.view2d.set_pattern(pattern)

    def set_live_nodes(self, nodes: dict[str, bool] | Iterable[str]) -> None:
        """Liveliness: name -> alive (or the names alive now; others are dead).
        A dead node stays listed as dead; its last drape stays on screen."""
        self.status.set_live_nodes(nodes)

    def set_node_status(
        self, name: str, *, kind: str = "", state: str = "", rates: dict | None = None, last_error: str = ""
    ) -> None:
        self.status.set_node_status(name, kind=kind, state=state, rates=rates, last_error=last_error)

    def set_rejection(self, text: str) -> None:
        """Show why the newest design was rejected (node, field, value, allowed
        range) at the top of the status; '' clears it."""
        self.status.set_rejection(text)

    def set_tryon_note(self, text: str) -> None:
        """A solver refused a try-on op: why, in the Try-on folder (the design
        and its drape stay as they were)."""
        self.tryon.set_refused(text)

    def set_status_notes(self, notes: list[str]) -> None:
        """Extra lines under the status table (the adapter's view of the pipeline)."""
        self.status.set_notes(notes)

    def set_record_note(self, text: str, on: bool | None = None) -> None:
        """What the record toggle did (file path, or why not); ``on`` moves the toggle."""
        self.session.show_record(text, on)

    def set_design(self, design: Design, *, emit: bool = False) -> None:
        """Adopt a design (from the bus or a replay): controls follow, nothing
        is published unless ``emit``."""
        if emit:
            self.commit(design)
            return
        self.design = design
        self._adopt(design)

    def preview_remote_edit(self, element: str, d: np.ndarray) -> None:
        """Show an edit that another client is making (a replay): its handle
        and the outlines move; the design changes when its release commits."""
        self.view2d.preview_element(element, np.asarray(d, np.float64).reshape(2))

    def show_adjust_status(
        self, state: str, iteration: int, text: str, error: str = "", goal_met: bool | None = None
    ) -> None:
        """Progress of this UI's adjust request (running, iteration, done with its verdict, failed)."""
        self.adjust.show_status(state, iteration, text, error, goal_met)

    def _request_adjust(self, loop: str, amount: float) -> None:
        if self.on_adjust is None:
            raise RuntimeError("this UI is not on a bus: no adjust node to ask")
        self.on_adjust(loop, amount)

    def select_solver(self, name: str) -> None:
        """Show only ``name``'s drapes ('any': every solver's); predictions always show."""
        self.selected_solver = name
        self.status.dirty.set()
        if self.on_solver_selected is not None:
            self.on_solver_selected(name)

    def export(self, kind: str, fmt: str) -> Path | None:
        """Write an export without a browser ('pattern' or 'drape', format)."""
        return (self.session.export_pattern if kind == "pattern" else self.session.export_drape)(fmt)

    # ------------------------------------------------------------------ design changes made here

    def commit(self, design: Design) -> None:
        """A design change made in this UI: one generation more, handed to ``on_design_changed``."""
        self.design = design
        self.generation += 1
        self._adopt(design)
        if self.on_design_changed is not None:
            try:
                self.on_design_changed(design)
            except Exception:
                log.exception("publishing the design failed")

    def _adopt(self, design: Design) -> None:
        self.controls.show_design(design)
        self.view3d.set_fabric(design.fabric, design.scene.contact_stiffness_scale, design.panel_fabrics)
        shown = self.view3d.body_name
        try:
            from couture import bodies

            self.view3d.set_body(bodies.use(design.body))
        except ValueError:
            log.warning("unknown body %r: the view keeps %r", design.body.name, self.view3d.body_name)
        if self.view3d.body_name != shown:  # a point picked on the old body is no target
            self.tryon.set_target(None)
            self.view3d.show_body_marker(None)
        self.seams.show(design)
        self.drafter.slot.put(design)

    def pick_body(self, origin, direction):
        """A click on the body in the 3D view: the point its ray meets the
        shown body's ellipsoid proxy (couture.ui.geometry.pick_body; the proxy
        is loaded, or built and cached, once per body) becomes the Try-on
        folder's drag target. Returns the BodyPick, or None on a miss."""
        from couture.cloth.proxy import load_body_proxy
        from couture.ui.geometry import pick_body

        proxy = load_body_proxy(self.view3d.body_name, verbose=False)
        pick = pick_body(origin, direction, proxy)
        # marker first: a reader that sees the target also sees its marker
        self.view3d.show_body_marker(None if pick is None else pick.point)
        self.tryon.set_target(pick)
        return pick

    def _pick(self, mp: MaterialPoint) -> None:
        self.view2d.show_marker(mp)
        self.view3d.show_marker(mp)
        if self.on_pick is not None:
            self.on_pick(mp)

    def _show_field(self, field: str) -> None:
        self.view3d.set_field(field)
        self.controls.show_legend(self.view3d.scale)

    def _show_handles(self, design: Design, handle_set: HandleSet) -> None:
        self.view2d.set_handles(handle_set)
        self.handles_for = design

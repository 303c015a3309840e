"""The 3D view: mannequin, drape (plain or colour-banded), the picked-point
marker, and tugging the drape.

viser 1.1 meshes take one colour each (no per-vertex colours except through a
GLB, which the client re-parses and blanks on every update), so a colour map
is drawn as ``n_bands`` meshes, one per colour band of the scale, each holding
the triangles whose value falls in that band (a banded contour plot, as FEA
post-processors draw them). The nodes are created once and then only their
vertices/faces change, so a drag that started on one of them survives the
updates. Without a colour map the drape is one mesh whose vertices alone are
updated: the fast path.
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path
from typing import Callable

import numpy as np
import viser

from couture.mesh import GarmentMesh
from couture.ui import colormaps
from couture.ui.geometry import CameraState, MaterialPoint, closest_material_point, ray_hit
from couture.ui.state import VISER_DRAG_PHASE, Phase
from couture.ui.widgets import ClientFraming, fit_distance
from schemas.design import Fabric

log = logging.getLogger(__name__)

MANNEQUIN_OBJ = Path(__file__).resolve().parents[1] / "assets" / "mannequin" / "body_a_pose.obj"

DRAPE_COLOR = (214, 120, 92)
BODY_COLOR = (205, 200, 195)
CAMERA_FOV = float(np.deg2rad(30.0))
"""vertical field of view of the 3D view [rad]"""
_EMPTY_V = np.zeros((3, 3), np.float32)
_EMPTY_F = np.array([[0, 1, 2]], np.uint32)


def load_body(path: Path = MANNEQUIN_OBJ) -> tuple[np.ndarray, np.ndarray]:
    """Mannequin vertices [m] (y up) and faces."""
    import trimesh

    m = trimesh.load(path, process=False, force="mesh")
    assert isinstance(m, trimesh.Trimesh), f"{path}: not a single mesh"
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def same_geometry(a: GarmentMesh, b: GarmentMesh) -> bool:
    """Same rest positions and triangles (the same mesh, possibly re-sent)."""
    return (
        a.X.shape == b.X.shape
        and a.tris.shape == b.tris.shape
        and np.array_equal(a.tris, b.tris)
        and np.array_equal(a.X, b.X)
    )


TugCallback = Callable[[Phase, MaterialPoint, int, tuple[float, float], tuple[float, float], CameraState | None], None]
"""cb(phase 'press'|'drag'|'release', material point, picked vertex,
press screen position [px], current screen position [px], camera)"""


class DrapeView:
    """Owns the scene of the 3D viser server."""

    def __init__(self, server: viser.ViserServer, *, n_bands: int = 9, show_body: bool = True):
        self.server = server
        self.n_bands = n_bands
        self.mesh: GarmentMesh | None = None
        self.x: np.ndarray | None = None
        self.field = "none"
        self.scale: colormaps.ColorScale | None = None
        self.fabric = Fabric()
        """material of the stress and pressure maps"""
        self.panel_fabrics: dict[str, Fabric] = {}
        """panels' own fabrics (``Design.panel_fabrics``) for the fabric-mode maps"""
        self._axes: colormaps.FabricAxes | None = None
        """the fabric-mode maps' per-triangle warp and limits for this mesh and these fabrics"""
        self.contact_scale = 1.0
        """the design's factor on the solver's contact stiffness (pressure map)"""
        self.mesh_uploads = 0
        """how often triangles went to the browser (a new mesh)"""
        self.on_tug: TugCallback | None = None
        self.on_pick: Callable[[MaterialPoint], None] | None = None
        self.on_body_click: Callable[[np.ndarray, np.ndarray], None] | None = None
        """cb(ray origin, ray direction) of a click on the body"""
        self.body_handle = None
        self._lock = threading.RLock()
        self._tug: dict | None = None

        server.scene.set_up_direction("+y")
        self.body_distance: colormaps.BodyDistance | None = None
        self.show_body = show_body
        self.body_name = ""
        self.set_body("default")
        # the mannequin fills the canvas's height (or its width, on a wide canvas)
        self.body_box = (self.body_vertices.min(axis=0), self.body_vertices.max(axis=0))
        ic = server.initial_camera
        ic.fov = CAMERA_FOV
        ic.position, ic.look_at = self.fit_body(0.5)
        ic.up = (0.0, 1.0, 0.0)
        self.framing = ClientFraming(server, self.fit_body)
        self.plain = server.scene.add_mesh_simple(
            "/drape/plain",
            _EMPTY_V,
            _EMPTY_F,
            color=DRAPE_COLOR,
            side="double",
            visible=False,
            cast_shadow=False,
            receive_shadow=False,
        )
        self.bands = [
            server.scene.add_mesh_simple(
                f"/drape/band{b}",
                _EMPTY_V,
                _EMPTY_F,
                color=DRAPE_COLOR,
                side="double",
                visible=False,
                cast_shadow=False,
                receive_shadow=False,
            )
            for b in range(n_bands)
        ]
        self._band_tris: list[np.ndarray | None] = [None] * n_bands
        self.marker = server.scene.add_icosphere(
            "/marker", radius=0.012, color=(230, 30, 30), visible=False, cast_shadow=False, receive_shadow=False
        )
        self.body_marker = server.scene.add_icosphere(
            "/body_marker", radius=0.01, color=(40, 90, 220), visible=False, cast_shadow=False, receive_shadow=False
        )
        for h in [self.plain, *self.bands]:
            h.on_drag(self._on_drag)
            h.on_click(self._on_click)

    def set_body(self, name: str) -> None:
        """Show the body ``name`` (couture.bodies: 'default' or a graded size)."""
        from couture import bodies

        with self._lock:
            if name == self.body_name:
                return
            path = bodies.obj_path(name)
            self.body_vertices, self.body_faces = load_body(path)
            self.body_name = name
            self.body_distance = colormaps.BodyDistance(name) if self.field == "pressure" else None
            if self.show_body:
                self.body_handle = self.server.scene.add_mesh_simple(
                    "/body",
                    self.body_vertices.astype(np.float32),
                    self.body_faces.astype(np.uint32),
                    color=BODY_COLOR,
                    side="front",
                    cast_shadow=False,
                    receive_shadow=False,
                )
                self.body_handle.on_click(self._on_body_click)

    def fit_body(self, aspect: float) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Camera (position, look_at) [m] of a front view in which the
        mannequin's bounding box spans 95 % of a canvas of this aspect (its
        height, or on a narrow canvas the span of its arms)."""
        lo, hi = self.body_box
        c = 0.5 * (lo + hi)
        dist = fit_distance(0.5 * (hi[0] - lo[0]), 0.5 * (hi[1] - lo[1]), CAMERA_FOV, aspect, fill=0.95) + (
            hi[2] - c[2]
        )
        return (float(c[0]), float(c[1]), float(c[2] + dist)), (float(c[0]), float(c[1]), float(c[2]))

    # -- data in ----------------------------------------------------------------

    def set_mesh(self, mesh: GarmentMesh) -> None:
        """Show a mesh at its initial positions x0, unless it is the mesh on
        screen (same rest positions and triangles): then nothing is uploaded
        and the drape on screen stays."""
        with self._lock:
            if self.mesh is not None and same_geometry(self.mesh, mesh):
                if not (
                    np.array_equal(self.mesh.tri_panel, mesh.tri_panel)
                    and np.array_equal(self.mesh.panel_grain, mesh.panel_grain)
                    and self.mesh.panel_names == mesh.panel_names
                ):
                    self._axes = None
                self.mesh = mesh
                return
            self.mesh = mesh
            self._axes = None
            self.x = np.asarray(mesh.x0, np.float64)
            self._band_tris = [None] * self.n_bands
            self.plain.faces = mesh.tris.astype(np.uint32)
            self.mesh_uploads += 1
            self._draw()

    def set_fabric(
        self, fabric: Fabric, contact_scale: float | None = None, panel_fabrics: dict[str, Fabric] | None = None
    ) -> None:
        """The material of the stress, pressure and fabric-mode maps, the
        design's ``scene.contact_stiffness_scale`` (None: keep the current
        one) and its ``panel_fabrics`` (None: keep the current ones)."""
        with self._lock:
            scale = self.contact_scale if contact_scale is None else float(contact_scale)
            panels = self.panel_fabrics if panel_fabrics is None else dict(panel_fabrics)
            if fabric == self.fabric and scale == self.contact_scale and panels == self.panel_fabrics:
                return
            self.fabric = fabric
            self.contact_scale = scale
            self.panel_fabrics = panels
            self._axes = None
            if self.field in ("stress", "pressure") + colormaps.FABRIC_FIELDS:
                self._draw()

    def set_field(self, field: str) -> None:
        with self._lock:
            self.field = field
            if field == "pressure" and (self.body_distance is None or self.body_distance.name != self.body_name):
                self.body_distance = colormaps.BodyDistance(self.body_name or "default")
            self._band_tris = [None] * self.n_bands
            self._draw()

    def set_x(self, x: np.ndarray) -> None:
        with self._lock:
            if self.mesh is None or len(x) != self.mesh.n_vertices:
                return
            self.x = np.asarray(x, np.float64)
            self._draw()

    # -- drawing ------------------------------------------------------------------

    def fabric_axes(self) -> colormaps.FabricAxes | None:
        """Each triangle's warp and stretch limits (cached per mesh and fabrics);
        None without a mesh. Panel fabrics naming no panel of this mesh (a
        design ahead of its mesh) are left out until the mesh catches up."""
        if self.mesh is None:
            return None
        if self._axes is None:
            names = set(self.mesh.panel_names)
            panels = {k: v for k, v in self.panel_fabrics.items() if k in names}
            try:
                self._axes = colormaps.fabric_axes(self.mesh, self.fabric, panels)
            except ValueError as e:  # a fabric the model cannot build: the map is left off, the drape stays
                log.warning("fabric-mode map: %s", e)
                return None
        return self._axes

    def field_values(self) -> np.ndarray | None:
        if self.mesh is None or self.x is None:
            return None
        axes = None
        if self.field in colormaps.FABRIC_FIELDS:
            axes = self.fabric_axes()
            if axes is None:
                return None
        return colormaps.field_values(
            self.field,
            self.mesh.X,
            self.x,
            self.mesh.tris,
            stretch_stiffness=self.fabric.stretch_stiffness,
            poisson_ratio=self.fabric.poisson_ratio,
            body_distance=self.body_distance,
            contact_stiffness=colormaps.solver_contact_stiffness(
                self.fabric.stretch_stiffness, self.fabric.poisson_ratio, self.contact_scale
            ),
            axes=axes,
        )

    def _draw(self) -> None:
        mesh, x = self.mesh, self.x
        if mesh is None or x is None:
            return
        values = self.field_values() if self.field != "none" else None
        xf = x.astype(np.float32)
        with self.server.atomic():
            if values is None:
                self.scale = None
                self.plain.vertices = xf
                self.plain.visible = True
                for h in self.bands:
                    h.visible = False
                return
            self.plain.visible = False
            self.scale = colormaps.auto_scale(self.field, values, self.n_bands)
            band = self.scale.band_of(values)
            colors = self.scale.band_colors()
            order = np.argsort(band, kind="stable")
            bounds = np.searchsorted(band[order], np.arange(self.n_bands + 1))
            for b, h in enumerate(self.bands):
                tri_idx = order[bounds[b] : bounds[b + 1]]
                if tri_idx.size == 0:
                    h.visible = False
                    self._band_tris[b] = None
                    continue
                t = mesh.tris[tri_idx]
                uniq, inv = np.unique(t, return_inverse=True)
                red, green, blue = (int(c) for c in colors[b])
                h.color = (red, green, blue)
                h.vertices = xf[uniq]
                prev = self._band_tris[b]
                if prev is None or prev.shape != tri_idx.shape or not np.array_equal(prev, tri_idx):
                    h.faces = inv.reshape(-1, 3).astype(np.uint32)
                    self._band_tris[b] = tri_idx
                h.visible = True

    def show_marker(self, mp: MaterialPoint | None) -> None:
        if mp is None or self.mesh is None or self.x is None:
            self.marker.visible = False
            return
        self.marker.position = tuple(mp.on(self.x, self.mesh.tris))
        self.marker.visible = True

    def show_body_marker(self, point) -> None:
        """The point picked on the body (a try-on drag's target), or none."""
        if point is None:
            self.body_marker.visible = False
            return
        self.body_marker.position = np.asarray(point, np.float64)
        self.body_marker.visible = True

    # -- interaction ----------------------------------------------------------------

    def _on_body_click(self, event) -> None:
        if self.on_body_click is not None and event.ray_origin is not None and event.ray_direction is not None:
            self.on_body_click(np.asarray(event.ray_origin, np.float64), np.asarray(event.ray_direction, np.float64))

    def _on_click(self, event) -> None:
        with self._lock:
            if self.mesh is None or self.x is None:
                return
            hit = ray_hit(self.x, self.mesh.tris, event.ray_origin, event.ray_direction)
        if hit is None:
            return
        mp = hit[0]
        self.show_marker(mp)
        if self.on_pick is not None:
            self.on_pick(mp)

    def _screen_px(self, client, pos01) -> tuple[float, float]:
        cam = client.camera
        return (float(pos01[0]) * cam.image_width, float(pos01[1]) * cam.image_height)

    async def _on_drag(self, event) -> None:
        # async: viser runs async callbacks in order on its event loop (sync ones
        # go to a thread pool and may reorder press/drag/release)
        with self._lock:
            if self.mesh is None or self.x is None:
                return
            phase = VISER_DRAG_PHASE[event.phase]
            if phase == "press":
                mp = closest_material_point(self.x, self.mesh.tris, event.start_position)
                try:
                    cam = CameraState.from_viser(event.client.camera)
                except Exception:
                    cam = None
                p0 = self._screen_px(event.client, event.start_screen_pos)
                self._tug = {"mp": mp, "vertex": mp.nearest_vertex(self.mesh.tris), "p0": p0, "cam": cam}
            tug = self._tug
            if tug is None:
                return
            p = self._screen_px(event.client, event.end_screen_pos)
            if phase == "release":
                self._tug = None
        self.show_marker(tug["mp"])
        if self.on_tug is not None:
            self.on_tug(phase, tug["mp"], tug["vertex"], tug["p0"], p, tug["cam"])

"""The flat pattern view: panels in the z = 0 plane, seen from above (+z,
looking down -z, +y up on screen), on its own viser server.

Drawn from the drafted pattern (couture.pattern), nothing recomputed here:
panel fills, outlines and holes, seam segments colour-matched pairwise, dart
legs (the segments couture.pattern names ``dart:<id>:left|right``), the mesh
(optional), draggable handles, one per editable element of the design
(sloper options, curve control points, darts, imported pieces' corners: see
:mod:`couture.ui.handles`)
with their names shown for the selected handle only, and the marker of the
material point picked in either view.

Panels that overlap in their own coordinates are laid out side by side for
display (a per-panel offset); every pointer delta is a difference and so is
unaffected, and picking subtracts the offset before the mesh lookup.
"""

from __future__ import annotations

import threading
from typing import Callable

import numpy as np
import viser

from couture.mesh import GarmentMesh
from couture.pattern.drafted import DraftedPattern, Panel, Segment
from couture.ui.geometry import MaterialPoint, locate_in_pattern
from couture.ui.handles import Handle, HandleSet
from couture.ui.state import VISER_DRAG_PHASE, Phase
from couture.ui.widgets import ClientFraming, fit_distance

SEAM_PALETTE = np.array(
    [
        (228, 26, 28),
        (55, 126, 184),
        (77, 175, 74),
        (152, 78, 163),
        (255, 127, 0),
        (166, 86, 40),
        (247, 129, 191),
        (0, 170, 170),
        (180, 180, 0),
        (90, 90, 90),
    ],
    np.uint8,
)
PANEL_FILL = (236, 228, 214)
OUTLINE = (40, 40, 40)
HANDLE_COLORS = {
    "param": (20, 90, 200),
    "cv": (20, 160, 120),
    "dart": (200, 0, 120),
    "hole": (200, 0, 120),
    "pt": (90, 60, 30),
}
HANDLE_ACTIVE = (240, 160, 0)
DART_COLOR = (200, 0, 120)
HANDLE_RADIUS = 0.012
"""[m]"""
CAMERA_FOV = float(np.deg2rad(40.0))
"""vertical field of view of the pattern view [rad]"""


def segment_indices(panel: Panel, seg_name: str) -> np.ndarray:
    """Indices of a segment's vertices in its polyline (outline or hole)."""
    seg = next(s for s in panel.segments if s.name == seg_name)
    k = len(polyline_of(panel, seg))
    n = (seg.stop - seg.start) % k
    return (seg.start + np.arange(n + 1)) % k


def polyline_of(panel: Panel, seg: Segment) -> np.ndarray:
    """The polyline a segment lies on: the outline, or its hole."""
    return panel.outline if seg.hole < 0 else panel.holes[seg.hole]


def segment_points(panel: Panel, seg_name: str) -> np.ndarray:
    """A segment's vertices [m], shape (k, 2)."""
    seg = next(s for s in panel.segments if s.name == seg_name)
    return polyline_of(panel, seg)[segment_indices(panel, seg_name)]


def is_dart_leg(seg_name: str) -> bool:
    return seg_name.startswith("dart:")


def layout_offsets(pattern: DraftedPattern, gap: float = 0.08) -> dict[str, np.ndarray]:
    """Display offsets [m] per panel: zero if no two panels' bounding boxes
    overlap, else the panels in a row left to right."""
    boxes = {p.name: (p.outline.min(axis=0), p.outline.max(axis=0)) for p in pattern.panels}
    names = list(boxes)
    overlap = any(
        np.all(boxes[a][0] < boxes[b][1]) and np.all(boxes[b][0] < boxes[a][1])
        for i, a in enumerate(names)
        for b in names[i + 1 :]
    )
    if not overlap:
        return {n: np.zeros(2) for n in names}
    out, cursor = {}, 0.0
    for n in names:
        lo, hi = boxes[n]
        out[n] = np.array([cursor - lo[0], -lo[1]])
        cursor += (hi[0] - lo[0]) + gap
    return out


def fit_camera(
    lo: np.ndarray, hi: np.ndarray, aspect: float
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Camera (position, look_at) [m] looking straight down (-z) at the box
    lo..hi [m] of the pattern plane, the box spanning 90 % of a canvas of this
    aspect (width / height) in its tighter direction; vertical field of view CAMERA_FOV."""
    c = 0.5 * (np.asarray(lo) + np.asarray(hi))
    dist = fit_distance(0.5 * float(hi[0] - lo[0]), 0.5 * float(hi[1] - lo[1]), CAMERA_FOV, aspect)
    return (float(c[0]), float(c[1]), max(dist, 0.3)), (float(c[0]), float(c[1]), 0.0)


class PatternView:
    """Owns the scene of the pattern viser server."""

    def __init__(self, server: viser.ViserServer):
        self.server = server
        self.pattern: DraftedPattern | None = None
        self.mesh: GarmentMesh | None = None
        self.offsets: dict[str, np.ndarray] = {}
        self.handles: list[Handle] = []
        self.handle_set: HandleSet = HandleSet([], {})
        self.selected: int | None = None
        """index of the selected handle (its name shows), None for none"""
        self.show_all_labels = False
        self.show_mesh_edges = False
        self.on_handle_drag: Callable[[Phase, Handle, np.ndarray], None] | None = None
        """cb(phase 'press'|'drag'|'release', handle, d): d is the edit's d for the
        pointer motion since press (Handle.element_delta)"""
        self.on_click: Callable[[np.ndarray, str | None], None] | None = None
        """cb(point in panel coordinates [m], panel name or None)"""
        self._lock = threading.RLock()
        self._drag: dict | None = None
        self._handle_node: viser.BatchedMeshHandle | None = None
        self._labels: list = []
        self._nodes: dict[str, object] = {}
        self._framed: tuple[np.ndarray, np.ndarray] | None = None
        """the pattern bounds (lo, hi) [m] the cameras were framed for"""
        server.scene.set_up_direction("+y")
        ic = server.initial_camera
        ic.fov = CAMERA_FOV
        ic.up = (0.0, 1.0, 0.0)
        ic.position, ic.look_at = self.fit_pattern(1.0)
        self.framing = ClientFraming(server, self.fit_pattern)
        self.marker = server.scene.add_icosphere(
            "/marker", radius=0.012, color=(230, 30, 30), visible=False, position=(0.0, 0.0, 0.004)
        )
        server.scene.on_click()(self._on_scene_click)

    # -- data in ----------------------------------------------------------------

    def set_pattern(self, pattern: DraftedPattern) -> None:
        with self._lock:
            self.pattern = pattern
            self.offsets = layout_offsets(pattern)
            self.handles, self.handle_set, self.selected = [], HandleSet([], {}), None
            self._draw_all()
            self._frame_if_changed()

    def set_handles(self, handle_set: HandleSet) -> None:
        """The design's editable elements (planned for the pattern on screen)."""
        with self._lock:
            if self._drag is not None:
                return  # keep the gesture's handles until it ends
            self.handle_set = handle_set
            self.handles = list(handle_set.handles)
            self.selected = None
            self._draw_handles()

    def set_mesh(self, mesh: GarmentMesh) -> None:
        with self._lock:
            if (
                self.mesh is not None
                and self.mesh.tris.shape == mesh.tris.shape
                and np.array_equal(self.mesh.tris, mesh.tris)
                and np.array_equal(self.mesh.X, mesh.X)
            ):
                self.mesh = mesh
                return
            self.mesh = mesh
            self._draw_mesh()

    def restore(self) -> None:
        """Outlines and handles back at rest (a drag that moved nothing, a rejected edit)."""
        with self._lock:
            if self.pattern is None:
                return
            with self.server.atomic():
                for p in self.pattern.panels:
                    self._draw_panel(p, p.outline)
                if self._handle_node is not None:
                    self._handle_node.batched_positions = self.handle_positions().astype(np.float32)

    # -- camera -------------------------------------------------------------------

    def fit_pattern(self, aspect: float) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Camera (position, look_at) [m] of a canvas of this aspect showing the whole pattern."""
        return fit_camera(*self.bounds(), aspect)

    def _frame_if_changed(self) -> None:
        """Frame the cameras to the pattern's bounds when they changed: every
        piece stays in view whatever an edit did to the pattern's size."""
        lo, hi = self.bounds()
        if self._framed is not None and np.array_equal(lo, self._framed[0]) and np.array_equal(hi, self._framed[1]):
            return
        self._framed = (lo, hi)
        ic = self.server.initial_camera
        ic.position, ic.look_at = self.fit_pattern(1.0)
        self.framing.reframe()

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        if self.pattern is None:
            return np.array([-0.5, -0.5]), np.array([0.5, 0.5])
        pts = np.concatenate([p.outline + self.offsets[p.name] for p in self.pattern.panels])
        return pts.min(axis=0), pts.max(axis=0)

    # -- drawing ------------------------------------------------------------------

    def display(self, panel: str, pts: np.ndarray) -> np.ndarray:
        return np.asarray(pts) + self.offsets.get(panel, 0.0)

    def _add(self, name: str, node: object) -> None:
        self._nodes[name] = node

    def _draw_all(self) -> None:
        pat = self.pattern
        assert pat is not None, "_draw_all without a pattern"
        sc = self.server.scene
        with self.server.atomic():
            for name in list(self._nodes):
                sc.remove_by_name(name)
            self._nodes.clear()
            for p in pat.panels:
                self._draw_panel(p, p.outline)
                c = self.display(p.name, p.outline).mean(axis=0)
                self._add(
                    f"/panels/{p.name}/label",
                    sc.add_label(
                        f"/panels/{p.name}/label",
                        p.name,
                        position=(float(c[0]), float(c[1]), 0.002),
                        anchor="center-center",
                        font_screen_scale=0.8,
                    ),
                )
            self._draw_seams()
            self._draw_handles()

    def _draw_panel(self, p: Panel, outline: np.ndarray) -> None:
        """Fill, outline with holes, and dart legs of a panel whose outline is ``outline``."""
        sc = self.server.scene
        P = self.display(p.name, outline)
        holes = [self.display(p.name, h) for h in p.holes]
        loops = [P, *holes]
        segs = np.concatenate([np.stack([L, np.roll(L, -1, axis=0)], axis=1) for L in loops])
        name = f"/panels/{p.name}/outline"
        self._add(name, sc.add_line_segments(name, _lift(segs, 0.0), OUTLINE, thickness=2.0, thickness_units="screen"))
        fill = _triangulate(P, holes)
        if fill is not None:
            v, f = fill
            name = f"/panels/{p.name}/fill"
            self._add(
                name,
                sc.add_mesh_simple(
                    name,
                    np.column_stack([v, np.full(len(v), -0.002)]).astype(np.float32),
                    f.astype(np.uint32),
                    color=PANEL_FILL,
                    side="double",
                    cast_shadow=False,
                    receive_shadow=False,
                ),
            )
        legs = []
        for seg in p.segments:
            if is_dart_leg(seg.name):
                poly = outline if seg.hole < 0 else p.holes[seg.hole]
                Q = self.display(p.name, poly[segment_indices(p, seg.name)])
                legs.append(np.stack([Q[:-1], Q[1:]], axis=1))
        if legs:
            name = f"/panels/{p.name}/darts"
            self._add(
                name,
                sc.add_line_segments(
                    name, _lift(np.concatenate(legs), 0.001), DART_COLOR, thickness=3.0, thickness_units="screen"
                ),
            )

    def _draw_seams(self) -> None:
        """Seams between panel edges, each pair in its own colour (a dart's
        two legs are its seam: drawn as the dart)."""
        pat = self.pattern
        assert pat is not None, "_draw_seams without a pattern"
        k = 0
        for s in pat.seams:
            if is_dart_leg(s.a_segment) and is_dart_leg(s.b_segment):
                continue
            red, green, blue = (int(c) for c in SEAM_PALETTE[k % len(SEAM_PALETTE)])
            col = (red, green, blue)
            for side, (pn, sn) in enumerate(((s.a_panel, s.a_segment), (s.b_panel, s.b_segment))):
                try:
                    P = self.display(pn, segment_points(pat.panel(pn), sn))
                except (KeyError, StopIteration):
                    continue
                name = f"/seams/{k}/{side}"
                self._add(
                    name,
                    self.server.scene.add_line_segments(
                        name,
                        _lift(np.stack([P[:-1], P[1:]], axis=1), 0.001),
                        col,
                        thickness=5.0,
                        thickness_units="screen",
                    ),
                )
            k += 1

    def handle_positions(self) -> np.ndarray:
        """Display positions of the handles, shape (h, 3) (z slightly above the panels)."""
        pos = []
        for h in self.handles:
            assert self.pattern is not None, "handles without a pattern"
            p = self.pattern.panel(h.panel)
            pos.append(np.append(self.display(h.panel, h.rest_position(p)), 0.003))
        return np.array(pos).reshape(-1, 3)

    def _draw_handles(self) -> None:
        import trimesh

        sc = self.server.scene
        for name in [n for n in self._nodes if n.startswith("/handles")]:
            sc.remove_by_name(name)
            del self._nodes[name]
        self._handle_node, self._labels = None, []
        if not self.handles or self.pattern is None:
            return
        ico = trimesh.creation.icosphere(subdivisions=1, radius=HANDLE_RADIUS)
        pos = self.handle_positions()
        cols = np.array([HANDLE_COLORS.get(h.kind, HANDLE_ACTIVE) for h in self.handles], np.uint8)
        for i, (h, p) in enumerate(zip(self.handles, pos, strict=True)):
            name = f"/handles_labels/{i}"
            self._labels.append(
                sc.add_label(
                    name,
                    h.label,
                    position=(float(p[0]) + 0.015, float(p[1]), 0.004),
                    anchor="center-left",
                    font_screen_scale=0.8,
                    visible=self._label_visible(i),
                )
            )
            self._add(name, self._labels[-1])
        self._handle_node = sc.add_batched_meshes_simple(
            "/handles",
            np.asarray(ico.vertices, np.float32),
            np.asarray(ico.faces, np.uint32),
            batched_wxyzs=np.tile([1.0, 0.0, 0.0, 0.0], (len(pos), 1)),
            batched_positions=pos.astype(np.float32),
            batched_colors=cols,
            cast_shadow=False,
            receive_shadow=False,
            lod="off",
        )
        self._add("/handles", self._handle_node)
        self._handle_node.on_drag(self._on_handle_drag)
        self._handle_node.on_click(self._on_handle_click)

    # -- handle names: the selected one, or all on request ------------------------

    def _label_visible(self, i: int) -> bool:
        return self.show_all_labels or i == self.selected

    def _show_labels(self) -> None:
        for i, node in enumerate(self._labels):
            node.visible = self._label_visible(i)

    def select_handle(self, index: int | None) -> None:
        """Select a handle (its name shows); None clears the selection."""
        with self._lock:
            self.selected = index if index is not None and 0 <= index < len(self.handles) else None
            self._show_labels()

    def set_show_all_labels(self, on: bool) -> None:
        with self._lock:
            self.show_all_labels = on
            self._show_labels()

    def visible_labels(self) -> list[str]:
        """Names of the handles whose label is shown."""
        return [h.label for i, h in enumerate(self.handles) if i < len(self._labels) and self._labels[i].visible]

    def handle_near(self, p_display: np.ndarray, radius: float = 2 * HANDLE_RADIUS) -> int | None:
        """The handle within ``radius`` [m] of a display point, nearest first."""
        if not self.handles or self.pattern is None:
            return None
        d = np.linalg.norm(self.handle_positions()[:, :2] - np.asarray(p_display)[None, :2], axis=1)
        i = int(np.argmin(d))
        return i if d[i] <= radius else None

    # -- mesh, markers, picking -----------------------------------------------------

    def _draw_mesh(self) -> None:
        sc = self.server.scene
        m = self.mesh
        if m is None or not self.show_mesh_edges:
            sc.remove_by_name("/mesh")
            return
        e = np.sort(np.concatenate([m.tris[:, [0, 1]], m.tris[:, [1, 2]], m.tris[:, [2, 0]]]), axis=1)
        e = np.unique(e, axis=0)
        XY = self.mesh_display_X()
        sc.add_line_segments(
            "/mesh",
            _lift(np.stack([XY[e[:, 0]], XY[e[:, 1]]], axis=1), -0.001),
            (150, 150, 170),
            thickness=1.0,
            thickness_units="screen",
        )

    def set_show_mesh(self, on: bool) -> None:
        with self._lock:
            self.show_mesh_edges = on
            self._draw_mesh()

    def mesh_vertex_panel(self) -> np.ndarray:
        m = self.mesh
        assert m is not None, "no mesh yet"
        vp = np.zeros(m.n_vertices, np.int32)
        vp[m.tris.ravel()] = np.repeat(m.tri_panel, 3)
        return vp

    def mesh_display_X(self) -> np.ndarray:
        """Mesh rest positions with each panel's display offset added, shape (n, 2)."""
        m = self.mesh
        assert m is not None, "no mesh yet"
        X = m.X.copy()
        if self.offsets and m.panel_names:
            vp = self.mesh_vertex_panel()
            for i, name in enumerate(m.panel_names):
                if name in self.offsets:
                    X[vp == i] += self.offsets[name]
        return X

    def show_marker(self, mp: MaterialPoint | None) -> None:
        if mp is None or self.mesh is None:
            self.marker.visible = False
            return
        p = mp.on(self.mesh_display_X(), self.mesh.tris)
        self.marker.position = (float(p[0]), float(p[1]), 0.004)
        self.marker.visible = True

    def locate(self, p_display: np.ndarray) -> MaterialPoint | None:
        """Material point under a display-space point of the pattern view."""
        if self.mesh is None:
            return None
        panel = self.panel_at(p_display)
        mask = None
        if panel is not None and panel in self.mesh.panel_names:
            mask = self.mesh.tri_panel == self.mesh.panel_names.index(panel)
        return locate_in_pattern(self.mesh_display_X(), self.mesh.tris, p_display, mask)

    def panel_at(self, p_display: np.ndarray) -> str | None:
        if self.pattern is None:
            return None
        for p in self.pattern.panels:
            if _inside(self.display(p.name, p.outline), p_display):
                return p.name
        return None

    def nearest_segment(self, p_display: np.ndarray) -> tuple[str, str, float] | None:
        """(panel, segment, t along it in [0, 1]) of the boundary piece nearest a point."""
        if self.pattern is None:
            return None
        best = None
        for p in self.pattern.panels:
            for s in p.segments:
                P = self.display(p.name, segment_points(p, s.name))
                a, b = P[:-1], P[1:]
                ab = b - a
                t = np.clip(np.einsum("ij,ij->i", p_display - a, ab) / np.maximum((ab * ab).sum(1), 1e-18), 0, 1)
                d = np.linalg.norm(a + t[:, None] * ab - p_display, axis=1)
                j = int(np.argmin(d))
                L = np.linalg.norm(ab, axis=1)
                s_at = (L[:j].sum() + t[j] * L[j]) / max(L.sum(), 1e-12)
                if best is None or d[j] < best[0]:
                    best = (float(d[j]), p.name, s.name, float(s_at))
        return None if best is None else best[1:]

    # -- interaction ----------------------------------------------------------------

    def _on_scene_click(self, event) -> None:
        o, d = np.asarray(event.ray_origin), np.asarray(event.ray_direction)
        if abs(d[2]) < 1e-9:
            return
        p = (o - o[2] / d[2] * d)[:2]
        self.select_handle(self.handle_near(p))
        if self.on_click is not None:
            self.on_click(p, self.panel_at(p))

    def _on_handle_click(self, event) -> None:
        i = event.instance_index
        if i is None:
            o, d = np.asarray(event.ray_origin), np.asarray(event.ray_direction)
            i = self.handle_near((o - o[2] / d[2] * d)[:2]) if abs(d[2]) > 1e-9 else None
        self.select_handle(i)

    async def _on_handle_drag(self, event) -> None:
        # async: keeps press/drag/release in order (see drape_view)
        with self._lock:
            if event.instance_index is None or event.instance_index >= len(self.handles):
                return
            phase = VISER_DRAG_PHASE[event.phase]
            if phase == "press":
                h = self.handles[event.instance_index]
                self._drag = {
                    "handle": h,
                    "grab": np.asarray(event.end_position[:2], np.float64),
                    "index": event.instance_index,
                }
                self.select_handle(event.instance_index)
            drag = self._drag
            if drag is None:
                return
            d = drag["handle"].element_delta(np.asarray(event.end_position[:2], np.float64) - drag["grab"])
            self.preview(drag["handle"], d, drag["index"])
            if phase == "release":
                self._drag = None
        if self.on_handle_drag is not None:
            self.on_handle_drag(phase, drag["handle"], d)

    def handle_motion(self, handle: Handle, dd: np.ndarray) -> np.ndarray:
        """How far a handle's point moves for the edit d = dd, to first order [m], shape (2,)."""
        pj = self.handle_set.jacobians.get(handle.element, {}).get(handle.panel)
        if pj is None:
            return np.zeros(2)
        jac = pj.outline if handle.hole < 0 else pj.holes[handle.hole]
        return jac[handle.vertex] @ np.asarray(dd, np.float64)

    def preview_element(self, element: str, dd: np.ndarray) -> None:
        """Show an edit of ``element`` made elsewhere (its handle, if it has one)."""
        i = next((i for i, h in enumerate(self.handles) if h.element == element), None)
        if i is not None:
            self.preview(self.handles[i], dd, i)

    def preview(self, handle: Handle, dd: np.ndarray, index: int | None = None) -> None:
        """Show an edit before the new design is drafted: every outline moves
        by its Jacobian (X + J dd: a sloper option moves every gore), the
        handle with its point."""
        if self.pattern is None:
            return
        moved = self.handle_set.moved_outlines(self.pattern, handle.element, dd)
        with self.server.atomic():
            for p in self.pattern.panels:
                if p.name in moved and moved[p.name] is not p.outline:
                    self._draw_panel(p, moved[p.name])
            if self._handle_node is not None and index is not None and index < len(self.handles):
                pos = self.handle_positions()
                pos[index, :2] += self.handle_motion(handle, dd)
                self._handle_node.batched_positions = pos.astype(np.float32)
                if index < len(self._labels):
                    self._labels[index].position = (float(pos[index, 0]) + 0.015, float(pos[index, 1]), 0.004)


def _lift(segs: np.ndarray, z: float) -> np.ndarray:
    """2D line segments (k, 2, 2) at height z as float32 (k, 2, 3)."""
    return np.concatenate([segs, np.full(segs.shape[:2] + (1,), z)], axis=-1).astype(np.float32)


def _inside(poly: np.ndarray, p: np.ndarray) -> bool:
    x, y = p
    xs, ys = poly[:, 0], poly[:, 1]
    xj, yj = np.roll(xs, 1), np.roll(ys, 1)
    cross = ((ys > y) != (yj > y)) & (x < (xj - xs) * (y - ys) / np.where(yj - ys == 0, 1e-18, yj - ys) + xs)
    return bool(np.count_nonzero(cross) % 2)


def _triangulate(P: np.ndarray, holes: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray] | None:
    """A fill triangulation of a polygon with holes (constrained Delaunay)."""
    import triangle as tr

    loops = [L for L in (P, *holes) if len(L) >= 3]
    if not loops or loops[0] is not P:
        return None
    starts = np.cumsum([0] + [len(L) for L in loops[:-1]])
    segs = np.concatenate(
        [
            s + np.column_stack([np.arange(len(L)), (np.arange(len(L)) + 1) % len(L)])
            for s, L in zip(starts, loops, strict=True)
        ]
    )
    data = {"vertices": np.concatenate(loops), "segments": segs}
    if len(loops) > 1:
        data["holes"] = np.array([_point_inside(L) for L in loops[1:]])
    try:
        out = tr.triangulate(data, "pQ")
    except Exception:
        return None
    if "triangles" not in out:
        return None
    return out["vertices"], out["triangles"]


def _point_inside(poly: np.ndarray) -> np.ndarray:
    """A point inside a simple polygon: the centroid if inside, else the
    midpoint of the first chord across it found from a vertex's neighbours."""
    c = poly.mean(axis=0)
    if _inside(poly, c):
        return c
    for i in range(len(poly)):
        q = 0.5 * (poly[i - 1] + poly[(i + 1) % len(poly)])
        m = 0.5 * (poly[i] + q)
        if _inside(poly, m):
            return m
    return c

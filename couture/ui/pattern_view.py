"""The flat pattern view: panels in the z = 0 plane, seen from above (+z,
looking down -z, +y up on screen), on its own viser server.

Drawn: panel fills and outlines, seam segments colour-matched pairwise, dart
strokes, mirrored outlines of panels marked symmetric, the mesh (optional),
draggable handles, one per editable element of the design (sloper options,
curve control points, darts: see :mod:`couture.ui.handles`), and the marker
of the material point picked in either view.

Panels that overlap in their own coordinates are laid out side by side for
display (a per-panel offset); every pointer delta is a difference and so is
unaffected, and picking subtracts the offset before the mesh lookup.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Callable

import numpy as np
import viser

from couture.mesh import GarmentMesh
from couture.pattern.drafted import DraftedPattern, Panel
from couture.ui.geometry import MaterialPoint, locate_in_pattern
from couture.ui.handles import Handle, HandleSet

SEAM_PALETTE = np.array([
    (228, 26, 28), (55, 126, 184), (77, 175, 74), (152, 78, 163), (255, 127, 0),
    (166, 86, 40), (247, 129, 191), (0, 170, 170), (180, 180, 0), (90, 90, 90),
], np.uint8)
PANEL_FILL = (236, 228, 214)
OUTLINE = (40, 40, 40)
HANDLE_COLORS = {"param": (20, 90, 200), "cv": (20, 160, 120), "dart": (200, 0, 120), "hole": (200, 0, 120)}
HANDLE_ACTIVE = (240, 160, 0)


def segment_indices(panel: Panel, seg_name: str) -> np.ndarray:
    seg = next(s for s in panel.segments if s.name == seg_name)
    k = len(panel.outline)
    n = (seg.stop - seg.start) % k
    return (seg.start + np.arange(n + 1)) % k


def mirror_about(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Reflect 2D points across the line through a and b."""
    d = (b - a) / max(np.linalg.norm(b - a), 1e-12)
    r = points - a
    return a + 2 * np.outer(r @ d, d) - r


def layout_offsets(pattern: DraftedPattern, gap: float = 0.08) -> dict[str, np.ndarray]:
    """Display offsets [m] per panel: zero if no two panels' bounding boxes
    overlap, else the panels in a row left to right."""
    boxes = {p.name: (p.outline.min(axis=0), p.outline.max(axis=0)) for p in pattern.panels}
    names = list(boxes)
    overlap = any(
        np.all(boxes[a][0] < boxes[b][1]) and np.all(boxes[b][0] < boxes[a][1])
        for i, a in enumerate(names) for b in names[i + 1:]
    )
    if not overlap:
        return {n: np.zeros(2) for n in names}
    out, cursor = {}, 0.0
    for n in names:
        lo, hi = boxes[n]
        out[n] = np.array([cursor - lo[0], -lo[1]])
        cursor += (hi[0] - lo[0]) + gap
    return out


class PatternView:
    """Owns the scene of the pattern viser server."""

    def __init__(self, server: viser.ViserServer):
        self.server = server
        self.pattern: DraftedPattern | None = None
        self.mesh: GarmentMesh | None = None
        self.offsets: dict[str, np.ndarray] = {}
        self.handles: list[Handle] = []
        self.handle_set: HandleSet = HandleSet([], {})
        self.symmetric: dict[str, str] = {}
        """panel -> segment it is mirrored about (symmetry strokes)"""
        self.darts: list[dict] = []
        self.show_mesh_edges = False
        self.on_handle_drag: Callable[[str, Handle, np.ndarray], None] | None = None
        """cb(phase 'press'|'drag'|'release', handle, d): d is the edit's d for the
        pointer motion since press (Handle.element_delta)"""
        self.on_click: Callable[[np.ndarray, str | None], None] | None = None
        """cb(point in panel coordinates [m], panel name or None)"""
        self._lock = threading.RLock()
        self._drag: dict | None = None
        self._handle_node = None
        self._line_nodes: dict[str, object] = {}
        server.scene.set_up_direction("+y")
        server.initial_camera.position = (0.0, 0.0, 2.5)
        server.initial_camera.look_at = (0.0, 0.0, 0.0)
        server.initial_camera.up = (0.0, 1.0, 0.0)
        server.initial_camera.fov = np.deg2rad(40.0)
        self.marker = server.scene.add_icosphere("/marker", radius=0.012, color=(230, 30, 30), visible=False,
                                                 position=(0.0, 0.0, 0.004))
        server.scene.on_click()(self._on_scene_click)

    # -- data in ----------------------------------------------------------------

    def set_pattern(self, pattern: DraftedPattern, strokes: list | None = None) -> None:
        with self._lock:
            self.pattern = pattern
            self.offsets = layout_offsets(pattern)
            self.handles, self.handle_set = [], HandleSet([], {})
            self.symmetric, self.darts = {}, []
            for st in strokes or []:
                if st.kind == "symmetry" and st.panel:
                    self.symmetric[st.panel] = str(st.params.get("axis", ""))
                elif st.kind == "dart":
                    self.darts.append({"panel": st.panel, **st.params})
            self._draw_all()
            self.frame_camera()

    def set_handles(self, handle_set: HandleSet) -> None:
        """The design's editable elements (planned for the pattern on screen)."""
        with self._lock:
            if self._drag is not None:
                return  # keep the gesture's handles until it ends
            self.handle_set = handle_set
            self.handles = list(handle_set.handles)
            self._draw_handles()

    def set_mesh(self, mesh: GarmentMesh) -> None:
        with self._lock:
            self.mesh = mesh
            self._draw_mesh()

    def frame_camera(self) -> None:
        """Centre every connected client's camera on the laid-out pattern."""
        lo, hi = self.bounds()
        c = 0.5 * (lo + hi)
        span = float(max(hi[0] - lo[0], hi[1] - lo[1], 0.2))
        dist = 0.6 * span / np.tan(np.deg2rad(20.0)) + 0.2
        ic = self.server.initial_camera
        ic.look_at = (float(c[0]), float(c[1]), 0.0)
        ic.position = (float(c[0]), float(c[1]), dist)
        for client in self.server.get_clients().values():
            with client.atomic():
                client.camera.position = ic.position
                client.camera.look_at = ic.look_at
                client.camera.up_direction = (0.0, 1.0, 0.0)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        if self.pattern is None:
            return np.array([-0.5, -0.5]), np.array([0.5, 0.5])
        pts = np.concatenate([p.outline + self.offsets[p.name] for p in self.pattern.panels])
        return pts.min(axis=0), pts.max(axis=0)

    # -- drawing ------------------------------------------------------------------

    def display(self, panel: str, pts: np.ndarray) -> np.ndarray:
        return np.asarray(pts) + self.offsets.get(panel, 0.0)

    def _draw_all(self) -> None:
        pat = self.pattern
        sc = self.server.scene
        with self.server.atomic():
            for name in list(self._line_nodes):
                sc.remove_by_name(name)
            self._line_nodes.clear()
            for p in pat.panels:
                self._draw_panel(p, p.outline)
                c = self.display(p.name, p.outline).mean(axis=0)
                self._line_nodes[f"/panels/{p.name}/label"] = sc.add_label(
                    f"/panels/{p.name}/label", p.name, position=(float(c[0]), float(c[1]), 0.002),
                    anchor="center-center", font_screen_scale=0.8)
            self._draw_seams()
            self._draw_darts()
            self._draw_handles()

    def _draw_panel(self, p: Panel, outline: np.ndarray) -> None:
        sc = self.server.scene
        P = self.display(p.name, outline)
        closed = np.vstack([P, P[:1]])
        segs = np.stack([closed[:-1], closed[1:]], axis=1)
        pts3 = np.concatenate([segs, np.zeros(segs.shape[:2] + (1,))], axis=-1)
        name = f"/panels/{p.name}/outline"
        self._line_nodes[name] = sc.add_line_segments(name, pts3.astype(np.float32), OUTLINE, thickness=2.0,
                                                      thickness_units="screen")
        fill = _fan_or_triangulate(P)
        if fill is not None:
            v, f = fill
            name = f"/panels/{p.name}/fill"
            self._line_nodes[name] = sc.add_mesh_simple(
                name, np.column_stack([v, np.full(len(v), -0.002)]).astype(np.float32), f.astype(np.uint32),
                color=PANEL_FILL, side="double", cast_shadow=False, receive_shadow=False)
        name = f"/panels/{p.name}/mirror"
        seg_name = self.symmetric.get(p.name)
        # drawn only while the drafted panel still has its axis segment (i.e.
        # before couture.pattern has mirrored it)
        if seg_name and any(s.name == seg_name for s in p.segments):
            idx = segment_indices(p, seg_name)
            M = mirror_about(P, P[idx[0]], P[idx[-1]])
            closed = np.vstack([M, M[:1]])
            segs = np.stack([closed[:-1], closed[1:]], axis=1)[::2]  # every other piece: dashed
            pts3 = np.concatenate([segs, np.zeros(segs.shape[:2] + (1,))], axis=-1)
            self._line_nodes[name] = sc.add_line_segments(name, pts3.astype(np.float32), (120, 120, 120),
                                                          thickness=1.5, thickness_units="screen")

    def _draw_seams(self) -> None:
        pat = self.pattern
        for i, s in enumerate(pat.seams):
            col = tuple(int(c) for c in SEAM_PALETTE[i % len(SEAM_PALETTE)])
            for side, (pn, sn) in enumerate(((s.a_panel, s.a_segment), (s.b_panel, s.b_segment))):
                try:
                    panel = pat.panel(pn)
                    idx = segment_indices(panel, sn)
                except (KeyError, StopIteration):
                    continue
                P = self.display(pn, panel.outline[idx])
                segs = np.stack([P[:-1], P[1:]], axis=1)
                pts3 = np.concatenate([segs, np.full(segs.shape[:2] + (1,), 0.001)], axis=-1)
                name = f"/seams/{i}/{side}"
                self._line_nodes[name] = self.server.scene.add_line_segments(
                    name, pts3.astype(np.float32), col, thickness=5.0, thickness_units="screen")

    def _draw_darts(self) -> None:
        for i, d in enumerate(self.darts):
            try:
                panel = self.pattern.panel(d["panel"])
                if "segment" not in d or not any(s.name == d["segment"] for s in panel.segments):
                    continue
                idx = segment_indices(panel, str(d["segment"]))
            except (KeyError, StopIteration):
                continue
            P = panel.outline[idx]
            t = float(d.get("position", 0.5))
            s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
            at = t * s[-1]
            j = int(np.clip(np.searchsorted(s, at) - 1, 0, len(P) - 2))
            f = (at - s[j]) / max(s[j + 1] - s[j], 1e-12)
            c = P[j] * (1 - f) + P[j + 1] * f
            tan = (P[j + 1] - P[j]) / max(np.linalg.norm(P[j + 1] - P[j]), 1e-12)
            inward = np.array([-tan[1], tan[0]])  # outline is counter-clockwise: left is inside
            half, depth = 0.5 * float(d.get("width", 0.02)), float(d.get("length", 0.08))
            a, b, apex = c - half * tan, c + half * tan, c + depth * inward
            pts = self.display(d["panel"], np.array([a, apex, apex, b]))
            pts3 = np.column_stack([pts, np.full(4, 0.001)]).reshape(2, 2, 3)
            name = f"/darts/{i}"
            self._line_nodes[name] = self.server.scene.add_line_segments(
                name, pts3.astype(np.float32), (200, 0, 120), thickness=3.0, thickness_units="screen")

    def handle_positions(self) -> np.ndarray:
        """Display positions of the handles, shape (h, 3) (z slightly above the panels)."""
        pos = []
        for h in self.handles:
            p = self.pattern.panel(h.panel)
            pos.append(np.append(self.display(h.panel, h.rest_position(p)), 0.003))
        return np.array(pos).reshape(-1, 3)

    def _draw_handles(self) -> None:
        import trimesh

        sc = self.server.scene
        for name in [n for n in self._line_nodes if n.startswith("/handles")]:
            sc.remove_by_name(name)
            del self._line_nodes[name]
        self._handle_node = None
        if not self.handles or self.pattern is None:
            return
        ico = trimesh.creation.icosphere(subdivisions=1, radius=0.012)
        pos = self.handle_positions()
        cols = np.array([HANDLE_COLORS.get(h.kind, HANDLE_ACTIVE) for h in self.handles], np.uint8)
        for i, (h, p) in enumerate(zip(self.handles, pos)):
            name = f"/handles_labels/{i}"
            self._line_nodes[name] = sc.add_label(name, h.label, position=(float(p[0]) + 0.015, float(p[1]), 0.004),
                                                  anchor="center-left", font_screen_scale=0.6)
        name = "/handles"
        self._handle_node = self.server.scene.add_batched_meshes_simple(
            name, np.asarray(ico.vertices, np.float32), np.asarray(ico.faces, np.uint32),
            batched_wxyzs=np.tile([1.0, 0.0, 0.0, 0.0], (len(pos), 1)), batched_positions=pos.astype(np.float32),
            batched_colors=cols, cast_shadow=False, receive_shadow=False, lod="off")
        self._line_nodes[name] = self._handle_node
        self._handle_colors = cols
        self._handle_node.on_drag(self._on_handle_drag)

    def _draw_mesh(self) -> None:
        sc = self.server.scene
        m = self.mesh
        if m is None or not self.show_mesh_edges:
            sc.remove_by_name("/mesh")
            return
        e = np.sort(np.concatenate([m.tris[:, [0, 1]], m.tris[:, [1, 2]], m.tris[:, [2, 0]]]), axis=1)
        e = np.unique(e, axis=0)
        XY = self.mesh_display_X()
        segs = np.stack([XY[e[:, 0]], XY[e[:, 1]]], axis=1)
        pts3 = np.concatenate([segs, np.full(segs.shape[:2] + (1,), -0.001)], axis=-1)
        sc.add_line_segments("/mesh", pts3.astype(np.float32), (150, 150, 170), thickness=1.0,
                             thickness_units="screen")

    def set_show_mesh(self, on: bool) -> None:
        with self._lock:
            self.show_mesh_edges = on
            self._draw_mesh()

    def mesh_vertex_panel(self) -> np.ndarray:
        m = self.mesh
        vp = np.zeros(m.n_vertices, np.int32)
        vp[m.tris.ravel()] = np.repeat(m.tri_panel, 3)
        return vp

    def mesh_display_X(self) -> np.ndarray:
        """Mesh rest positions with each panel's display offset added, shape (n, 2)."""
        m = self.mesh
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
        best = None
        for p in self.pattern.panels:
            for s in p.segments:
                P = self.display(p.name, p.outline[segment_indices(p, s.name)])
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
        t = -o[2] / d[2]
        p = (o + t * d)[:2]
        if self.on_click is not None:
            self.on_click(p, self.panel_at(p))

    async def _on_handle_drag(self, event) -> None:
        # async: keeps press/drag/release in order (see drape_view)
        with self._lock:
            if event.instance_index is None or event.instance_index >= len(self.handles):
                return
            phase = {"start": "press", "update": "drag", "end": "release"}[event.phase]
            if phase == "press":
                h = self.handles[event.instance_index]
                self._drag = {"handle": h, "p0": self.handle_positions()[event.instance_index][:2].copy(),
                              "grab": np.asarray(event.end_position[:2], np.float64),
                              "index": event.instance_index}
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


def _inside(poly: np.ndarray, p: np.ndarray) -> bool:
    x, y = p
    xs, ys = poly[:, 0], poly[:, 1]
    xj, yj = np.roll(xs, 1), np.roll(ys, 1)
    cross = ((ys > y) != (yj > y)) & (x < (xj - xs) * (y - ys) / np.where(yj - ys == 0, 1e-18, yj - ys) + xs)
    return bool(np.count_nonzero(cross) % 2)


def _fan_or_triangulate(P: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """A fill triangulation of a simple polygon (constrained Delaunay)."""
    import triangle as tr

    k = len(P)
    if k < 3:
        return None
    segs = np.column_stack([np.arange(k), (np.arange(k) + 1) % k])
    try:
        out = tr.triangulate({"vertices": P, "segments": segs}, "pQ")
    except Exception:
        return None
    if "triangles" not in out:
        return None
    return out["vertices"], out["triangles"]

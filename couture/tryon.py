"""Try-on manipulation (Meng et al. 2010 §6): move, rotate, fix and drag
pattern pieces around the body, and sequential sewing.

Pure functions on a placed garment (no bus code, no solver: the solver node
applies them through :class:`TryOn`, ``couture/tryon/v1`` messages carry them,
and :func:`couture.solvers.service.solve_tryon` solves a try-on state):

* :func:`move` translates a panel, :func:`rotate` turns it rigidly about an
  axis through its centroid (or any point);
* :func:`drag` slides a panel along the body (Meng §6 "Drag"): the rigid
  motion (a turn about the body's vertical axis and a rise along it) is cut
  into steps of at most ``step`` metres of travel; after each step every
  vertex of the panel that is nearer the body than the contact offset is
  pushed out along the distance field's gradient until phi >= offset. The
  panel thus wraps around the body and never enters it (it may stretch a
  little where it is pushed out; the next solve relaxes that). With a
  ``guide`` (the body's ellipsoid proxy, couture.cloth.proxy, Meng §4) the
  steps are pushed out of the guide instead, a fast bound of the body, and
  the end once more out of the body itself;
* :func:`TryOn.fix` pins a panel where it is (Meng §6 "Fix": its vertices
  keep their positions in the solve);
* sequential sewing (Meng §6 "Complex sewing and inter-stage adjustment"):
  the mesh's seam springs are grouped into seams (:func:`seam_groups`); a
  :class:`TryOn` holds which seams are sewn and builds the model's mesh with
  only those springs (:meth:`TryOn.model_mesh`); each ``sew`` activates one
  more seam and the caller solves to equilibrium from the current state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from couture.mesh import GarmentMesh

UP = np.array([0.0, 1.0, 0.0])
TORSO_AXIS_POINT = np.array([0.0, 0.0, 0.04])
"""a point on the mannequin's vertical torso axis (x = 0, z = TORSO_AXIS_Z)"""
PUSH_ITERS = 30
"""most projection sweeps of :func:`push_out` per drag step"""

Op = Literal["move", "rotate", "drag", "fix", "unfix", "sew", "unsew"]
OPS: tuple[str, ...] = ("move", "rotate", "drag", "fix", "unfix", "sew", "unsew")


class TryOnError(ValueError):
    """A try-on operation that cannot apply (the text names the problem)."""


# ----------------------------------------------------------------------
# panels
# ----------------------------------------------------------------------


def panel_index(mesh: GarmentMesh, panel: str | int) -> int:
    """Index of a panel given by name or index; TryOnError if there is none."""
    n = max(len(mesh.panel_names), int(mesh.tri_panel.max()) + 1 if len(mesh.tri_panel) else 0)
    if isinstance(panel, str):
        if panel not in mesh.panel_names:
            raise TryOnError(f"no panel {panel!r}; panels are {mesh.panel_names}")
        return mesh.panel_names.index(panel)
    p = int(panel)
    if not 0 <= p < n:
        raise TryOnError(f"panel index {p} outside [0, {n})")
    return p


def panel_vertices(mesh: GarmentMesh, panel: str | int) -> np.ndarray:
    """Vertex indices of a panel (those of its triangles), sorted, int32."""
    p = panel_index(mesh, panel)
    return np.unique(mesh.tris[mesh.tri_panel == p]).astype(np.int32)


def _vec3(v, what: str) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.isfinite(a).all():
        raise TryOnError(f"{what} must be 3 finite numbers, got {v!r}")
    return a


def rotation_matrix(axis, angle: float) -> np.ndarray:
    """Rotation by ``angle`` [rad] about the unit direction of ``axis`` (Rodrigues)."""
    a = _vec3(axis, "axis")
    n = np.linalg.norm(a)
    if n == 0:
        raise TryOnError("rotation axis is zero")
    a = a / n
    if not math.isfinite(angle):
        raise TryOnError(f"angle must be finite, got {angle!r}")
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * (K @ K)


# ----------------------------------------------------------------------
# rigid moves
# ----------------------------------------------------------------------


def move(x: np.ndarray, verts: np.ndarray, d) -> np.ndarray:
    """x with ``verts`` translated by d [m] (a copy)."""
    out = np.array(x, dtype=np.float64, copy=True)
    out[verts] += _vec3(d, "move vector")
    return out


def rotate(x: np.ndarray, verts: np.ndarray, angle: float, axis=UP, center=None) -> np.ndarray:
    """x with ``verts`` rotated by ``angle`` [rad] about ``axis`` through
    ``center`` (default: their centroid), a copy."""
    out = np.array(x, dtype=np.float64, copy=True)
    c = out[verts].mean(axis=0) if center is None else _vec3(center, "rotation centre")
    R = rotation_matrix(axis, angle)
    out[verts] = (out[verts] - c) @ R.T + c
    return out


# ----------------------------------------------------------------------
# drag along the body
# ----------------------------------------------------------------------


def push_out(x: np.ndarray, verts: np.ndarray, body, offset: float, iters: int = PUSH_ITERS) -> np.ndarray:
    """Move each of ``verts`` nearer the body than ``offset`` outward along the
    distance field's gradient until phi >= offset (in place; returns x).

    Each sweep moves a vertex by (offset - phi) grad / |grad|², a Newton step
    on phi = offset, aiming a hair (1e-7 m) beyond so round-off cannot leave
    it just inside. Raises TryOnError if some vertex is still inside after
    ``iters`` sweeps (a vertex deep in a crevice whose gradient vanishes)."""
    verts = np.asarray(verts)
    active = verts
    for _ in range(iters):
        phi, g = body.phi_grad(x[active])
        inside = phi < offset
        if not inside.any():
            return x
        active = active[inside]
        g = g[inside]
        g2 = np.maximum((g * g).sum(axis=1), 1e-12)
        x[active] += ((offset + 1e-7 - phi[inside]) / g2)[:, None] * g
    phi, _ = body.phi_grad(x[verts])
    if (phi < offset).any():
        raise TryOnError(f"{int((phi < offset).sum())} vertices could not be pushed out of the body")
    return x


def drag(
    x: np.ndarray,
    verts: np.ndarray,
    body,
    *,
    turn: float = 0.0,
    rise: float = 0.0,
    offset: float = 0.01,
    step: float = 0.01,
    axis=UP,
    axis_point=TORSO_AXIS_POINT,
    guide=None,
) -> np.ndarray:
    """x with ``verts`` slid along the body (a copy; module docstring).

    turn [rad] about the vertical ``axis`` through ``axis_point`` (positive:
    counter-clockwise seen from above), rise [m] along it. The motion is cut
    into ceil(L / step) equal steps, L the longest path a vertex travels
    (arc at its radius plus rise); after each step the panel is pushed out
    of the body's offset layer (phi >= offset).

    ``guide``: a body to slide along instead (same ``phi_grad``), e.g. the
    ellipsoid proxy, which bounds the body (the panel rides up to its fit
    error farther out) and whose gradient never vanishes; the result is
    pushed out of ``body`` once at the end, so it is outside ``body``'s
    offset layer either way."""
    if not (math.isfinite(turn) and math.isfinite(rise)):
        raise TryOnError(f"drag turn and rise must be finite, got {turn!r}, {rise!r}")
    if step <= 0:
        raise TryOnError(f"drag step must be positive, got {step!r}")
    a = _vec3(axis, "drag axis")
    a = a / np.linalg.norm(a)
    c = _vec3(axis_point, "drag axis point")
    out = np.array(x, dtype=np.float64, copy=True)
    rel = out[verts] - c
    radial = rel - np.outer(rel @ a, a)
    r_max = float(np.sqrt((radial * radial).sum(axis=1)).max()) if len(verts) else 0.0
    travel = math.hypot(abs(turn) * r_max, rise)
    n = max(1, math.ceil(travel / step))
    R = rotation_matrix(a, turn / n)
    along = body if guide is None else guide
    push_out(out, verts, along, offset)  # start outside (a placement may graze the layer)
    for _ in range(n):
        out[verts] = (out[verts] - c) @ R.T + c + (rise / n) * a
        push_out(out, verts, along, offset)
    if guide is not None:
        push_out(out, verts, body, offset)
    return out


# ----------------------------------------------------------------------
# seams
# ----------------------------------------------------------------------


def seam_groups(mesh: GarmentMesh, seam_of_spring: np.ndarray | None = None) -> list[np.ndarray]:
    """The mesh's seam springs grouped into seams, each an int32 array of
    spring indices, ordered by their first spring.

    With ``seam_of_spring`` (the remesher's :attr:`RemeshResult.seam_of_spring`)
    the groups are the drafted seams. Without it (a mesh off the bus) they are
    found from the mesh alone: springs joining the same pair of panels
    (emitter's panel, receiving edge's panel) whose emitters are linked by
    mesh edges (one run along the boundary) form a seam; two side seams of
    the same two panels are two seams."""
    k = len(mesh.seam_emitters)
    if seam_of_spring is not None:
        s = np.asarray(seam_of_spring)
        if s.shape != (k,):
            raise TryOnError(f"seam_of_spring has shape {s.shape}, the mesh has {k} seam springs")
        groups = [np.nonzero(s == v)[0].astype(np.int32) for v in np.unique(s)]
        return sorted(groups, key=lambda g: int(g[0]))
    if k == 0:
        return []
    vpanel = np.full(mesh.n_vertices, -1, np.int64)
    for j in range(3):
        vpanel[mesh.tris[:, j]] = mesh.tri_panel
    pa = vpanel[mesh.seam_emitters]
    pb = vpanel[mesh.seam_edges[:, 0]]
    key = np.minimum(pa, pb) * (vpanel.max() + 2) + np.maximum(pa, pb)
    # union-find over springs: same panel pair and emitters equal or joined by a mesh edge
    parent = np.arange(k)

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    edges = np.concatenate([mesh.tris[:, [0, 1]], mesh.tris[:, [1, 2]], mesh.tris[:, [2, 0]]])
    nbr: dict[int, set[int]] = {}
    on_seam = set(mesh.seam_emitters.tolist()) | set(mesh.seam_edges.ravel().tolist())
    for u, v in edges.tolist():
        if u in on_seam and v in on_seam:
            nbr.setdefault(u, set()).add(v)
            nbr.setdefault(v, set()).add(u)
    # springs touching each vertex (emitter or receiving edge end)
    touch: dict[int, list[int]] = {}
    for i in range(k):
        for v in (int(mesh.seam_emitters[i]), int(mesh.seam_edges[i, 0]), int(mesh.seam_edges[i, 1])):
            touch.setdefault(v, []).append(i)
    for i in range(k):
        for v in (int(mesh.seam_emitters[i]), int(mesh.seam_edges[i, 0]), int(mesh.seam_edges[i, 1])):
            for u in [v, *nbr.get(v, ())]:
                for j in touch.get(u, ()):
                    if key[j] == key[i]:
                        ri, rj = find(i), find(j)
                        if ri != rj:
                            parent[max(ri, rj)] = min(ri, rj)
    roots = np.array([find(i) for i in range(k)])
    groups = [np.nonzero(roots == r)[0].astype(np.int32) for r in np.unique(roots)]
    return sorted(groups, key=lambda g: int(g[0]))


# ----------------------------------------------------------------------
# the try-on state
# ----------------------------------------------------------------------


@dataclass
class TryOn:
    """A garment being tried on: the full mesh (every seam), the current
    positions, which seams are sewn and which panels are fixed."""

    mesh: GarmentMesh
    x: np.ndarray
    """current positions [m], (n, 3)"""
    groups: list[np.ndarray] = field(default_factory=list)
    """spring indices of each seam (:func:`seam_groups`)"""
    sewn: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    """per seam: sewn (its springs are in the model)"""
    fixed: set[int] = field(default_factory=set)
    """panel indices pinned where they are"""

    @classmethod
    def start(
        cls, mesh: GarmentMesh, x: np.ndarray | None = None, *, sewn: bool = True, seam_of_spring=None
    ) -> "TryOn":
        """A try-on of ``mesh`` from x (default its placement x0), every seam
        sewn (the usual drape) or none (sequential sewing from scratch)."""
        groups = seam_groups(mesh, seam_of_spring)
        x = mesh.x0 if x is None else x
        x = np.array(x, dtype=np.float64, copy=True)
        if x.shape != (mesh.n_vertices, 3):
            raise TryOnError(f"positions have shape {x.shape}, the mesh has {mesh.n_vertices} vertices")
        return cls(mesh=mesh, x=x, groups=groups, sewn=np.full(len(groups), bool(sewn)))

    @property
    def n_seams(self) -> int:
        return len(self.groups)

    def next_unsewn(self) -> int:
        """The first seam not yet sewn; TryOnError when all are."""
        left = np.nonzero(~self.sewn)[0]
        if not len(left):
            raise TryOnError("every seam is sewn")
        return int(left[0])

    def _seam(self, seam: int | None, *, sewn: bool) -> int:
        if seam is None or seam < 0:
            if sewn:
                return self.next_unsewn()
            done = np.nonzero(self.sewn)[0]
            if not len(done):
                raise TryOnError("no seam is sewn")
            return int(done[-1])
        if not 0 <= seam < self.n_seams:
            raise TryOnError(f"seam {seam} outside [0, {self.n_seams})")
        return int(seam)

    def apply(
        self,
        op: str,
        *,
        panel: str | int | None = None,
        vector=None,
        angle: float = 0.0,
        seam: int | None = None,
        body=None,
        offset: float = 0.01,
        step: float = 0.01,
        guide=None,
    ) -> "TryOn":
        """One operation, in place; returns self.

        move: panel by vector [m]; rotate: panel by angle [rad] about vector
        (an axis; default vertical) through its centroid; drag: panel slid
        along ``body`` by angle [rad] about the body's vertical axis and
        vector[1] [m] up it (vector's other components are ignored); fix /
        unfix: pin / release panel; sew / unsew: seam (None or < 0: the next
        unsewn / the last sewn). Positions change only by move, rotate, drag.
        ``guide``: what drag slides along (:func:`drag`; None: ``body``).
        """
        if op not in OPS:
            raise TryOnError(f"unknown try-on op {op!r}; use one of {OPS}")
        if op in ("sew", "unsew"):
            s = self._seam(seam, sewn=op == "sew")
            self.sewn[s] = op == "sew"
            return self
        if panel is None or panel == "":
            raise TryOnError(f"{op} needs a panel")
        p = panel_index(self.mesh, panel)
        if op == "fix":
            self.fixed.add(p)
            return self
        if op == "unfix":
            self.fixed.discard(p)
            return self
        if p in self.fixed:
            raise TryOnError(f"panel {self._name(p)} is fixed; unfix it before {op}")
        verts = panel_vertices(self.mesh, p)
        if op == "move":
            self.x = move(self.x, verts, vector)
        elif op == "rotate":
            axis = UP if vector is None or not np.any(vector) else vector
            self.x = rotate(self.x, verts, float(angle), axis)
        else:
            if body is None:
                raise TryOnError("drag needs a body")
            rise = 0.0 if vector is None else float(_vec3(vector, "drag vector")[1])
            self.x = drag(self.x, verts, body, turn=float(angle), rise=rise, offset=offset, step=step, guide=guide)
        return self

    def _name(self, p: int) -> str:
        return repr(self.mesh.panel_names[p]) if p < len(self.mesh.panel_names) else str(p)

    def pinned(self) -> np.ndarray:
        """Vertices held in the solve: the mesh's own pins and the fixed panels'."""
        parts = [self.mesh.pinned] + [panel_vertices(self.mesh, p) for p in sorted(self.fixed)]
        return np.unique(np.concatenate(parts)).astype(np.int32)

    def spring_mask(self) -> np.ndarray:
        """(k,) bool: the seam springs of sewn seams."""
        m = np.zeros(len(self.mesh.seam_emitters), bool)
        for g, on in zip(self.groups, self.sewn, strict=True):
            m[g] = on
        return m

    def model_mesh(self) -> GarmentMesh:
        """The mesh a model of this state is built on: sewn seams' springs
        only, fixed panels pinned, x0 = the current positions (pins are held
        at x0)."""
        m = self.spring_mask()
        return replace(
            self.mesh,
            x0=self.x.copy(),
            seam_emitters=self.mesh.seam_emitters[m],
            seam_edges=self.mesh.seam_edges[m],
            seam_weights=self.mesh.seam_weights[m],
            pinned=self.pinned(),
        )

"""The simulation mesh shared by the remesher, the solvers and the sensitivity node.

A :class:`GarmentMesh` is pure data: 2D rest positions (the pattern, material
space), triangles, panel ids, seams, and an initial 3D placement. The remesher
produces it (``couture.remesh``), the ``mesh/{coarse,fine}`` message carries
it, and ``couture.cloth.ClothModel`` is built from it.

Seams follow SC §7: each *emitter* vertex is tied by a zero-length spring to
a point on a *receiver* edge ``(a, b)`` at ``(1 - w) * x[a] + w * x[b]``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class GarmentMesh:
    """A triangulated garment (or test sheet) in material and world space."""

    X: np.ndarray
    """rest (pattern) positions [m], shape (n, 2), float64"""
    tris: np.ndarray
    """triangles as vertex indices, counter-clockwise in X, shape (m, 3), int32"""
    # None is accepted and replaced in __post_init__, so readers always see an array
    x0: np.ndarray = None  # type: ignore[assignment]
    """initial 3D placement [m], shape (n, 3), float64; None: the flat pattern at z = 0"""
    tri_panel: np.ndarray = None  # type: ignore[assignment]
    """panel index of each triangle, shape (m,), int32; None: all in panel 0"""
    panel_names: list[str] = field(default_factory=list)
    """panel names, indexed by ``tri_panel``"""
    panel_grain: np.ndarray = None  # type: ignore[assignment]
    """[rad] each panel's grain (``Panel.grain``: the warp's angle from material
    +y, counter-clockwise; 0 straight grain, pi/4 bias), indexed by
    ``tri_panel``, shape (p,), float64, p = the number of panels
    (``n_panels``); None: every panel on the straight grain (0)"""
    seam_emitters: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    """emitting vertex of each seam spring, shape (k,), int32"""
    seam_edges: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int32))
    """receiving edge (a, b) of each seam spring, shape (k, 2), int32"""
    seam_weights: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float64))
    """barycentric weight w of the receiving point (1-w) x_a + w x_b, shape (k,), float64"""
    pinned: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    """indices of vertices held at their x0, shape (p,), int32"""
    level: str = "fine"
    """'coarse' or 'fine' (cascadic refinement level)"""
    generation: int = 0
    """pattern generation this mesh was built from"""

    def __post_init__(self) -> None:
        self.X = np.ascontiguousarray(self.X, dtype=np.float64)
        self.tris = np.ascontiguousarray(self.tris, dtype=np.int32)
        if self.X.ndim != 2 or self.X.shape[1] != 2:
            raise ValueError(f"GarmentMesh.X must have shape (n, 2), got {self.X.shape}")
        if self.tris.ndim != 2 or self.tris.shape[1] != 3:
            raise ValueError(f"GarmentMesh.tris must have shape (m, 3), got {self.tris.shape}")
        if self.tris.size and (self.tris.min() < 0 or self.tris.max() >= len(self.X)):
            raise ValueError("GarmentMesh.tris index a vertex outside X")
        if self.x0 is None:
            self.x0 = np.column_stack([self.X, np.zeros(len(self.X))])
        self.x0 = np.ascontiguousarray(self.x0, dtype=np.float64)
        if self.x0.shape != (len(self.X), 3):
            raise ValueError(f"GarmentMesh.x0 must have shape ({len(self.X)}, 3), got {self.x0.shape}")
        if self.tri_panel is None:
            self.tri_panel = np.zeros(len(self.tris), np.int32)
        self.tri_panel = np.ascontiguousarray(self.tri_panel, dtype=np.int32)
        if self.panel_grain is None or len(self.panel_grain) == 0:
            self.panel_grain = np.zeros(self.n_panels)
        self.panel_grain = np.ascontiguousarray(self.panel_grain, dtype=np.float64).reshape(-1)
        if len(self.panel_grain) != self.n_panels:
            raise ValueError(f"GarmentMesh.panel_grain has {len(self.panel_grain)} values for {self.n_panels} panels")
        if not np.all(np.isfinite(self.panel_grain)):
            raise ValueError("GarmentMesh.panel_grain must be finite angles [rad]")
        self.seam_emitters = np.ascontiguousarray(self.seam_emitters, dtype=np.int32)
        self.seam_edges = np.ascontiguousarray(self.seam_edges, dtype=np.int32).reshape(-1, 2)
        self.seam_weights = np.ascontiguousarray(self.seam_weights, dtype=np.float64)
        self.pinned = np.ascontiguousarray(self.pinned, dtype=np.int32)
        if not (len(self.seam_emitters) == len(self.seam_edges) == len(self.seam_weights)):
            raise ValueError("GarmentMesh seam arrays differ in length")

    @property
    def n_vertices(self) -> int:
        return len(self.X)

    @property
    def n_triangles(self) -> int:
        return len(self.tris)

    @property
    def n_panels(self) -> int:
        """len(panel_names), or for an unnamed mesh 1 + the largest ``tri_panel``"""
        top = int(self.tri_panel.max()) + 1 if len(self.tri_panel) else 0
        return max(len(self.panel_names), top)

    def warp_directions(self) -> np.ndarray:
        """(m, 2) unit warp direction of every triangle in material space,
        (-sin g, cos g) for its panel's grain g (the weft is (cos g, sin g))."""
        g = self.panel_grain[self.tri_panel]
        return np.column_stack([-np.sin(g), np.cos(g)])


def grid_sheet(width: float, height: float, nx: int, ny: int, *, jitter: float = 0.0, seed: int = 0) -> GarmentMesh:
    """A rectangular sheet [0, width] x [0, height] triangulated by ``triangle``
    (quality constrained Delaunay, not a structured grid), about nx*ny vertices.

    Test and benchmark scenes use it; garments come from the remesher.
    """
    import triangle as tr

    area = width * height / max(1, (nx - 1) * (ny - 1)) * 0.5 * 1.2
    bx = np.linspace(0, width, nx)
    by = np.linspace(0, height, ny)
    boundary = np.concatenate(
        [
            np.column_stack([bx[:-1], np.zeros(nx - 1)]),
            np.column_stack([np.full(ny - 1, width), by[:-1]]),
            np.column_stack([bx[::-1][:-1], np.full(nx - 1, height)]),
            np.column_stack([np.zeros(ny - 1), by[::-1][:-1]]),
        ]
    )
    k = len(boundary)
    segs = np.column_stack([np.arange(k), (np.arange(k) + 1) % k])
    out = tr.triangulate({"vertices": boundary, "segments": segs}, f"pq30a{area:.12f}Q")
    X = out["vertices"].astype(np.float64)
    tris = out["triangles"].astype(np.int32)
    if jitter:
        rng = np.random.default_rng(seed)
        X = X + rng.normal(scale=jitter, size=X.shape)
    # counter-clockwise orientation in X
    e1 = X[tris[:, 1]] - X[tris[:, 0]]
    e2 = X[tris[:, 2]] - X[tris[:, 0]]
    flip = (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) < 0
    tris[flip] = tris[flip][:, [0, 2, 1]]
    return GarmentMesh(X=X, tris=tris)

"""A stand-in garment for running the UI without the pipeline (tests, the
benchmark, ``python -m couture.ui``): a rectangular sheet
(``couture.mesh.grid_sheet``) wrapped as a flared tube skirt around the
mannequin's hips, its pattern (one panel, four segments) and a helper that
deforms it the way a drag would, so predictions can be faked."""

from __future__ import annotations

import numpy as np

from couture.mesh import GarmentMesh, grid_sheet
from couture.pattern.drafted import DraftedPattern, Panel, SeamSpec, Segment

WAIST_Y = 0.06
"""[m] height of the skirt's waist on the default mannequin"""
CENTRE = np.array([0.0, 0.0, 0.025])
"""[m] axis of the mannequin's hips (x, z)"""


def demo_sheet(n_vertices: int = 2000, width: float = 1.2, height: float = 0.5) -> tuple[GarmentMesh, DraftedPattern]:
    """The sheet mesh (about n_vertices) and its one-panel pattern, whose
    outline is the sheet boundary and whose side segments are sewn together."""
    ny = max(3, int(round(np.sqrt(n_vertices * height / width))))
    nx = max(3, int(round(n_vertices / ny)))
    mesh = grid_sheet(width, height, nx, ny)
    k = 2 * (nx - 1) + 2 * (ny - 1)
    outline = mesh.X[:k].copy()  # triangle keeps the input boundary points first
    segs = [
        Segment("hem", 0, nx - 1),
        Segment("right", nx - 1, nx - 1 + ny - 1),
        Segment("waist", nx - 1 + ny - 1, 2 * (nx - 1) + ny - 1),
        Segment("left", 2 * (nx - 1) + ny - 1, 0),
    ]
    pattern = DraftedPattern(
        [Panel("skirt", outline, segments=segs)], seams=[SeamSpec("skirt", "right", "skirt", "left")]
    )
    mesh = GarmentMesh(
        X=mesh.X,
        tris=mesh.tris,
        x0=wrap(mesh.X, width, height),
        panel_names=["skirt"],
        tri_panel=np.zeros(len(mesh.tris), np.int32),
    )
    return mesh, pattern


def wrap(
    X: np.ndarray, width: float, height: float, flare: float = 0.12, wave: float = 0.015, phase: float = 0.0
) -> np.ndarray:
    """The sheet as a flared tube around the hips [m], shape (n, 3): material
    x goes round, material y goes up to the waist."""
    a = 2 * np.pi * X[:, 0] / width + np.pi / 2
    t = 1.0 - X[:, 1] / height  # 0 at the waist, 1 at the hem
    wob = wave * t * np.sin(8 * a + phase)
    rx = 0.215 + flare * t + wob
    rz = 0.145 + flare * t + wob
    return np.column_stack([CENTRE[0] + rx * np.cos(a), WAIST_Y - height * t, CENTRE[2] + rz * np.sin(a)])


def tugged(x: np.ndarray, vertex: int, offset: np.ndarray, radius: float = 0.15) -> np.ndarray:
    """x with a smooth bump moving vertex by ``offset`` [m] (Gaussian falloff
    of ``radius`` [m]): what a fake prediction shows during a drag."""
    w = np.exp(-((x - x[vertex]) ** 2).sum(axis=1) / (2 * radius**2))
    return x + w[:, None] * np.asarray(offset)[None, :]

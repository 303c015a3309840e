"""Scenes for the solver tests, built on the real ``couture.cloth.ClothModel``
(y up, gravity -y): hanging and edge-pinned sheets, a drape over a sphere
(SC Fig. 5), and the fabric they use."""

from __future__ import annotations

import numpy as np

from couture.cloth import Fabric
from couture.mesh import GarmentMesh


def fabric(stretch: float = 500.0, bend: float = 1e-6, density: float = 0.15, poisson: float = 0.3) -> Fabric:
    """A fabric in SC Table 1's ranges: stretch [N/m], bend [N m], density [kg/m²]."""
    return Fabric(stretch_stiffness=stretch, bend_stiffness=bend, area_density=density, poisson_ratio=poisson)


def horizontal(mesh: GarmentMesh, height: float = 0.0, center=None) -> GarmentMesh:
    """Place the pattern flat in the x-z plane (y up, the cloth model's gravity axis) at y = height."""
    X = mesh.X
    c = X.mean(axis=0) if center is None else np.asarray(center, float)
    mesh.x0 = np.column_stack([X[:, 0] - c[0], np.full(len(X), height), X[:, 1] - c[1]])
    return mesh


def cloth_hanging_sheet(nx: int = 12, ny: int = 12, size: float = 0.5, *, fab=None, scene=None) -> "object":
    """Real ClothModel: a horizontal square sheet pinned at the two corners of one edge."""
    from couture.cloth import ClothModel, Scene
    from couture.mesh import grid_sheet

    m = horizontal(grid_sheet(size, size, nx, ny), center=(size / 2, size / 2))
    X = m.X
    top = np.nonzero(np.isclose(X[:, 1], size))[0]
    m.pinned = top[[np.argmin(X[top, 0]), np.argmax(X[top, 0])]].astype(np.int32)
    return ClothModel(m, fab or fabric(), scene or Scene())


def cloth_edge_pinned_sheet(nx: int, ny: int, size: float = 0.5, *, fab=None, scene=None):
    """Real ClothModel: a horizontal sheet clamped along its whole edge y = size (cantilever/curtain)."""
    from couture.cloth import ClothModel, Scene
    from couture.mesh import grid_sheet

    m = horizontal(grid_sheet(size, size, nx, ny), center=(size / 2, size / 2))
    m.pinned = np.nonzero(np.isclose(m.X[:, 1], size))[0].astype(np.int32)
    return ClothModel(m, fab or fabric(), scene or Scene())


def cloth_sphere_drape(nx: int = 16, *, fab=None, size: float = 0.6, radius: float = 0.2, friction: bool = False):
    """SC Fig. 5 scene: a square cloth pinned along one edge, partly draped on a sphere.

    Sphere of radius 0.2 m at the origin; the 0.6 m cloth starts flat 2 cm above
    the sphere's top, its pinned edge over the sphere, 5 cm before its centre,
    so the rest of it falls over the sphere and hangs on the far side. (Pinned
    outside the sphere's footprint, a frictionless cloth slides off and hangs
    free from its pins, never touching the sphere.)
    """
    from couture.cloth import ClothModel, Scene
    from couture.cloth.body import SphereBody as Sphere
    from couture.mesh import grid_sheet

    m = grid_sheet(size, size, nx, nx)
    X = m.X
    m.x0 = np.column_stack([X[:, 0] - size / 2, np.full(len(X), radius + 0.02), X[:, 1] - 0.05])
    m.pinned = np.nonzero(np.isclose(X[:, 1], 0.0))[0].astype(np.int32)
    body = Sphere(center=np.zeros(3), radius=radius)
    return ClothModel(m, fab or fabric(), Scene(body=body, friction=friction))

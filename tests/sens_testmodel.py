"""Scenes for the sensitivity tests, built on couture.cloth.ClothModel.

The re-solves behind the finite-difference checks use Newton
(couture.cloth.testing.newton or couture.solvers' newton).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass
class SimpleFabric:
    """The fields couture.cloth.ClothModel reads from a fabric."""

    stretch_stiffness: float = 50.0  # E h [N/m]
    poisson_ratio: float = 0.3
    bend_stiffness: float = 1e-6  # [N m]
    area_density: float = 0.15  # [kg/m^2]


def nearest(X, points):
    return np.array([int(np.argmin(np.linalg.norm(X - p, axis=1))) for p in np.atleast_2d(points)], np.int32)


def sheet_pinned_corners(nx=9, size=0.5, fabric=None):
    """Square sheet in the x-z plane, corners pinned 2 % apart more than rest, sagging under gravity (-y)."""
    from couture.cloth.model import ClothModel, Scene
    from couture.mesh import grid_sheet

    mesh = grid_sheet(size, size, nx, nx)
    X = mesh.X
    mesh.pinned = nearest(X, [[0, 0], [size, 0], [0, size], [size, size]])
    mesh.x0 = np.column_stack([X[:, 0] * 1.02, np.zeros(len(X)), X[:, 1] * 1.02])
    return ClothModel(mesh, fabric or SimpleFabric(), Scene())


def strip_over_sphere(nx=21, ny=6, length=0.8, width=0.25, radius=0.2, fabric=None, friction=False):
    """SC Fig. 5: a strip pinned at one end, lying over a sphere, the rest hanging.
    Material x runs along the strip (world +x), material y across it (world z)."""
    from couture.cloth.body import SphereBody
    from couture.cloth.model import ClothModel, Scene
    from couture.mesh import grid_sheet

    mesh = grid_sheet(length, width, nx, ny)
    X = mesh.X
    h = length / (nx - 1)
    mesh.pinned = np.nonzero(X[:, 0] < 0.25 * h)[0].astype(np.int32)
    mesh.x0 = np.column_stack([X[:, 0] - 0.05, np.full(len(X), radius + 0.05), X[:, 1] - width / 2])
    body = SphereBody(center=np.zeros(3), radius=radius)
    return ClothModel(mesh, fabric or SimpleFabric(), Scene(body=body, friction=friction))


class DressFormBody:
    """A smooth dress form: surface of revolution about the vertical axis
    through ``axis`` (x, z) with radius r(y) = r_w + 2 (r_h - r_w) u² / (1 + u²),
    u = (y - y_waist) / drop: narrowest at the waist, r_h at the hip line,
    saturating below. phi = (ρ - r(y)) / sqrt(1 + r'²) (a first-order signed
    distance, smooth everywhere), frictionless, rotationally symmetric: a
    garment on it can spin about the axis."""

    def __init__(self, axis=(0.0, 0.04), y_waist=0.27, r_waist=0.11, r_hip=0.155, drop=0.31):
        self.ax, self.az = axis
        self.yw, self.rw, self.rh, self.drop = y_waist, r_waist, r_hip, drop

    def _r(self, y):
        u = (y - self.yw) / self.drop
        c = 2.0 * (self.rh - self.rw)
        r = self.rw + c * u * u / (1 + u * u)
        dr = c * 2 * u / (1 + u * u) ** 2 / self.drop
        ddr = c * (2 - 6 * u * u) / (1 + u * u) ** 3 / self.drop**2
        return r, dr, ddr

    def phi_grad(self, p):
        p = np.asarray(p, dtype=np.float64)
        dx, dz = p[:, 0] - self.ax, p[:, 2] - self.az
        rho = np.maximum(np.hypot(dx, dz), 1e-12)
        r, dr, ddr = self._r(p[:, 1])
        s = np.sqrt(1 + dr * dr)
        ds = dr * ddr / s
        phi = (rho - r) / s
        g = np.empty_like(p)
        g[:, 0] = dx / rho / s
        g[:, 2] = dz / rho / s
        g[:, 1] = -dr / s - (rho - r) * ds / (s * s)
        return phi, g


def skirt_design():
    from couture.pattern.io import load_design

    return load_design(Path(__file__).resolve().parents[1] / "couture" / "pattern" / "examples" / "default_skirt.json")


def skirt_on_dress_form(design=None, vertices=400, mesh=None, fabric=None):
    """The default skirt sloper, meshed by the remesher, on a frictionless
    smooth dress form (the mannequin's grid SDF is only C⁰ in its gradient,
    too rough for tight finite-difference re-solves). Returns (model, remesh result)."""
    from couture.cloth.model import ClothModel, Scene
    from couture.pattern.validate import validate
    from couture.remesh import mesh_pattern

    design = design or skirt_design()
    res = None
    if mesh is None:
        res = mesh_pattern(validate(design), vertices, level="coarse")
        mesh = res.mesh
    return ClothModel(mesh, fabric or design.fabric, Scene(body=DressFormBody(), friction=False)), res

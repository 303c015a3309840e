"""Remesher library (SC §6, §7): drafted pattern -> garment meshes, seams, Ψ,
Delaunay smoothing, state transfer and coarse <-> fine maps. Pure functions;
the remesher node (nodes/remesher) is a thin adapter around them."""

from couture.remesh.meshing import LEVEL_TARGETS, BoundaryLoop, RemeshResult, mesh_pattern
from couture.remesh.psi import PsiCoordinates, build_coordinates, follow_pattern, interpolate, psi
from couture.remesh.quality import QualityReport, flip_to_delaunay, improve, triangle_quality
from couture.remesh.seams import seam_springs
from couture.remesh.transfer import (
    apply_map,
    locate_points,
    prolong,
    prolongation,
    restrict,
    restriction,
    transfer_state,
)

__all__ = [
    "LEVEL_TARGETS",
    "BoundaryLoop",
    "RemeshResult",
    "mesh_pattern",
    "PsiCoordinates",
    "build_coordinates",
    "follow_pattern",
    "interpolate",
    "psi",
    "QualityReport",
    "flip_to_delaunay",
    "improve",
    "triangle_quality",
    "seam_springs",
    "apply_map",
    "locate_points",
    "prolong",
    "prolongation",
    "restrict",
    "restriction",
    "transfer_state",
]

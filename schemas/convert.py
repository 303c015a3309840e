"""Conversions between bus messages and the library's data classes."""

from __future__ import annotations

import numpy as np

from couture.mesh import GarmentMesh
from schemas.arrays import Array, as_array
from schemas.messages import MeshMsg, SchemaError


def _wire(name: str, a: np.ndarray | None) -> Array:
    """A required MeshMsg array in its wire dtype (the one its ArraySpec allows)."""
    if a is None:
        raise SchemaError(f"{MeshMsg.TYPE}: field `$.{name}` is required")
    return Array.from_numpy(a, MeshMsg.ARRAYS[name].dtypes[0])


def mesh_to_msg(
    mesh: GarmentMesh,
    *,
    generation: int | None = None,
    mesh_generation: int = 0,
    design_id: str = "",
    fine_parent_tri: np.ndarray | None = None,
    fine_bary: np.ndarray | None = None,
) -> MeshMsg:
    """GarmentMesh -> ``couture/mesh/v1`` (level and generation taken from the
    mesh unless ``generation`` is given)."""
    return MeshMsg(
        generation=mesh.generation if generation is None else generation,
        level=mesh.level,  # type: ignore[arg-type]
        mesh_generation=mesh_generation,
        X=_wire("X", mesh.X),
        x0=_wire("x0", mesh.x0),
        tris=_wire("tris", mesh.tris),
        tri_panel=_wire("tri_panel", mesh.tri_panel),
        panel_names=list(mesh.panel_names),
        # [] for an all-straight-grain mesh keeps its message as before
        panel_grain=[float(g) for g in mesh.panel_grain] if np.any(mesh.panel_grain) else [],
        seam_emitters=_wire("seam_emitters", mesh.seam_emitters),
        seam_edges=_wire("seam_edges", mesh.seam_edges.reshape(-1, 2)),
        seam_weights=_wire("seam_weights", mesh.seam_weights),
        pinned=_wire("pinned", mesh.pinned),
        design_id=design_id,
        fine_parent_tri=as_array(fine_parent_tri, "int32"),
        fine_bary=as_array(fine_bary, "float64"),
    )


def msg_to_mesh(msg: MeshMsg) -> GarmentMesh:
    """``couture/mesh/v1`` -> GarmentMesh (arrays copied, so writable).
    The coarse->fine map stays on the message (``msg.fine_bary.numpy()``)."""
    return GarmentMesh(
        X=msg.X.numpy().copy(),
        tris=msg.tris.numpy().copy(),
        x0=msg.x0.numpy().copy(),
        tri_panel=msg.tri_panel.numpy().copy(),
        panel_names=list(msg.panel_names),
        panel_grain=np.array(msg.panel_grain, dtype=np.float64),  # [] (an older message): all 0
        seam_emitters=msg.seam_emitters.numpy().copy(),
        seam_edges=msg.seam_edges.numpy().copy(),
        seam_weights=msg.seam_weights.numpy().copy(),
        pinned=msg.pinned.numpy().copy(),
        level=msg.level,
        generation=msg.generation,
    )

"""Conversions between bus messages and the library's data classes."""

from __future__ import annotations

import numpy as np

from couture.mesh import GarmentMesh
from schemas.messages import MeshMsg


def mesh_to_msg(
    mesh: GarmentMesh,
    *,
    generation: int | None = None,
    mesh_generation: int = 0,
    psi: np.ndarray | None = None,
    psi_edit_id: str = "",
    unchanged: bool = False,
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
        X=mesh.X, x0=mesh.x0, tris=mesh.tris, tri_panel=mesh.tri_panel,
        panel_names=list(mesh.panel_names),
        seam_emitters=mesh.seam_emitters, seam_edges=mesh.seam_edges.reshape(-1, 2),
        seam_weights=mesh.seam_weights, pinned=mesh.pinned,
        psi=psi, psi_edit_id=psi_edit_id, unchanged=unchanged, design_id=design_id, fine_parent_tri=fine_parent_tri, fine_bary=fine_bary,
    )


def msg_to_mesh(msg: MeshMsg) -> GarmentMesh:
    """``couture/mesh/v1`` -> GarmentMesh (arrays copied, so writable).
    Ψ and the coarse->fine map stay on the message (``msg.psi.numpy()``)."""
    return GarmentMesh(
        X=msg.X.numpy().copy(), tris=msg.tris.numpy().copy(), x0=msg.x0.numpy().copy(),
        tri_panel=msg.tri_panel.numpy().copy(), panel_names=list(msg.panel_names),
        seam_emitters=msg.seam_emitters.numpy().copy(), seam_edges=msg.seam_edges.numpy().copy(),
        seam_weights=msg.seam_weights.numpy().copy(), pinned=msg.pinned.numpy().copy(),
        level=msg.level, generation=msg.generation,
    )

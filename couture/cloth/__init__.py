"""Cloth statics core (SC §5, §7): energies, forces, stiffness, body contact.

Pure library, no bus code. Contract used by the solvers and the sensitivity
node (``couture.cloth.model.ClothModel``):

- ``ClothModel(mesh: GarmentMesh, fabric: Fabric, scene: Scene)``; a scene
  declares its terms (body SDF or none, seams, friction, pins, gravity) and
  absent terms are never built.
- ``model.n`` vertices; ``model.mass`` (n,) lumped masses [kg];
  ``model.free`` (n,) bool, False for pinned vertices.
- ``model.energy(x) -> float`` [J]; ``model.forces(x) -> (n, 3)`` total force
  [N] = -dE/dx (gravity, elasticity, seams, contact, friction anchors);
  ``model.stiffness(x) -> scipy.sparse.csr_matrix (3n, 3n)`` = d²E/dx²
  made positive semi-definite, same sparsity every call (refilled in place).
- ``model.relative_residual(x) -> float`` (see couture.solvers.base).
- ``model.update_friction(x)`` moves/releases friction anchors (static and
  dynamic Coulomb); a no-op without friction.
- ``model.dforces_dX(x, dX) -> (n, 3)``: directional derivative of the force
  with respect to the rest positions X along dX (n, 2), for sensitivity.
"""

from couture.cloth.model import (  # noqa: E402
    BEND_CONSTANT,
    GRAVITY,
    Body,
    ClothModel,
    Scene,
    lame_parameters,
)
from schemas.design import Fabric  # noqa: E402  (re-exported: the material a ClothModel reads)

__all__ = ["BEND_CONSTANT", "GRAVITY", "Body", "ClothModel", "Fabric", "Scene", "lame_parameters"]

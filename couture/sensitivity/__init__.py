"""Sensitivity predictor (SC §4, §4.1, §7): a pure library, no bus code.

- :class:`SensitivityFactor` — the stiffness at an equilibrium, factored and
  kept ready; response columns ``∂x/∂d`` for a pointer Jacobian Ψ.
- :class:`GMLSCache` — progressive nonlinear model: zeroth- and first-order
  samples blended by generalized moving least squares; plain MLS and linear
  prediction for the trade-off menu.
- :func:`drag_to_param` — 3D tug → sloper parameter change.
- :class:`Predictor` — equilibrium → refactor (idle), press → columns,
  drag → prediction with an error estimate, solver equilibrium → new sample,
  release → warm start.
- ``couture.sensitivity.service.SensitivityService`` — the node's state
  machine over a Predictor: meshes matched with their designs, gestures
  (press, drag, pause, release, enrich), the 3D tug's design edit.
"""

from .bending import length_scale
from .drag3d import DragResult, drag_to_param, project_jacobian
from .factor import FactorInfo, SensitivityFactor, find_null_modes, rigid_modes
from .gmls import GMLSCache, gmls_coefficients
from .predictor import Prediction, Predictor

__all__ = [
    "DragResult",
    "FactorInfo",
    "GMLSCache",
    "Prediction",
    "Predictor",
    "SensitivityFactor",
    "drag_to_param",
    "find_null_modes",
    "gmls_coefficients",
    "length_scale",
    "project_jacobian",
    "rigid_modes",
]

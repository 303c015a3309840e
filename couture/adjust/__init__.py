"""Direct 3D garment edits with physics-driven pattern adjustment (Bartle et al. 2016).

- :mod:`couture.adjust.target`: a target 3D garment from a loop edit of a
  drape (hem shortened, waist loosened), style kept;
- :mod:`couture.adjust.fixed_point`: 2D patterns whose simulated drape
  reproduces the target (per-triangle fixed point + ARAP embedding), any
  solver as a black box;
- :mod:`couture.adjust.geometry`: flattening, embedding, stretch (eq. 8),
  Hausdorff distances;
- :mod:`couture.adjust.seams`: seam lengths of a pattern, panel outlines for export.

Bus-free: ``couture.client.SolveFanout`` sends the solves to solver nodes.
"""

from .fixed_point import (
    MANNEQUIN_HEIGHT,
    AdjustResult,
    Iteration,
    Simulated,
    adjust,
    fixed_point_update,
    local_simulator,
    with_rest,
)
from .target import Target, hem_edit, waist_edit

__all__ = [
    "MANNEQUIN_HEIGHT",
    "AdjustResult",
    "Iteration",
    "Simulated",
    "Target",
    "adjust",
    "fixed_point_update",
    "hem_edit",
    "local_simulator",
    "waist_edit",
    "with_rest",
]

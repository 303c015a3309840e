"""Pattern adjustment's settings and goal: one place, read by ``couture adjust``,
the adjust node (the UI's tool) and ``couture bench adjust``.

The settings were chosen once for every case by ``couture bench
adjust_sweep`` (every example design, every edit it allows; the sweep and
its scores are in docs/adjustment.md), not per case: a caller that passes
nothing gets the method that meets the goal where it can be met.
"""

from __future__ import annotations

from dataclasses import dataclass, replace


@dataclass(frozen=True)
class Goal:
    """What an adjustment must reach (Bartle et al. 2016, Table 1; the issue's figures)."""

    hausdorff_pct: float = 1.0
    """[% of mannequin height] worst distance between the adjusted pattern's drape and the target"""
    stretch: float = 0.98
    """mean stretch (eq. 8) of that drape against the target, at least"""
    solves: int = 5
    """re-simulated patterns, at most: the start pattern's, every fixed-point update's and every
    gradient step's trial (the source drape, the design as it was, not counted)"""
    seconds: float = 60.0
    """[s] from the edit to the pattern (target, updates, steps, their solves), at most"""


GOAL = Goal()


@dataclass(frozen=True)
class AdjustSettings:
    """How the pattern is adjusted (``couture.adjust.pipeline.run_case``)."""

    start: str = "source"
    """iteration 0's pattern (``couture.adjust.fixed_point.STARTS``): 'source', one update from the
    source pattern and its drape; 'flatten', the target flattened (Bartle's start)"""
    updates: int = 2
    """fixed-point updates after the start pattern, at most"""
    stop_stretch: float = 0.995
    """the fixed point stops once the mean stretch reaches this"""
    gradient_steps: int = 2
    """Gauss-Newton steps with the design sensitivity after the fixed point, at most"""
    stretch_weight: float = 10.0
    """w of the steps' objective (couture.adjust.gradient): an edge off by 1/w mm costs what a vertex 1 mm off does"""
    lengths: tuple[float, ...] = (1.0, 0.5)
    """fractions of a Gauss-Newton step tried in turn (each a solve)"""
    fresh_jacobian: bool = True
    """each Gauss-Newton step linearizes at its own drape (False: a second step reuses the first's
    Jacobian, the chord)"""
    max_solves: int = GOAL.solves
    """re-simulated patterns in all (start, updates, step trials): the steps stop when it is spent"""

    def with_(self, **kw) -> AdjustSettings:
        """A copy with the fields in ``kw`` changed (None values ignored: unset command-line flags)."""
        return replace(self, **{k: v for k, v in kw.items() if v is not None})


DEFAULTS = AdjustSettings()

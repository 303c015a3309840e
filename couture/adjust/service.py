"""One adjustment request, bus-free: what the adjust node (``nodes/adjust``)
runs for each ``couture/adjust/v1``.

Drape the design on a coarse mesh, edit the drape (hem or waist loop) into a
target, adjust the pattern (:func:`couture.adjust.pipeline.run_case`, every
solve through ``simulate_for``), then fit the design's sloper options to the
adjusted pattern (:func:`couture.adjust.project.project_to_design`): the
result is a design the remesher and the solvers re-drape like any other.
Progress goes to ``progress(state, iteration, text)`` as it happens.
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass
from typing import Callable

from couture.mesh import GarmentMesh
from schemas.design import Design

from .fixed_point import Simulate
from .pipeline import CaseResult, run_case
from .project import Projection, project_to_design

Progress = Callable[[str, int, str], None]
"""progress(state, iteration, text): state 'running' or 'iteration'"""

_ITERATION = re.compile(r"^\[adjust\] iteration (\d+):")


@dataclass
class AdjustOutcome:
    design: Design
    """the adjusted design: ``design`` with the fitted sloper options"""
    projection: Projection
    case: CaseResult
    seconds: float
    """[s] the whole request"""

    @property
    def hausdorff_pct(self) -> float:
        """[% of mannequin height] the adjusted pattern's drape to the target"""
        r = self.case.result
        return r.history[r.best].hausdorff_pct

    def text(self) -> str:
        p = self.projection
        opts = ", ".join(f"{k} {a:.3f} -> {b:.3f}" for k, (a, b) in sorted(p.changed.items())) or "none changed"
        r = self.case.result
        return (
            f"{self.case.edit} {self.case.amount:+.3f} m: adjusted pattern's drape {self.hausdorff_pct:.2f} % of "
            f"height from the target (flattening only {r.history[0].hausdorff_pct:.2f} %); design options: {opts}; "
            f"outline fit {1e3 * p.fit_rms_m:.1f} mm RMS ({1e3 * p.fit_max_m:.1f} mm max); {self.seconds:.1f} s"
        )


def run_adjustment(
    design: Design,
    edit: str,
    amount: float,
    simulate_for: Callable[[GarmentMesh], Simulate],
    *,
    vertices: int,
    max_iters: int = 2,
    progress: Progress | None = None,
) -> AdjustOutcome:
    """Adjust ``design`` for a hem or waist edit of ``amount`` [m]; raises
    ValueError (the edit cannot apply, the fit failed) or the simulator's
    errors (no solver answered, a solve failed)."""
    say = progress or (lambda state, k, text: None)
    t0 = time.perf_counter()

    def log(line: str) -> None:
        m = _ITERATION.match(line)
        text = line.removeprefix("[adjust] ")
        if m:
            say("iteration", int(m.group(1)), text)
        else:
            say("running", 0, text)

    case = run_case(
        design,
        edit,
        amount,
        simulate_for,
        vertices=vertices,
        name="design",
        log=log,
        max_iters=max_iters,
        stop_stretch=1.1,  # run the iterations asked for: a few, each one a solve
    )
    if not case.source_solve["converged"]:
        raise ValueError(
            f"the design's drape did not converge on the {vertices}-vertex mesh "
            f"(residual {case.source_solve['residual']:.1e}): nothing to edit"
        )
    say("running", len(case.result.history) - 1, "fitting the design's sloper options to the adjusted pattern")
    projection = project_to_design(design, case.mesh, case.X_out, vertices=vertices)
    if not projection.changed:
        raise ValueError(
            f"the adjusted pattern changes no sloper option of {design.sloper.kind!r} "
            f"(outline fit {1e3 * projection.fit_rms_m:.1f} mm RMS): the edit is not expressible as this design"
        )
    return AdjustOutcome(projection.design, projection, case, time.perf_counter() - t0)

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

import numpy as np

from couture.mesh import GarmentMesh
from schemas.design import Design

from .fixed_point import Simulate
from .pipeline import CaseResult, run_case
from .project import Projection, project_to_design

EDGE_WEIGHT_FLOOR = 0.1
"""fit weight of a vertex the edit did not move (1 + this where it moved most)"""

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
    achieved: float = float("nan")
    """[m] the change measured on the published design's own drape (coarse,
    from its placement), in the request's terms: hem: length change of the
    lowest point (negative: shorter); waist: girth change at the waist"""

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
            f"outline fit {1e3 * p.fit_rms_m:.1f} mm RMS ({1e3 * p.fit_max_m:.1f} mm max); "
            f"the new design's drape: {self.case.edit} {100 * self.achieved:+.1f} cm "
            f"({100 * self.case.amount:+.1f} cm asked); {self.seconds:.1f} s"
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
    # the fit weighs most where the edit moved the garment (the hem, the waist
    # band): the adjusted pattern also differs from the drafted one elsewhere,
    # by what flattening and embedding leave, which no option should chase
    moved = np.linalg.norm(case.target.x - case.x_source, axis=1)
    weights = EDGE_WEIGHT_FLOOR + moved / max(float(moved.max()), 1e-12)
    projection = project_to_design(design, case.mesh, case.X_out, vertices=vertices, weights=weights)
    if not projection.changed:
        raise ValueError(
            f"the adjusted pattern changes no sloper option of {design.sloper.kind!r} "
            f"(outline fit {1e3 * projection.fit_rms_m:.1f} mm RMS): the edit is not expressible as this design"
        )
    say("running", len(case.result.history) - 1, "draping the fitted design to measure what it achieves")
    from .pipeline import garment_mesh

    mesh = garment_mesh(projection.design, vertices)
    drape = simulate_for(mesh)(mesh.X, mesh.x0)
    achieved = measure(edit, case.x_source, case.mesh.tris, drape.x, mesh.tris)
    return AdjustOutcome(projection.design, projection, case, time.perf_counter() - t0, achieved)


def measure(edit: str, x_src: np.ndarray, tris_src: np.ndarray, x: np.ndarray, tris: np.ndarray) -> float:
    """[m] what a drape ``x`` changed against ``x_src``, in the request's
    terms: hem: the lowest point's height change, negated (shorter is
    negative); waist: the girth change at the mannequin's waist."""
    if edit == "hem":
        return -(float(x[:, 1].min()) - float(x_src[:, 1].min()))
    from couture.pattern.mannequin import WAIST_Y

    from .target import section_girth

    return section_girth(x, tris, WAIST_Y) - section_girth(x_src, tris_src, WAIST_Y)

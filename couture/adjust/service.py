"""One adjustment request, bus-free: what the adjust node (``nodes/adjust``)
runs for each ``couture/adjust/v1``.

Drape the design on a coarse mesh, edit the drape (hem or waist loop) into a
target, adjust the pattern (:func:`couture.adjust.pipeline.run_case`, every
solve through ``simulate_for``, with the settings ``couture adjust`` uses:
:data:`couture.adjust.settings.DEFAULTS`), judge it against the goal
(:func:`couture.adjust.verdict.assess`), then fit the design's sloper options
to the adjusted pattern (:func:`fit_design`,
:func:`couture.adjust.project.project_to_design`): the result is a design
the remesher and the solvers re-drape like any other. ``couture adjust``
runs the same steps (``run_case``, ``assess``, ``fit_design``) and writes
that design as ``design.json``. Progress goes to ``progress(state,
iteration, text)`` as it happens.
"""

from __future__ import annotations

import dataclasses
import re
import time
from dataclasses import dataclass, field
from typing import Callable

import msgspec
import numpy as np

from couture.mesh import GarmentMesh
from schemas.design import Design

from .fixed_point import Simulate
from .pipeline import CaseResult, run_case
from .project import Projection, project_to_design
from .settings import DEFAULTS, AdjustSettings
from .target import TORSO_SPAN, MaterialLoop, material_loop, section_girth
from .verdict import Verdict, assess, body_for

CALIBRATE_TOLERANCE = 0.1
"""a waist edit's design is refitted while its drape misses the ask by more than this fraction"""
MAX_SCALE = 2.0
"""a hem edit's fitted option change is scaled by at most this"""
CLOTH_CAP = 3.0
"""the refit changes the loop's cloth by at most this many times the asked girth change"""
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
    lowest point (negative: shorter); waist: girth change of the loop's cloth"""
    calibration: list = field(default_factory=list)
    """(correction, achieved [m]) per drape of a fitted design: waist: the
    change of the loop's cloth [m] fitted; hem: the scale of the fitted option change"""

    @property
    def verdict(self) -> Verdict:
        """The adjusted pattern judged against the goal (the case's, assessed once)."""
        if self.case.verdict is None:
            self.case.verdict = assess(self.case)
        return self.case.verdict

    @property
    def hausdorff_pct(self) -> float:
        """[% of mannequin height] the adjusted pattern's drape (the pattern the
        design was fitted to: after any gradient steps) to the target"""
        return self.verdict.hausdorff_pct

    def text(self) -> str:
        p = self.projection
        opts = ", ".join(f"{k} {a:.3f} -> {b:.3f}" for k, (a, b) in sorted(p.changed.items())) or "none changed"
        r = self.case.result
        return (
            f"{self.case.edit} {self.case.amount:+.3f} m: adjusted pattern's drape {self.hausdorff_pct:.2f} % of "
            f"height from the target (its start {r.history[0].hausdorff_pct:.2f} %); design options: {opts}; "
            f"outline fit {1e3 * p.fit_rms_m:.1f} mm RMS ({1e3 * p.fit_max_m:.1f} mm max); "
            f"the new design's drape: {self.case.edit} {100 * self.achieved:+.1f} cm "
            f"({100 * self.case.amount:+.1f} cm asked); {self.seconds:.1f} s; {self.verdict.text()}"
        )


def run_adjustment(
    design: Design,
    edit: str,
    amount: float,
    simulate_for: Callable[[GarmentMesh], Simulate],
    *,
    vertices: int,
    settings: AdjustSettings = DEFAULTS,
    calibrate_steps: int = 3,
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
        settings=settings,
    )
    case.verdict = assess(case, body=body_for(design))
    say("running", len(case.result.history) - 1, case.verdict.text())
    return fit_design(
        design, case, simulate_for, vertices=vertices, calibrate_steps=calibrate_steps, progress=say, t0=t0
    )


def fit_design(
    design: Design,
    case: CaseResult,
    simulate_for: Callable[[GarmentMesh], Simulate],
    *,
    vertices: int,
    calibrate_steps: int = 3,
    progress: Progress | None = None,
    t0: float | None = None,
) -> AdjustOutcome:
    """The design for an adjusted pattern (``case``, :func:`run_case` of
    ``design`` at ``vertices``): its sloper options fitted, then corrected on
    the fitted design's drapes (at most ``calibrate_steps`` more solves)
    until it achieves what was asked; see :func:`run_adjustment`."""
    say = progress or (lambda state, k, text: None)
    t0 = time.perf_counter() if t0 is None else t0
    edit, amount = case.edit, case.amount
    say("running", len(case.result.history) - 1, "fitting the design's sloper options to the adjusted pattern")
    # the fit weighs most where the edit moved the garment (the hem, the waist
    # band): the adjusted pattern also differs from the drafted one elsewhere,
    # by what flattening and embedding leave, which no option should chase
    moved = np.linalg.norm(case.target.x - case.x_source, axis=1)
    weights = EDGE_WEIGHT_FLOOR + moved / max(float(moved.max()), 1e-12)
    loop = None
    if edit == "waist":
        # what was asked is the girth at the loop: the fitted design keeps the
        # adjusted pattern's cloth along it (a handful of boundary vertices out
        # of hundreds would not make the least squares honour it)
        loop = material_loop(case.x_source, case.mesh.tris, case.target.info["y_loop"], min_span=TORSO_SPAN)
    projection = project_to_design(design, case.mesh, case.X_out, vertices=vertices, weights=weights, loop=loop)
    if not projection.changed:
        raise ValueError(
            f"the adjusted pattern changes no sloper option of {design.sloper.kind!r} "
            f"(outline fit {1e3 * projection.fit_rms_m:.1f} mm RMS): the edit is not expressible as this design"
        )
    from .pipeline import garment_mesh

    def drape_and_measure(p: Projection) -> float:
        # a waist's fitted mesh keeps the adjusted one's vertices: the loop is
        # the same cloth; a hem is measured on the design meshed as it comes
        mesh = p.mesh if loop is not None and p.mesh is not None else garment_mesh(p.design, vertices)
        drape = simulate_for(mesh)(mesh.X, mesh.x0)
        return measure(edit, case, drape.x, mesh, loop)

    say("running", len(case.result.history) - 1, "draping the fitted design to measure what it achieves")
    achieved = drape_and_measure(projection)
    # The fit is a proxy: the outline (and a waist's cloth along the loop)
    # of the adjusted pattern, not the drape. Correct it on the drape until
    # the design does what was asked: a waist by the loop's cloth (refitted,
    # a centimetre of girth per centimetre of cloth to start), a hem by
    # scaling the fitted option change. Regula falsi once two drapes bracket
    # the ask (the measure growing with the correction), else a step from
    # the nearest drape along the slope two drapes show.
    if loop is not None and projection.loop_m is not None:
        start = projection.loop_m[0]
        t1, slope0, cap = projection.loop_m[1] - start, 1.0, (-CLOTH_CAP * abs(amount), CLOTH_CAP * abs(amount))

        def refit_cloth(t: float) -> Projection:
            return project_to_design(
                design, case.mesh, case.X_out, vertices=vertices, weights=weights, loop=loop, loop_length=start + t
            )

        refit: Callable[[float], Projection] = refit_cloth

        what = "cm of cloth along the loop"
    else:
        t1, slope0, cap = 1.0, 1.0 / achieved if achieved * amount > 0 else 1.0 / amount, (0.0, MAX_SCALE)

        first = projection

        def refit_scale(t: float) -> Projection:
            return scaled(first, t)

        refit = refit_scale

        what = "times the fitted option change"
    calibration = [(t1, achieved)]
    pts = [(0.0, 0.0), (t1, achieved)]
    best = (abs(achieved - amount), projection, achieved)
    for _ in range(calibrate_steps):
        if abs(achieved - amount) <= CALIBRATE_TOLERANCE * abs(amount):
            break
        t = float(np.clip(_next_try(pts, amount, slope0), *cap))
        if min(abs(t - c) for c, _ in pts) < 1e-4:
            break  # capped, or nothing new to try
        say(
            "running",
            len(case.result.history) - 1,
            f"the fitted design's drape: {case.edit} {100 * achieved:+.1f} cm ({100 * amount:+.1f} cm asked): "
            f"refitting with {100 * t if loop is not None else t:+.2f} {what}",
        )
        p = refit(t)
        if not p.changed:
            break
        achieved = drape_and_measure(p)
        pts.append((t, achieved))
        calibration.append((t, achieved))
        if abs(achieved - amount) < best[0]:
            best = (abs(achieved - amount), p, achieved)
    _, projection, achieved = best
    return AdjustOutcome(projection.design, projection, case, time.perf_counter() - t0, achieved, calibration)


def scaled(p: Projection, t: float) -> Projection:
    """``p`` with its option changes scaled by ``t`` (kept in range); its fit
    numbers stay those of the fit."""
    from couture.pattern.draft import sloper_of

    rng = {o.name: (o.min, o.max) for o in sloper_of(p.design).options}
    changed = {k: (a, float(np.clip(a + t * (b - a), *rng[k]))) for k, (a, b) in p.changed.items()}
    params = dict(p.design.sloper.params)
    params.update({k: v for k, (_, v) in changed.items()})
    design = msgspec.structs.replace(p.design, sloper=msgspec.structs.replace(p.design.sloper, params=params))
    return dataclasses.replace(p, design=design, changed=changed, mesh=None, scale=t)


def _next_try(pts: list[tuple[float, float]], ask: float, slope0: float) -> float:
    """The next correction to try, from (correction, achieved change) pairs
    measured so far (see the caller); ``slope0``: correction per achieved
    change until two drapes on one side of the ask show theirs."""
    under = [p for p in pts if (p[1] - ask) * np.sign(ask) < 0]
    over = [p for p in pts if (p[1] - ask) * np.sign(ask) >= 0]
    if under and over:
        (c0, a0) = min(under, key=lambda p: abs(p[1] - ask))
        (c1, a1) = min(over, key=lambda p: abs(p[1] - ask))
        if abs(a1 - a0) > 1e-6:
            return c0 + (ask - a0) * (c1 - c0) / (a1 - a0)
    side = sorted(under or over, key=lambda p: abs(p[1] - ask))
    (c0, a0) = side[0]
    slope = slope0
    if len(side) > 1 and abs(side[1][1] - a0) > 1e-4:
        s = (side[1][0] - c0) / (side[1][1] - a0)
        if 0.5 < s / slope0 < 3.0:
            slope = s
    return c0 + slope * (ask - a0)


def measure(edit: str, case: CaseResult, x: np.ndarray, mesh: GarmentMesh, loop: MaterialLoop | None = None) -> float:
    """[m] what a drape ``x`` of ``mesh`` changed against the source drape of
    ``case``, in the request's terms: hem: the lowest point's height change,
    negated (shorter is negative); waist: the girth change of the loop, the
    same cloth (``loop``, when ``mesh`` has the case's vertices) or else the
    garment's section at the loop's height."""
    x_src = case.x_source
    if edit == "hem":
        return -(float(x[:, 1].min()) - float(x_src[:, 1].min()))
    if loop is not None and mesh.n_vertices == case.mesh.n_vertices:
        return loop.girth(x) - loop.girth(x_src)
    y0 = case.target.info["y_loop"]
    return section_girth(x, mesh.tris, y0) - section_girth(x_src, case.mesh.tris, y0)

"""One direct 3D edit, end to end, bus-free: mesh the design, drape it, edit
the drape into a target, adjust the pattern, measure, write the results.

The solves go through ``simulate_for(mesh) -> Simulate``: in-process
(:func:`couture.adjust.fixed_point.local_simulator`) or on solver nodes
(``couture.client.SolveFanout``, what ``couture adjust`` and ``couture bench
adjust`` use).
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

import msgspec
import numpy as np

from couture.mesh import GarmentMesh
from schemas.design import Design

from .fixed_point import MANNEQUIN_HEIGHT, AdjustResult, Simulate, adjust
from .geometry import edges2, frames3, stretch
from .seams import drafted_from_mesh, mirror_asymmetry, seam_lengths
from .settings import DEFAULTS, AdjustSettings
from .target import Target, hem_edit, opening_edges, waist_edit, waist_room

EDITS = ("hem", "waist")
START_LABEL = {"source": "start (source updated)", "flatten": "flattening only"}


def garment_mesh(design: Design, vertices: int | None = None) -> GarmentMesh:
    """The design's coarse mesh, as the remesher makes it (``vertices``: its
    target size instead of the design's ``resolution.coarse_vertices``)."""
    from couture.remesh.service import RemeshService

    return RemeshService().set_design(at_resolution(design, vertices), 1)[0].mesh


def at_resolution(design: Design, vertices: int | None) -> Design:
    """``design`` with coarse meshes of ``vertices`` (None: as it is)."""
    if vertices is None:
        return design
    return msgspec.structs.replace(
        design,
        resolution=msgspec.structs.replace(
            design.resolution,
            coarse_vertices=int(vertices),
            fine_vertices=max(int(vertices), design.resolution.fine_vertices),
        ),
    )


def make_target(
    edit: str, amount: float, x_src: np.ndarray, tris: np.ndarray, mesh: GarmentMesh | None = None
) -> Target:
    """The target of an edit of drape ``x_src``; with ``mesh`` (for its
    seams) the edits know the garment's openings: where a hem may grow, where
    a waist loop goes round."""
    openings = None if mesh is None else opening_edges(mesh)
    if edit == "hem":
        from .seams import vertex_panels

        if mesh is None:
            return hem_edit(x_src, tris, amount, openings=openings)
        sewn = np.concatenate([np.column_stack([mesh.seam_emitters, mesh.seam_edges[:, k]]) for k in (0, 1)]).astype(
            np.int64
        )
        return hem_edit(x_src, tris, amount, openings=openings, vertex_panel=vertex_panels(mesh), sewn=sewn)
    if edit == "waist":
        return waist_edit(x_src, tris, amount, openings=openings)
    raise ValueError(f"edit {edit!r}: choose one of {EDITS}")


def _check_tightening(design: Design, target: Target, x_src: np.ndarray, mesh: GarmentMesh) -> None:
    """Refuse a tightening the body does not leave room for (:func:`waist_room`)."""
    from couture.cloth.body import load_mannequin_sdf
    from couture.solvers.service import scene_from_design

    scene = scene_from_design(design)
    name = design.body.name  # as scene_from_design names it (and registers a body of measurements)
    body = load_mannequin_sdf(verbose=False, name=name)
    y0 = target.info["y_loop"]
    room = waist_room(x_src, mesh.tris, y0, body, scene.contact_offset)
    if -target.amount > room + 0.25 * -target.amount:
        raise ValueError(
            f"waist edit: tightening by {-100 * target.amount:.1f} cm presses the cloth into the body: at "
            f"y = {y0:.3f} m the drape already rests on it (the solver keeps cloth {1e3 * scene.contact_offset:.0f} mm "
            f"from the skin), so its girth can shrink by {100 * room:.1f} cm at most; a tighter pattern "
            "only stretches the cloth over the body"
        )


@dataclass
class CaseResult:
    design_name: str
    edit: str
    amount: float
    mesh: GarmentMesh
    x_source: np.ndarray
    target: Target
    result: AdjustResult
    source_solve: dict
    timings: dict = field(default_factory=dict)
    gradient: list = field(default_factory=list)
    """:class:`~couture.adjust.gradient.GradientStep` of the gradient steps after the fixed point (none by default)"""
    X_final: np.ndarray | None = None
    """the pattern written out: after the gradient steps, else the fixed point's"""
    x_final: np.ndarray | None = None
    verdict: Any = None
    """:class:`~couture.adjust.verdict.Verdict` once assessed (written into the summary)"""

    @property
    def solves(self) -> int:
        """Re-simulated patterns: the start pattern's, every update's, every gradient step trial's."""
        return len(self.result.history) + sum(g.solves for g in self.gradient)

    @property
    def X_out(self) -> np.ndarray:
        return self.result.X if self.X_final is None else self.X_final

    @property
    def x_out(self) -> np.ndarray:
        return self.result.x if self.x_final is None else self.x_final

    def _final_metrics(self) -> dict:
        from .geometry import hausdorff

        m = self.mesh
        H = hausdorff(self.target.x, self.x_out, m.tris)
        return {
            "stretch": float(stretch(frames3(self.target.x, m.tris), frames3(self.x_out, m.tris)).mean()),
            "hausdorff_pct": 100 * H["hausdorff"] / MANNEQUIN_HEIGHT,
            "hausdorff_mm": 1e3 * H["hausdorff"],
            "mean_distance_mm": 1e3 * H["mean"],
            "gradient_steps_taken": sum(1 for g in self.gradient if g.accepted),
        }

    def summary(self) -> dict:
        """JSON-able numbers: per iteration, the start against adjusted, seams, symmetry."""
        r, m = self.result, self.mesh
        first, best = r.history[0], r.history[r.best]
        return {
            "design": self.design_name,
            "edit": self.edit,
            "amount_m": self.amount,
            "achieved_m": self.target.achieved,
            "target_info": self.target.info,
            "vertices": m.n_vertices,
            "triangles": m.n_triangles,
            "mannequin_height_m": MANNEQUIN_HEIGHT,
            "solvers": sorted({h.solver for h in r.history}),
            "source_solve": self.source_solve,
            "iterations": [asdict(h) for h in r.history],
            "start": {"pattern": r.start, "stretch": first.stretch_mean, "hausdorff_pct": first.hausdorff_pct},
            "adjusted": {
                "iteration": best.k,
                "stretch": best.stretch_mean,
                "hausdorff_pct": best.hausdorff_pct,
                "hausdorff_mm": 1e3 * best.hausdorff_m,
                "mean_distance_mm": 1e3 * best.mean_distance_m,
            },
            "gradient_steps": [asdict(g) for g in self.gradient],
            "solves": self.solves,
            "verdict": None if self.verdict is None else self.verdict.as_dict(),
            "final": self._final_metrics(),
            "updates": len(r.history) - 1,
            "stopped": r.stopped,
            "adjust_wall_s": r.wall_time_s,
            "timings_s": self.timings,
            "seams": {
                "source": seam_lengths(m, m.X),
                "start": seam_lengths(m, r.X_start),
                "adjusted": seam_lengths(m, self.X_out),
                "max_mismatch_mm": {
                    "source": 1e3 * max((abs(s["mismatch_m"]) for s in seam_lengths(m, m.X)), default=0.0),
                    "start": 1e3 * max((abs(s["mismatch_m"]) for s in seam_lengths(m, r.X_start)), default=0.0),
                    "adjusted_before_equalizing": 1e3 * r.history[r.best].seam_mismatch_raw_m,
                    "adjusted": 1e3 * max((abs(s["mismatch_m"]) for s in seam_lengths(m, self.X_out)), default=0.0),
                },
            },
            "symmetry": {
                "source": mirror_asymmetry(m, m.X, self.x_source),
                "start": mirror_asymmetry(m, r.X_start, self.x_source),
                "adjusted": mirror_asymmetry(m, self.X_out, self.x_source),
            },
            "pattern_change": {
                "mean_stretch_adjusted_vs_source": float(
                    stretch(edges2(self.X_out, m.tris), edges2(m.X, m.tris)).mean()
                ),
                "area_ratio_adjusted_vs_source": float(
                    np.abs(np.linalg.det(edges2(self.X_out, m.tris))).sum()
                    / np.abs(np.linalg.det(edges2(m.X, m.tris))).sum()
                ),
                "target_vs_source_drape_stretch": float(
                    stretch(frames3(self.target.x, m.tris), frames3(self.x_source, m.tris)).mean()
                ),
            },
        }


def run_case(
    design: Design,
    edit: str,
    amount: float,
    simulate_for: Callable[[GarmentMesh], Simulate],
    *,
    vertices: int | None = None,
    name: str = "design",
    log: Callable[[str], None] | None = print,
    settings: AdjustSettings = DEFAULTS,
    equalize: bool = True,
) -> CaseResult:
    """Mesh, drape from the placement, edit, adjust by the fixed point (at
    most ``settings.updates`` updates), then at most
    ``settings.gradient_steps`` Gauss-Newton steps
    (:mod:`couture.adjust.gradient`) while the solve budget
    ``settings.max_solves`` lasts; every solve through ``simulate_for(mesh)``."""
    say = log or (lambda s: None)
    t0 = time.perf_counter()
    mesh = garment_mesh(design, vertices)
    t_mesh = time.perf_counter() - t0
    simulate = simulate_for(mesh)
    src = simulate(mesh.X, mesh.x0)
    say(
        f"[adjust] {name}: {mesh.n_vertices} vertices, source drape {'converged' if src.converged else 'NOT converged'} "
        f"(residual {src.residual:.1e}, {src.solver}, {src.wall_time_s:.1f} s)"
    )
    t1 = time.perf_counter()
    target = make_target(edit, amount, src.x, mesh.tris, mesh)
    if edit == "waist" and amount < 0 and design.scene.body:
        _check_tightening(design, target, src.x, mesh)
    t_target = time.perf_counter() - t1
    say(f"[adjust] target: {edit} {amount:+.3f} m asked, {target.achieved:+.4f} m on the target")
    result = adjust(
        mesh,
        target.x,
        simulate,
        x_source=src.x,
        log=log,
        max_iters=max(0, min(settings.updates, settings.max_solves - 1)),
        stop_stretch=settings.stop_stretch,
        equalize=equalize,
        start=settings.start,
    )
    steps: list = []
    X_final = x_final = None
    t2 = time.perf_counter()
    budget = settings.max_solves - len(result.history)
    if settings.gradient_steps > 0 and budget > 0:
        from .gradient import gradient_polish

        X_final, x_final, steps = gradient_polish(
            mesh,
            design,
            result.X,
            result.x,
            target.x,
            simulate,
            steps=settings.gradient_steps,
            stretch_weight=settings.stretch_weight,
            lengths=settings.lengths,
            max_solves=budget,
            reuse_jacobian=not settings.fresh_jacobian,
            equalize=equalize,
            log=log,
        )
    t_grad = time.perf_counter() - t2
    return CaseResult(
        design_name=name,
        edit=edit,
        amount=amount,
        mesh=mesh,
        x_source=src.x,
        target=target,
        result=result,
        gradient=steps,
        X_final=X_final,
        x_final=x_final,
        source_solve={
            "solver": src.solver,
            "residual": src.residual,
            "converged": src.converged,
            "diagnosis": src.diagnosis,
            "wall_time_s": src.wall_time_s,
        },
        timings={
            "mesh": t_mesh,
            "source_drape": src.wall_time_s,
            "target": t_target,
            "adjust": result.wall_time_s,
            "gradient": t_grad,
            "edit_to_pattern": t_target + result.wall_time_s + t_grad,
            "total": time.perf_counter() - t0,
        },
    )


def write_outputs(case: CaseResult, out: str | Path, extra: dict | None = None) -> list[Path]:
    """The adjusted pattern as DXF (AAMA), SVG and PDF (true scale), the
    target's flattening (Bartle's start) as ``flattened.svg``, the drapes as OBJ (source,
    target, adjusted, the start pattern's), the pattern's panels as JSON and ``adjust.json`` (the
    case's summary, with ``extra``'s keys added)."""
    from couture.pattern.io import export_dxf, export_pdf, export_svg

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    m, r = case.mesh, case.result
    adjusted = drafted_from_mesh(m, case.X_out)
    paths = [out / "pattern.dxf", out / "pattern.svg", out / "pattern.pdf", out / "flattened.svg"]
    export_dxf(adjusted, paths[0])
    export_svg(adjusted, paths[1])
    export_pdf(adjusted, paths[2])
    export_svg(drafted_from_mesh(m, r.X_flat), paths[3])
    panels = {
        "schema": "couture/adjusted_pattern/v1",
        "units": "m",
        "panels": [
            {"name": p.name, "outline": p.outline.tolist(), "holes": [h.tolist() for h in p.holes]}
            for p in adjusted.panels
        ],
    }
    (out / "panels.json").write_text(json.dumps(panels))
    paths.append(out / "panels.json")
    for nm, x in (
        ("source", case.x_source),
        ("target", case.target.x),
        ("adjusted", case.x_out),
        ("start", r.x_start),
    ):
        p = out / f"drape_{nm}.obj"
        _write_obj(p, x, m.tris)
        paths.append(p)
    np.savez_compressed(
        out / "adjust_mesh.npz",
        X_source=m.X,
        X_adjusted=case.X_out,
        X_flattened=r.X_flat,
        X_start=r.X_start,
        x_start=r.x_start,
        tris=m.tris,
        tri_panel=m.tri_panel,
        x_source=case.x_source,
        x_target=case.target.x,
        x_adjusted=case.x_out,
    )
    paths.append(out / "adjust_mesh.npz")
    from couture.jsonout import dumps

    (out / "adjust.json").write_text(dumps({**case.summary(), **(extra or {})}, indent=2))
    paths.append(out / "adjust.json")
    return paths


def _write_obj(path: Path, x: np.ndarray, tris: np.ndarray) -> None:
    with open(path, "w") as f:
        f.write("# couture adjust, units: metres\n")
        f.writelines(f"v {p[0]:.7g} {p[1]:.7g} {p[2]:.7g}\n" for p in x)
        f.writelines(f"f {t[0]} {t[1]} {t[2]}\n" for t in tris + 1)


def plot_case(case: CaseResult, path: str | Path) -> None:
    """Target against the re-simulated drapes (the start pattern's and adjusted),
    front and side, coloured by distance to the target; and the patterns."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .geometry import SurfaceDistance

    m, r = case.mesh, case.result
    surf = SurfaceDistance(case.target.x, m.tris)
    fig = plt.figure(figsize=(14, 7))
    fin = case._final_metrics()
    label = "adjusted" + (f" + {fin['gradient_steps_taken']} gradient steps" if fin["gradient_steps_taken"] else "")
    views = [
        (START_LABEL[r.start], r.x_start, (r.history[0].hausdorff_pct, r.history[0].stretch_mean)),
        (label, case.x_out, (fin["hausdorff_pct"], fin["stretch"])),
    ]
    for col, (title, x, (h_pct, s_mean)) in enumerate(views):
        _, d, _ = surf.closest(x)
        for row, (ax_h, lab) in enumerate(((0, "front (x-y)"), (2, "side (z-y)"))):
            ax = fig.add_subplot(2, 4, 1 + col + 4 * row)
            ax.triplot(case.target.x[:, ax_h], case.target.x[:, 1], m.tris, color="0.75", lw=0.3)
            sc = ax.scatter(x[:, ax_h], x[:, 1], c=1e3 * d, s=3, cmap="magma_r", vmin=0, vmax=30)
            ax.set_aspect("equal")
            ax.set_title(f"{title}, {lab}\nHausdorff {h_pct:.2f} % h, stretch {s_mean:.3f}", fontsize=9)
            if col == 1:
                fig.colorbar(sc, ax=ax, label="distance to target [mm]", shrink=0.8)
    from couture.pattern.io import layout

    ax = fig.add_subplot(1, 2, 2)
    shift = {p.name: s for p, s in layout(drafted_from_mesh(m, m.X))}
    for X, c, lab in (
        (m.X, "tab:green", "source pattern"),
        (r.X_start, "tab:red", START_LABEL[r.start]),
        (case.X_out, "tab:blue", label),
    ):
        for i, p in enumerate(drafted_from_mesh(m, X).panels):
            P = np.vstack([p.outline, p.outline[:1]]) + shift[p.name]
            ax.plot(P[:, 0], P[:, 1], color=c, lw=1, label=lab if i == 0 else None)
    ax.set_aspect("equal")
    ax.legend(fontsize=8)
    ax.set_title(f"{case.design_name}: {case.edit} {case.amount:+.2f} m; patterns [m]", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=65)
    plt.close(fig)

"""``python -m bench.drape_slopers``: a from-scratch drape of every sloper.

For each sloper at its default options: draft, mesh coarse (``--vertices``),
place around the mannequin (``couture.pattern.placement``), then solve for
static equilibrium on the mannequin with gravity, seams, contact and friction
(default fabric, ``schemas.design.Fabric``; friction from the first iteration, as
the solver node solves a level from its placement) with each solver in ``--solvers``
(the best result is kept). Reported per sloper: seam gaps at the placement
and at the end, relative residual reached, time, the smallest signed distance
of any vertex to the body (the grid SDF; < 0 is inside), and whether the
garment slid down (its top more than 10 cm below where it was placed).

Prints a table, writes ``drape_slopers.json`` to the results folder (``--out``,
default bench/results/) and one PNG per sloper under its ``drapes/`` (body and
garment, front and side).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from bench import add_out_arg, write_results
from couture.solvers import SOLVERS

SLID_LIMIT = 0.10
"""[m] the garment's top may drop this much below its placed height"""
INSIDE_LIMIT = -0.002
"""[m] signed distance below which a vertex counts as inside the body"""


@dataclass
class DrapeRow:
    sloper: str
    solver: str
    vertices: int
    gap0_median_cm: float
    gap0_max_cm: float
    gap_max_cm: float
    residual0: float
    residual: float
    converged: bool
    seconds: float
    min_phi0_mm: float
    min_phi_mm: float
    top_drop_cm: float
    diagnosis: str

    @property
    def dressed(self) -> bool:
        return self.min_phi_mm >= INSIDE_LIMIT * 1e3 and self.top_drop_cm <= SLID_LIMIT * 100


def seam_gaps(mesh, x: np.ndarray) -> np.ndarray:
    """|x[emitter] - receiving point| [m] of every seam spring, shape (k,)."""
    e, (a, b), w = mesh.seam_emitters, mesh.seam_edges.T, mesh.seam_weights
    return np.linalg.norm(x[e] - ((1 - w)[:, None] * x[a] + w[:, None] * x[b]), axis=1)


def body_params(kind: str, body: str) -> dict[str, float]:
    """The option values a design of sloper ``kind`` on ``body`` drafts from
    before defaults: for a body-fitted sloper, the body's measurements
    (:func:`couture.pattern.draft.sloper_params`)."""
    from couture.pattern.draft import sloper_params
    from schemas.design import Body, Design, Sloper

    return sloper_params(Design(sloper=Sloper(kind=kind), body=Body(name=body)))


def coarse_mesh(kind: str, vertices: int, params: dict | None = None, body: str = "default"):
    """Drafted pattern and its coarse mesh (placed on ``body``) for a sloper."""
    from couture.pattern.validate import validate
    from couture.remesh.meshing import mesh_pattern
    from schemas.design import Body, Design, Sloper

    design = Design(sloper=Sloper(kind=kind, params=params or {}), body=Body(name=body))
    drafted = validate(design)
    return design, drafted, mesh_pattern(drafted, vertices, level="coarse")


def drape(
    kind: str,
    vertices: int = 1600,
    solvers=("newton", "kinetic"),
    max_seconds: float = 60.0,
    tol: float = 1e-4,
    params: dict | None = None,
    body: str = "default",
) -> tuple[DrapeRow, np.ndarray, object]:
    """Drape one sloper (its default options, overridden by ``params``) on
    ``body`` (a name of ``couture.bodies``); returns the best row (lowest
    residual), its x and the mesh."""
    from couture.cloth.body import load_mannequin_sdf
    from couture.cloth.model import ClothModel, Scene
    from couture.solvers import get_solver

    design, _, res = coarse_mesh(kind, vertices, params, body)
    mesh = res.mesh
    sdf = load_mannequin_sdf(verbose=False, name=body)
    model = ClothModel(mesh, design.fabric, Scene(body=sdf, friction=True))
    x0 = mesh.x0.copy()
    g0 = seam_gaps(mesh, x0)
    phi0 = sdf.phi_grad(x0)[0]
    r0 = float(model.relative_residual(x0)) if hasattr(model, "relative_residual") else float("nan")
    top0 = x0[:, 1].max()
    best = None
    for name in solvers:
        solver = get_solver(name)
        model.release_friction()  # each solver from the placement, with no anchors of the last one
        # friction from the first iteration, as the solver node solves a level from its placement
        # (couture.solvers.service.FRICTION_AT_ONCE)
        out = solver.solve(
            model, x0.copy(), tol=tol, max_seconds=max_seconds, friction_after=math.inf, from_placement=True
        )
        x = out.x
        phi = sdf.phi_grad(x)[0]
        row = DrapeRow(
            kind,
            name,
            mesh.n_vertices,
            float(np.median(g0) * 100),
            float(g0.max() * 100),
            float(seam_gaps(mesh, x).max() * 100),
            r0,
            float(out.residual),
            bool(out.converged),
            float(out.wall_time),
            float(phi0.min() * 1e3),
            float(phi.min() * 1e3),
            float((top0 - x[:, 1].max()) * 100),
            out.diagnosis,
        )
        if best is None or row.residual < best[0].residual:
            best = (row, x)
        if out.converged:
            break
    if best is None:
        raise ValueError("drape needs at least one solver")
    return best[0], best[1], mesh


def render(path: Path, kind: str, mesh, x: np.ndarray, title: str, body: str = "default") -> None:
    """Front and side views of the body and the garment (matplotlib, headless)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from couture.cloth.body import load_mannequin_mesh

    V, F = load_mannequin_mesh(body)
    fig = plt.figure(figsize=(10, 8))
    for k, (elev, azim, label) in enumerate(((0, -90, "front"), (0, 0, "side"))):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        # y up: plot (x, z, y)
        body = Poly3DCollection(V[F][:, :, [0, 2, 1]], facecolor=(0.8, 0.8, 0.8, 0.25), edgecolor="none")
        ax.add_collection3d(body)
        cloth = Poly3DCollection(
            x[mesh.tris][:, :, [0, 2, 1]],
            facecolor=(0.2, 0.4, 0.85, 0.8),
            edgecolor=(0.1, 0.1, 0.3, 0.3),
            linewidth=0.2,
        )
        ax.add_collection3d(cloth)
        ax.set_xlim(-0.5, 0.5)
        ax.set_ylim(-0.5, 0.5)
        ax.set_zlim(-0.85, 0.85)
        ax.set_box_aspect((1, 1, 1.7))
        ax.view_init(elev=elev, azim=azim)
        ax.set_axis_off()
        ax.set_title(label)
    fig.suptitle(title)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    from couture.pattern import SLOPERS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slopers", nargs="*", default=sorted(SLOPERS))
    ap.add_argument("--vertices", type=int, default=1600)
    ap.add_argument("--solvers", nargs="*", default=["newton", "kinetic"], choices=list(SOLVERS))
    ap.add_argument("--max-seconds", type=float, default=60.0)
    ap.add_argument("--tol", type=float, default=1e-4)
    ap.add_argument(
        "--body", default="default", help="body to drape on (couture bodies), each sloper drafted for its measurements"
    )
    add_out_arg(ap)
    ap.add_argument("--no-png", action="store_true")
    args = ap.parse_args(argv)
    out = Path(args.out)
    rows = []
    hdr = (
        f"{'sloper':9s} {'solver':8s} {'n':>5s} {'gap0 med/max cm':>16s} {'gap cm':>7s} {'res0':>8s} "
        f"{'residual':>9s} {'s':>6s} {'phi0 mm':>8s} {'phi mm':>7s} {'drop cm':>8s} dressed"
    )
    print(hdr)
    for kind in args.slopers:
        params = body_params(kind, args.body) if args.body != "default" else None
        row, x, mesh = drape(kind, args.vertices, args.solvers, args.max_seconds, args.tol, params, args.body)
        rows.append(row)
        print(
            f"{row.sloper:9s} {row.solver:8s} {row.vertices:5d} {row.gap0_median_cm:7.1f}/{row.gap0_max_cm:<8.1f} "
            f"{row.gap_max_cm:7.2f} {row.residual0:8.1e} {row.residual:9.1e} {row.seconds:6.1f} "
            f"{row.min_phi0_mm:8.1f} {row.min_phi_mm:7.1f} {row.top_drop_cm:8.1f} {row.dressed}"
            + (f"  ({row.diagnosis})" if row.diagnosis else ""),
            flush=True,
        )
        if not args.no_png:
            render(
                out / "drapes" / f"{kind}.png",
                kind,
                mesh,
                x,
                f"{kind}: {row.solver}, residual {row.residual:.1e}, {row.seconds:.0f} s",
                args.body,
            )
    write_results(
        out,
        "drape_slopers",
        {"rows": [dict(asdict(r), dressed=r.dressed) for r in rows], "args": dict(vars(args), out=str(args.out))},
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

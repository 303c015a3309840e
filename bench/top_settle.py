"""``python -m bench.top_settle PATTERN [--body SET.json] [--exclude NAME ...]``:
where an imported top starts, where its coarse drape ends, and what holds it
there (docs/import.md, "Where tops start and end").

The pattern imported as ``couture import`` does (``--body``: the measurement
set's own body), meshed coarse (``--vertices``), solved by Newton from its
placement with friction from the first iteration (as the solver node does).
Prints: the body's landmark heights; per panel the placed and draped height
span; the placed seam springs' largest gaps by panel pair; the contact
force's vertical part summed over bands of drape height [N] against the
garment's weight (which band carries the top: the shoulders, or a tight hem
on the hips); and the torso panels' largest principal stretch by drape
height (median over each band's triangles). Writes the same numbers to
``top_settle.json`` under ``--out`` (default bench/results/).
"""

from __future__ import annotations

import argparse
import json
import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from bench import RESULTS_DIR, write_results
from bench.drape_slopers import seam_gaps

BAND = 0.1
"""[m] height of the bands the contact force and the stretch are summed over"""


def main(argv: list[str] | None = None) -> None:
    from couture import bodies
    from couture.cloth.model import ClothModel
    from couture.pattern.imported import read_pattern
    from couture.pattern.landmarks import neck
    from couture.pattern.sewing import body_of_measurements, build_design
    from couture.pattern.validate import validate
    from couture.remesh.meshing import mesh_pattern
    from couture.solvers import get_solver
    from couture.solvers.service import scene_from_design
    from schemas.design import Body

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pattern", help="an SVG, DXF, ... couture import reads")
    ap.add_argument("--body", help="a FreeSewing measurement set (JSON [mm]): its own body")
    ap.add_argument("--exclude", nargs="*", default=[], help="pieces left out, as couture import --exclude")
    ap.add_argument("--vertices", type=int, default=1200, help="coarse mesh size (default 1200)")
    ap.add_argument(
        "--out", type=Path, default=RESULTS_DIR, metavar="DIR", help=f"results folder (default {RESULTS_DIR})"
    )
    args = ap.parse_args(argv)

    body: str | Body = "default"
    if args.body:
        body, note = body_of_measurements(json.loads(Path(args.body).read_text()), name=Path(args.body).stem)
        print(note)
    design, _ = build_design(read_pattern(args.pattern), body=body, exclude=tuple(args.exclude))
    name = design.body.name
    m, nk = bodies.measured(name), neck(name)
    print(
        f"body {name}: waist {m['waist_y']:.3f}, underarm {m['underarm_y']:.3f}, neck base {nk.base_y:.3f}, "
        f"neck top {nk.top_y:.3f} m; ring heights: "
        + ", ".join(f"{p.name} {p.placement.ring} {p.placement.height:.3f}" for p in design.pieces)
    )
    drafted = validate(design)
    res = mesh_pattern(drafted, args.vertices, level="coarse")
    mesh, vp = res.mesh, res.vertex_panel
    names = [p.name for p in drafted.panels]
    model = ClothModel(mesh, design.fabric, scene_from_design(design))
    if model.body is None:
        raise SystemExit("the design's scene has no body: nothing to settle on")
    x0 = mesh.x0.copy()
    phi0 = model.body.phi_grad(x0)[0]
    print(f"placed: {len(x0)} vertices, nearest to the body {phi0.min() * 1000:.1f} mm, {(phi0 < 0).sum()} inside")

    gaps, e, a = seam_gaps(mesh, x0), mesh.seam_emitters, mesh.seam_edges[:, 0]
    by_pair: dict[tuple[str, str], float] = defaultdict(float)
    for g, i, j in zip(gaps, e, a, strict=True):
        key = (names[vp[i]], names[vp[j]])
        by_pair[key] = max(by_pair[key], float(g))
    print(
        "placed seam gaps, largest by pair [cm]:", ", ".join(f"{p}-{q} {g * 100:.1f}" for (p, q), g in by_pair.items())
    )

    out = get_solver("newton").solve(
        model, x0.copy(), tol=1e-3, max_seconds=300.0, friction_after=math.inf, from_placement=True
    )
    x = out.x
    print(f"drape: residual {out.residual:.1e}, converged {out.converged}, {out.wall_time:.1f} s")
    panels = {}
    for k, nm in enumerate(names):
        s = vp == k
        placed, draped = (float(x0[s, 1].min()), float(x0[s, 1].max())), (float(x[s, 1].min()), float(x[s, 1].max()))
        rise = float(np.mean(x[s, 1] - x0[s, 1]))
        panels[nm] = {"placed_y": placed, "draped_y": draped, "mean_rise": rise}
        print(
            f"  {nm}: placed y {placed[0]:.3f}..{placed[1]:.3f}, draped {draped[0]:.3f}..{draped[1]:.3f} m "
            f"(mean {rise * 100:+.1f} cm)"
        )

    weight = -float(model.forces(x, terms=("gravity",))[:, 1].sum())
    fc = model.forces(x, terms=("contact",))[:, 1]
    edges = np.arange(np.floor(x[:, 1].min() / BAND) * BAND, x[:, 1].max() + BAND, BAND)
    contact = {f"{y:.1f}": float(fc[(x[:, 1] >= y) & (x[:, 1] < y + BAND)].sum()) for y in edges}
    print(
        f"contact force, vertical [N], by drape height (weight {weight:.3f} N):",
        " ".join(f"{k}:{v:+.3f}" for k, v in contact.items()),
    )

    rings = {p.name: p.placement.ring for p in design.pieces}
    torso = [k for k, nm in enumerate(names) if rings.get(nm) == "torso"]
    tris = mesh.tris[np.isin(mesh.tri_panel, torso)]
    dX = np.stack([mesh.X[tris[:, 1]] - mesh.X[tris[:, 0]], mesh.X[tris[:, 2]] - mesh.X[tris[:, 0]]], axis=2)
    dx = np.stack([x[tris[:, 1]] - x[tris[:, 0]], x[tris[:, 2]] - x[tris[:, 0]]], axis=2)
    stretch = np.linalg.svd(dx @ np.linalg.inv(dX), compute_uv=False)[:, 0]
    yc = x[tris].mean(axis=1)[:, 1]
    bands = [(y, (yc >= y) & (yc < y + BAND)) for y in edges]
    torso_stretch = {f"{y:.1f}": float(np.median(stretch[m])) for y, m in bands if m.any()}
    print(
        "largest principal stretch of the torso ring's panels, median by drape height:",
        " ".join(f"{k}:{v:.3f}" for k, v in torso_stretch.items()),
    )
    path = write_results(
        args.out,
        "top_settle",
        {
            "pattern": str(args.pattern),
            "body": name,
            "neck_base_y": nk.base_y,
            "waist_y": m["waist_y"],
            "underarm_y": m["underarm_y"],
            "placed_nearest": float(phi0.min()),
            "placed_seam_gap_max": {f"{p}-{q}": g for (p, q), g in by_pair.items()},
            "residual": float(out.residual),
            "panels": panels,
            "weight": weight,
            "contact_fy_by_band": contact,
            "torso_stretch_by_band": torso_stretch,
        },
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()

"""``couture bench cloth``: timings of the cloth model on a sheet of about N vertices.

Energy, forces, stiffness and dF/dX of :class:`couture.cloth.ClothModel`
(best and median of ``--repeat`` calls), and the cost of building the model
and of the first calls. Run with ``NUMBA_CACHE_DIR`` pointing at an empty
folder to include the numba compile time in the first call. Writes
``cloth.json`` to ``--out``.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from bench import add_out_arg, source_commit, write_results


def run(vertices: int = 10_000, body: bool = False, repeat: int = 20) -> dict:
    """The timings [s and ms] on a grid sheet of about ``vertices`` vertices
    (with a sphere body, contact and friction when ``body``)."""
    t0 = time.perf_counter()
    from couture.cloth import ClothModel, Scene
    from couture.cloth.body import SphereBody
    from couture.mesh import grid_sheet
    from schemas.design import Fabric

    t_import = time.perf_counter() - t0
    side = int(np.sqrt(vertices / 1.15))
    mesh = grid_sheet(1.0, 1.0, side, side)
    scene = Scene(body=SphereBody(np.array([0.5, 0.5, -0.3]), 0.3), friction=True) if body else Scene()
    t0 = time.perf_counter()
    model = ClothModel(mesh, Fabric(), scene)
    t_build = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    x = mesh.x0 + rng.normal(scale=1e-3, size=mesh.x0.shape)
    t0 = time.perf_counter()
    model.energy(x)
    model.forces(x)
    model.stiffness(x)
    model.dforces_dX(x, np.ones((model.n, 2)))
    if body:
        model.update_friction(x)
    t_first = time.perf_counter() - t0

    def best(fn):
        ts = []
        for _ in range(repeat):
            t = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t)
        return min(ts) * 1e3, float(np.median(ts)) * 1e3

    dX = rng.normal(size=(model.n, 2))
    out = {
        "vertices": model.n,
        "triangles": len(mesh.tris),
        "terms": model.terms,
        "nnz": model.stiffness(x).nnz,
        "import_s": t_import,
        "build_model_s (pattern + maps + constant terms)": t_build,
        "first_calls_s (numba compile or cache load)": t_first,
        "energy_ms (min, median)": best(lambda: model.energy(x)),
        "forces_ms": best(lambda: model.forces(x)),
        "stiffness_ms": best(lambda: model.stiffness(x)),
        "energy_and_forces_ms": best(lambda: model.energy_and_forces(x)),
        "dforces_dX_ms": best(lambda: model.dforces_dX(x, dX)),
    }
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench cloth", description=__doc__.split("\n\n")[0])
    add_out_arg(ap)
    ap.add_argument("--vertices", type=int, default=10_000, help="about this many sheet vertices")
    ap.add_argument("--body", action="store_true", help="add a sphere body with contact and friction")
    ap.add_argument("--repeat", type=int, default=20, help="calls per timing (best and median reported)")
    a = ap.parse_args(argv)
    if a.vertices < 4 or a.repeat < 1:
        ap.error(f"--vertices {a.vertices} (at least 4) and --repeat {a.repeat} (at least 1)")
    out = run(a.vertices, a.body, a.repeat)
    for k, v in out.items():
        print(f"{k}: {v}")
    path = write_results(
        a.out, "cloth", {"commit": source_commit(), "settings": vars(a) | {"out": str(a.out)}, "timings": out}
    )
    print(f"wrote {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""``couture bench proxy_use``: the mannequin's ellipsoid proxy where it is used (Meng 2010 §4).

- Try-on drag (couture.tryon.drag) of the default skirt's panels on its fine
  mesh (from the placement), the same drags slid along three bodies: the
  proxy (``guide``; the end pushed out of the grid SDF, as the solver node
  does), the exact mesh distance (TriangleMeshDistance.phi_grad) and the
  grid SDF (B-spline, the solver's contact body). Per drag the median wall
  time of ``--repeats`` runs (bodies interleaved in one process), and the
  penetration of the result into the exact body (mesh distance < 0) and
  into its contact offset layer.
- Picking: rays from cameras around the body at random mannequin points;
  ``pick_body`` (ray against the proxy's ellipsoids) against the
  brute-force ray-triangle cast on the mesh (``ray_hit``): median time per
  ray, hit agreement, exact distance of the picked point to the body, and
  how far before the mesh hit along the ray it lies.

Writes ``proxy_use.json`` to the results folder (``--out``, default bench/results/).
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from bench import add_out_arg, source_commit, write_results

DRAGS = (
    ("gore1", 0.3, -0.03),
    ("gore0", -0.6, 0.0),
    ("gore2", 0.2, 0.05),
    ("gore3", 1.0, -0.1),
)
"""(panel, turn [rad], rise [m]) of the timed drags"""


def _median_ms(f, repeats):
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return 1e3 * float(np.median(ts))


def drag_times(mesh, grid, exact, proxy, repeats: int, offset: float = 0.01) -> list[dict]:
    from couture.tryon import drag, panel_vertices

    ways = {
        "proxy": lambda x, v, t, r: drag(x, v, grid, turn=t, rise=r, offset=offset, guide=proxy),
        "exact": lambda x, v, t, r: drag(x, v, exact, turn=t, rise=r, offset=offset),
        "grid": lambda x, v, t, r: drag(x, v, grid, turn=t, rise=r, offset=offset),
    }
    x0 = mesh.x0
    out = []
    for panel, turn, rise in DRAGS:
        v = panel_vertices(mesh, panel)
        row: dict = {"panel": panel, "turn_rad": turn, "rise_m": rise, "vertices": int(len(v))}
        times: dict[str, list[float]] = {k: [] for k in ways}
        for _ in range(repeats):  # interleaved, so load changes hit every body alike
            for k, f in ways.items():
                times[k].append(_median_ms(lambda f=f, v=v, turn=turn, rise=rise: f(x0, v, turn, rise), 1))
        for k, f in ways.items():
            y = f(x0, v, turn, rise)
            phi = exact(y[v])
            row[k] = {
                "ms": float(np.median(times[k])),
                "exact_phi_min_mm": 1e3 * float(phi.min()),
                "penetration_max_mm": 1e3 * float(max(0.0, -phi.min())),
                "inside_offset_layer": int((phi < offset - 1e-6).sum()),
                "exact_phi_median_mm": 1e3 * float(np.median(phi)),
            }
        row["speedup_proxy_vs_exact"] = row["exact"]["ms"] / row["proxy"]["ms"]
        row["speedup_proxy_vs_grid"] = row["grid"]["ms"] / row["proxy"]["ms"]
        out.append(row)
    return out


def pick_times(V, F, exact, proxy, n: int = 200, seed: int = 0) -> dict:
    from couture.cloth.proxy import mannequin_regions
    from couture.ui.geometry import pick_body, ray_hit

    rng = np.random.default_rng(seed)
    t_pick, t_mesh, sd, gap, agree, both, proxy_only, mesh_only, region = [], [], [], [], 0, 0, 0, 0, 0
    for _ in range(n):
        a = 2 * math.pi * rng.random()
        eye = np.array([2.5 * math.sin(a), rng.uniform(-0.5, 0.8), 2.5 * math.cos(a)])
        d = V[rng.integers(len(V))] + rng.normal(0, 0.02, 3) - eye
        d /= np.linalg.norm(d)
        t0 = time.perf_counter()
        pick = pick_body(eye, d, proxy)
        t1 = time.perf_counter()
        hit = ray_hit(V, F, eye, d)
        t2 = time.perf_counter()
        t_pick.append(t1 - t0)
        t_mesh.append(t2 - t1)
        if pick is not None and hit is not None:
            both += 1
            sd.append(float(exact(pick.point[None])[0]))
            gap.append(hit[1] - pick.t)
            region += int(mannequin_regions((eye + hit[1] * d)[None])[0] == pick.region)
        elif pick is not None:
            proxy_only += 1
        elif hit is not None:
            mesh_only += 1
        else:
            agree += 1
    sd_a, gap_a = np.array(sd), np.array(gap)
    return {
        "rays": n,
        "pick_body_ms_median": 1e3 * float(np.median(t_pick)),
        "ray_triangle_ms_median": 1e3 * float(np.median(t_mesh)),
        "speedup": float(np.median(t_mesh) / np.median(t_pick)),
        "both_hit": both,
        "both_miss": agree,
        "proxy_only": proxy_only,
        "mesh_only": mesh_only,
        "same_region": region,
        "exact_sd_at_pick_min_mm": 1e3 * float(sd_a.min()) if both else None,
        "exact_sd_at_pick_max_mm": 1e3 * float(sd_a.max()) if both else None,
        "exact_sd_at_pick_mean_mm": 1e3 * float(sd_a.mean()) if both else None,
        "ahead_of_mesh_hit_max_mm": 1e3 * float(gap_a.max()) if both else None,
        "ahead_of_mesh_hit_min_mm": 1e3 * float(gap_a.min()) if both else None,
        "ahead_of_mesh_hit_median_mm": 1e3 * float(np.median(gap_a)) if both else None,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench proxy_use", description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=10000, help="skirt mesh size (default %(default)s: the fine level)")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs per drag and body (default %(default)s)")
    ap.add_argument("--rays", type=int, default=200, help="picking rays (default %(default)s)")
    add_out_arg(ap)
    args = ap.parse_args(argv)

    from bench.drape_slopers import coarse_mesh
    from couture.cloth.body import TriangleMeshDistance, load_mannequin_mesh, load_mannequin_sdf
    from couture.cloth.proxy import load_mannequin_proxy

    V, F = load_mannequin_mesh()
    grid = load_mannequin_sdf()
    exact = TriangleMeshDistance(V, F)
    t = time.perf_counter()
    proxy = load_mannequin_proxy()
    load_s = time.perf_counter() - t
    mesh = coarse_mesh("skirt", args.vertices)[2].mesh
    print(f"proxy: {proxy.n_ellipsoids} leaves, loaded in {load_s:.2f} s; skirt {mesh.n_vertices} vertices")
    # warm the kernels (numba) before timing
    drag_times(mesh, grid, exact, proxy, 1)
    drags = drag_times(mesh, grid, exact, proxy, args.repeats)
    for r in drags:
        print(
            f"drag {r['panel']} turn {r['turn_rad']:+.2f} rise {r['rise_m']:+.2f} ({r['vertices']} vertices): "
            + "; ".join(
                f"{k} {r[k]['ms']:.0f} ms, exact phi min {r[k]['exact_phi_min_mm']:.2f} mm "
                f"({r[k]['inside_offset_layer']} in the layer)"
                for k in ("proxy", "exact", "grid")
            )
            + f"; proxy {r['speedup_proxy_vs_exact']:.1f}x faster than exact, {r['speedup_proxy_vs_grid']:.2f}x grid's speed"
        )
    picks = pick_times(V, F, exact, proxy, args.rays)
    print(
        f"picking, {picks['rays']} rays: pick_body {picks['pick_body_ms_median']:.2f} ms, ray-triangle "
        f"{picks['ray_triangle_ms_median']:.2f} ms ({picks['speedup']:.0f}x); both hit {picks['both_hit']}, "
        f"both miss {picks['both_miss']}, proxy only {picks['proxy_only']}, mesh only {picks['mesh_only']}; "
        f"same region {picks['same_region']}; exact distance at the pick {picks['exact_sd_at_pick_min_mm']:.2f} .. "
        f"{picks['exact_sd_at_pick_max_mm']:.2f} mm (mean {picks['exact_sd_at_pick_mean_mm']:.2f}); "
        f"ahead of the mesh hit {picks['ahead_of_mesh_hit_min_mm']:.2f} .. {picks['ahead_of_mesh_hit_max_mm']:.2f} mm "
        f"(median {picks['ahead_of_mesh_hit_median_mm']:.2f}; a ray grazing a limb meets its ellipsoid and the body behind)"
    )
    out = write_results(
        args.out,
        "proxy_use",
        {
            "commit": source_commit(),
            "skirt_vertices": mesh.n_vertices,
            "repeats": args.repeats,
            "proxy_leaves": proxy.n_ellipsoids,
            "proxy_load_s": load_s,
            "drags": drags,
            "picking": picks,
        },
        default=float,
    )
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

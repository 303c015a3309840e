"""``couture bench proxy``: the mannequin's ellipsoid proxy (Meng 2010 §4) against its grid SDF.

- Fit: per region, the number of leaf ellipsoids, the threshold, the maximal
  normal distance (max and mean) from the mesh vertices and from points
  sampled on the triangles, and the overshoot (how far the proxy's surface
  stands out of the body), as the build measured them; plus a check with the
  exact mesh distance: the true signed distance where rays from 5 cm out
  along the vertex normals meet the proxy (``raycast``).
- Queries per 10k points (``phi_grad``), points near the body (within 5 cm
  of its surface) and in its bounding box: proxy (sphere tree), proxy with
  every leaf tried, grid SDF (B-spline).

(Its Verlet contact comparison went with Verlet's mass-spring model: Verlet
now integrates the ClothModel, whose contact is the body's SDF.)

Writes ``proxy.json`` and ``proxy.png`` (the leaf ellipsoids over the body,
front and side) to the results folder (``--out``, default bench/results/).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from bench import add_out_arg, source_commit, write_results


def _best_of(f, repeats=5):
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t)
    return best


def query_times(proxy, grid, V, F, n=10_000, seed=0):
    """Best-of-5 seconds per n points, near the surface and in the bounding box."""
    from couture.cloth.proxy import sample_triangles

    rng = np.random.default_rng(seed)
    S, N = sample_triangles(V, F, per_triangle=n / len(F) + 0.01, seed=seed)
    near = S[:n] + N[:n] * rng.uniform(-0.05, 0.05, (n, 1))
    lo, hi = V.min(axis=0) - 0.05, V.max(axis=0) + 0.05
    box = rng.uniform(lo, hi, (n, 3))
    out = {}
    for name, P in (("near_surface", near), ("bounding_box", box)):
        proxy.phi_grad(P[:10])
        grid.phi_grad(P[:10])
        proxy.phi_grad_brute(P[:10])
        out[name] = {
            "proxy_ms": 1e3 * _best_of(lambda P=P: proxy.phi_grad(P)),
            "proxy_all_leaves_ms": 1e3 * _best_of(lambda P=P: proxy.phi_grad_brute(P), 2),
            "grid_sdf_ms": 1e3 * _best_of(lambda P=P: grid.phi_grad(P)),
        }
    return out


def surface_check(proxy, dist, V, F):
    """How far the proxy's surface lies from the body, by the exact mesh
    distance: rays from 5 cm out along each vertex normal back towards the
    vertex, where they meet the proxy (picking); and the proxy's phi at the
    vertices (<= 0: the body is inside the proxy)."""
    from couture.cloth.proxy import vertex_normals

    N = vertex_normals(V, F)
    hit, t, q, _, _ = proxy.raycast(V + 0.05 * N, -N)
    started_inside = hit & (t == 0)
    ok = hit & ~started_inside
    d = dist(q[ok])
    return {
        "rays": int(len(V)),
        "rays_starting_inside_proxy": int(started_inside.sum()),
        "true_sd_at_proxy_hit_max_m": float(d.max()),
        "true_sd_at_proxy_hit_mean_m": float(d.mean()),
        "true_sd_at_proxy_hit_min_m": float(d.min()),
        "proxy_phi_at_vertices_max_m": float(proxy.phi_grad(V)[0].max()),
    }


def plot(proxy, V, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Ellipse

    from couture.cloth.proxy import region_class

    colours = {"torso": "tab:blue", "legs": "tab:green", "arms": "tab:orange", "head": "tab:red"}
    fig, axes = plt.subplots(1, 2, figsize=(10, 8.5))
    for ax, (h, v, title) in zip(axes, ((0, 1, "front (x, y)"), (2, 1, "side (z, y)")), strict=True):
        ax.scatter(V[:, h], V[:, v], s=0.2, c="0.6", lw=0)
        for k in range(proxy.n_ellipsoids):
            # the outline of the ellipsoid's projection onto the view plane
            R, a, c = proxy.rot[k], proxy.radii[k], proxy.centers[k]
            P = np.array([[1.0 if h == 0 else 0, 0, 1.0 if h == 2 else 0], [0, 1.0, 0]])
            M = P @ R @ np.diag(a**2) @ R.T @ P.T  # projected shape matrix
            w, U = np.linalg.eigh(M)
            ang = np.degrees(np.arctan2(U[1, 1], U[0, 1]))
            ax.add_patch(
                Ellipse(
                    (c[h], c[v]),
                    2 * np.sqrt(w[1]),
                    2 * np.sqrt(w[0]),
                    angle=ang,
                    fill=False,
                    lw=0.3,
                    color=colours.get(region_class(proxy.regions[k]), "k"),
                    alpha=0.6,
                )
            )
        ax.set_aspect("equal")
        ax.set_title(title)
        ax.set_xlabel("[m]")
    fig.suptitle(f"mannequin ellipsoid proxy: {proxy.n_ellipsoids} leaves (colour: region)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="couture bench proxy", description=__doc__.splitlines()[0])
    ap.add_argument("--rebuild", action="store_true", help="build the proxy now (timed) instead of loading the cache")
    add_out_arg(ap)
    args = ap.parse_args(argv)

    from couture.cloth.body import TriangleMeshDistance, load_mannequin_mesh, load_mannequin_sdf
    from couture.cloth.proxy import DEFAULT_THRESHOLDS, build_mannequin_proxy, load_mannequin_proxy

    V, F = load_mannequin_mesh()
    grid = load_mannequin_sdf()
    t = time.perf_counter()
    proxy = build_mannequin_proxy() if args.rebuild else load_mannequin_proxy()
    build_s = time.perf_counter() - t
    dist = TriangleMeshDistance(V, F)
    regions = proxy.region_stats()
    print(
        f"{proxy.n_ellipsoids} leaf ellipsoids ({len(proxy.nodes)} nodes); {'built' if args.rebuild else 'loaded'} in {build_s:.1f} s"
    )
    print(
        f"{'region':7} {'thr mm':>6} {'leaves':>6} {'unmet':>5} {'MND v max':>9} {'v mean':>6} "
        f"{'MND s max':>9} {'s mean':>6} {'over mm':>7}"
    )
    for name, r in sorted(regions.items()):
        print(
            f"{name:7} {1e3 * r['threshold_m']:6.1f} {r['n_ellipsoids']:6d} {r['unmet']:5d} "
            f"{1e3 * r['mnd_vertex_max_m']:9.1f} {1e3 * r['mnd_vertex_mean_m']:6.1f} "
            f"{1e3 * r['mnd_sample_max_m']:9.1f} {1e3 * r['mnd_sample_mean_m']:6.1f} {1e3 * r['overshoot_max_m']:7.1f}"
        )
    check = surface_check(proxy, dist, V, F)
    print(
        f"exact-distance check: rays 5 cm out along the vertex normals meet the proxy at true distance "
        f"min {1e3 * check['true_sd_at_proxy_hit_min_m']:.1f} / mean {1e3 * check['true_sd_at_proxy_hit_mean_m']:.1f} / "
        f"max {1e3 * check['true_sd_at_proxy_hit_max_m']:.1f} mm ({check['rays_starting_inside_proxy']} of "
        f"{check['rays']} start inside it); proxy phi at the vertices <= {1e3 * check['proxy_phi_at_vertices_max_m']:.2g} mm"
    )
    qt = query_times(proxy, grid, V, F)
    for k, v in qt.items():
        print(f"phi_grad per 10k points, {k}: " + ", ".join(f"{a} {b:.2f}" for a, b in v.items()))
    out = write_results(
        args.out,
        "proxy",
        {
            "commit": source_commit(),
            "thresholds_m": DEFAULT_THRESHOLDS,
            "n_ellipsoids": proxy.n_ellipsoids,
            "n_nodes": len(proxy.nodes),
            "build_or_load_s": build_s,
            "built": args.rebuild,
            "regions": regions,
            "exact_distance_check": check,
            "query_per_10k": qt,
        },
        default=float,
    )
    png = Path(args.out) / "proxy.png"
    plot(proxy, V, png)
    print(f"wrote {out} and {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

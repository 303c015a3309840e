"""Cuttability checks and export of adjusted patterns.

Seam lengths: the seam springs of a :class:`~couture.mesh.GarmentMesh` tie
each emitter vertex to a point on a receiver edge. For two springs whose
emitters share a boundary edge, that edge's length in the pattern and the
distance between their two receiver points are the two sides' lengths of the
same piece of seam; summed per (emitter panel, receiver panel) they give each
seam's two lengths. A pattern is sewable without gathers when they match
(the drafted patterns match by construction, to the chord error of the
receiver polyline).

Export: a panel's outline is its mesh boundary loop in the adjusted rest
positions (the longest loop; the others are holes), so the adjusted pattern
goes out through the same DXF/SVG/PDF writers as a drafted one.
"""

from __future__ import annotations

import numpy as np

from couture.mesh import GarmentMesh
from couture.pattern.drafted import DraftedPattern, Panel


def vertex_panels(mesh: GarmentMesh) -> np.ndarray:
    vp = np.full(mesh.n_vertices, -1, np.int64)
    vp[mesh.tris.ravel()] = np.repeat(mesh.tri_panel, 3)
    return vp


def boundary_edges(tris: np.ndarray) -> np.ndarray:
    """Directed boundary edges (a, b) of a triangle mesh (counter-clockwise triangles:
    the outline runs counter-clockwise, holes clockwise)."""
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return e[cnt[inv.ravel()] == 1]


def seam_lengths(mesh: GarmentMesh, X: np.ndarray) -> list[dict]:
    """Per seam (emitter panel -> receiver panel): both sides' lengths [m] in
    pattern X and their difference."""
    if not len(mesh.seam_emitters):
        return []
    vp = vertex_panels(mesh)
    em = mesh.seam_emitters
    P = (1.0 - mesh.seam_weights)[:, None] * X[mesh.seam_edges[:, 0]] + mesh.seam_weights[:, None] * X[
        mesh.seam_edges[:, 1]
    ]
    spring_of = {int(v): i for i, v in enumerate(em)}
    acc: dict[tuple[str, str], list[float]] = {}
    for a, b in boundary_edges(mesh.tris):
        i, j = spring_of.get(int(a)), spring_of.get(int(b))
        if i is None or j is None:
            continue
        ra, rb = vp[mesh.seam_edges[i, 0]], vp[mesh.seam_edges[j, 0]]
        if ra != rb:
            continue  # the two springs land on different panels: no piece of one seam
        names = mesh.panel_names
        key = (names[vp[a]] if names else str(vp[a]), names[ra] if names else str(ra))
        s = acc.setdefault(key, [0.0, 0.0])
        s[0] += float(np.linalg.norm(X[a] - X[b]))
        s[1] += float(np.linalg.norm(P[i] - P[j]))
    return [
        {
            "emitter_panel": k[0],
            "receiver_panel": k[1],
            "emitter_m": v[0],
            "receiver_m": v[1],
            "mismatch_m": v[0] - v[1],
        }
        for k, v in sorted(acc.items())
    ]


EASE_MIN = 0.002
"""[m] two sides of a seam differing by less than this in the source pattern are drafted equal"""


def seam_ease(mesh: GarmentMesh, X: np.ndarray) -> dict[tuple[str, str], float]:
    """Per seam (emitter panel, receiver panel): emitter length / receiver
    length in pattern X, the ease a pattern maker drafted into it (a set-in
    sleeve's cap is longer than its armhole: the shirt's by 43 mm, 23 %);
    1 where the two sides differ by less than :data:`EASE_MIN` (the mesh's
    own discretization of two equal drafted lines: 0.03 mm on the skirt)."""
    return {
        (s["emitter_panel"], s["receiver_panel"]): (
            s["emitter_m"] / s["receiver_m"] if abs(s["mismatch_m"]) >= EASE_MIN else 1.0
        )
        for s in seam_lengths(mesh, X)
    }


def max_seam_mismatch(mesh: GarmentMesh, X: np.ndarray, reference: np.ndarray | None = None) -> float:
    """[m] the largest |emitter - receiver| length over the seams of X; with
    ``reference`` (a pattern of the same mesh: the source), the largest
    |emitter - ease × receiver|, the ease being the reference's ratio
    (:func:`seam_ease`): how far X is from keeping the drafted ease."""
    ease = {} if reference is None else seam_ease(mesh, reference)
    return max(
        (
            abs(s["emitter_m"] - ease.get((s["emitter_panel"], s["receiver_panel"]), 1.0) * s["receiver_m"])
            for s in seam_lengths(mesh, X)
        ),
        default=0.0,
    )


def _loops(edges: np.ndarray) -> list[list[int]]:
    nxt = {int(a): int(b) for a, b in edges}
    loops, seen = [], set()
    for start in nxt:
        if start in seen:
            continue
        loop, v = [], start
        while v not in seen:
            seen.add(v)
            loop.append(v)
            v = nxt[v]
        loops.append(loop)
    return loops


def _signed_area(P: np.ndarray) -> float:
    return 0.5 * float(np.sum(P[:, 0] * np.roll(P[:, 1], -1) - np.roll(P[:, 0], -1) * P[:, 1]))


def panel_outlines(mesh: GarmentMesh, X: np.ndarray) -> list[Panel]:
    """One :class:`Panel` per mesh panel: outline (counter-clockwise) and holes
    (clockwise) from the boundary loops in X."""
    out = []
    for p in range(int(mesh.tri_panel.max()) + 1 if len(mesh.tri_panel) else 0):
        tp = mesh.tris[mesh.tri_panel == p]
        if not len(tp):
            continue
        loops = [X[np.asarray(lp)] for lp in _loops(boundary_edges(tp))]
        loops.sort(key=lambda L: -abs(_signed_area(L)))
        outline = loops[0] if _signed_area(loops[0]) > 0 else loops[0][::-1]
        holes = [L if _signed_area(L) < 0 else L[::-1] for L in loops[1:]]
        name = mesh.panel_names[p] if p < len(mesh.panel_names) else f"panel{p}"
        out.append(Panel(name=name, outline=outline.copy(), holes=holes))
    return out


def drafted_from_mesh(mesh: GarmentMesh, X: np.ndarray) -> DraftedPattern:
    """The pattern X as a :class:`DraftedPattern` (outlines and holes; no seam specs), for the exporters."""
    return DraftedPattern(panels=panel_outlines(mesh, X))


def mirror_asymmetry(mesh: GarmentMesh, X: np.ndarray, x_drape: np.ndarray, *, max_gap: float = 0.01) -> list[dict]:
    """How far pattern X is from left-right symmetric, judged through a drape
    on the symmetric mannequin (plane x = 0): each vertex's mirror image on
    the drape lands in some panel (itself for a panel on the plane, like a
    dress front; its partner for a side panel); its pattern point there (by
    barycentric coordinates) is where a symmetric pattern has the vertex's
    mirror. Per panel: the partner, and the RMS and largest distance [m]
    left after the best reflection plus rigid motion maps the panel's
    vertices onto those points. On the source pattern these are the drape's
    and mesh's own asymmetry (the baseline); vertices whose mirror image is
    more than ``max_gap`` from the drape are left out."""
    from .geometry import SurfaceDistance

    vp = vertex_panels(mesh)
    names = list(mesh.panel_names) or [str(i) for i in range(int(vp.max()) + 1)]
    surf = SurfaceDistance(x_drape, mesh.tris)
    out = []
    for p in range(len(names)):
        v = np.nonzero(vp == p)[0]
        q, d, f = surf.closest(x_drape[v] * np.array([-1.0, 1.0, 1.0]))
        fp = mesh.tri_panel[f]
        partner = int(np.bincount(fp).argmax())
        ok = (fp == partner) & (d < max_gap)
        if ok.sum() < 3:
            continue
        v, q, f = v[ok], q[ok], f[ok]
        tri = mesh.tris[f]
        a, b, c = x_drape[tri[:, 0]], x_drape[tri[:, 1]], x_drape[tri[:, 2]]
        # barycentric coordinates of q in its face
        v0, v1, v2 = b - a, c - a, q - a
        d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
        d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
        den = d00 * d11 - d01 * d01
        w1 = (d11 * d20 - d01 * d21) / den
        w2 = (d00 * d21 - d01 * d20) / den
        Y = (1 - w1 - w2)[:, None] * X[tri[:, 0]] + w1[:, None] * X[tri[:, 1]] + w2[:, None] * X[tri[:, 2]]
        P = X[v]
        cp, cy = P.mean(0), Y.mean(0)
        U, _, Vt = np.linalg.svd((P - cp).T @ (Y - cy))
        D = np.diag([1.0, -np.sign(np.linalg.det(U @ Vt))])  # the best reflection (det -1): a mirror image
        R = (U @ D @ Vt).T
        r = np.linalg.norm((P - cp) @ R.T + cy - Y, axis=1)
        out.append(
            {
                "panel": names[p],
                "partner": names[partner],
                "vertices": int(len(v)),
                "rms_m": float(np.sqrt((r**2).mean())),
                "max_m": float(r.max()),
            }
        )
    return out


def equalize_seams(
    mesh: GarmentMesh, X: np.ndarray, iters: int = 30, reference: np.ndarray | None = None, passes: int = 50
) -> np.ndarray:
    """Make both sides of every seam equally long, or, with ``reference`` (a
    pattern of the same mesh: the source), keep its ease (emitter length =
    the reference's ratio × receiver length, :func:`seam_ease`; equalizing
    would take a set-in sleeve's eased cap away): each side's vertices are
    scaled about their centroid to its new length (the two keep their mean
    length), then the panels are re-embedded (ARAP, the seam vertices held
    there, each triangle's own current shape as reference), so the rest of
    each panel follows with the least distortion. Returns the new pattern (n, 2)."""
    from .geometry import Embedding, edges2

    seams = seam_lengths(mesh, X)
    if not seams:
        return X.copy()
    ease = {} if reference is None else seam_ease(mesh, reference)
    vp = vertex_panels(mesh)
    names = list(mesh.panel_names) or [str(i) for i in range(int(vp.max()) + 1)]
    pid = {n: i for i, n in enumerate(names)}
    recv_panel = vp[mesh.seam_edges[:, 0]]
    out = X.copy()
    held: list[np.ndarray] = []
    # a corner shared by two seams (a sleeve's underarm and cap) is scaled by
    # both: sweep until every seam has its length (a few sweeps)
    for sweep in range(passes):
        if sweep:
            seams = seam_lengths(mesh, out)
        worst = 0.0
        for s in seams:
            ep, rp = pid[s["emitter_panel"]], pid[s["receiver_panel"]]
            sel = (vp[mesh.seam_emitters] == ep) & (recv_panel == rp)
            rho = ease.get((s["emitter_panel"], s["receiver_panel"]), 1.0)
            worst = max(worst, abs(s["emitter_m"] - rho * s["receiver_m"]))
            recv = (s["emitter_m"] + s["receiver_m"]) / (1.0 + rho)
            for verts, length, target in (
                (np.unique(mesh.seam_emitters[sel]), s["emitter_m"], rho * recv),
                (np.unique(mesh.seam_edges[sel]), s["receiver_m"], recv),
            ):
                c = out[verts].mean(axis=0)
                out[verts] = c + (out[verts] - c) * (target / length)
                if not sweep:
                    held.append(verts)
        if worst < 1e-12:
            break
    hold = np.unique(np.concatenate(held))
    emb = Embedding(mesh.tris, edges2(X, mesh.tris), mesh.n_vertices, hold=hold)
    return emb.run(out, iters=iters)

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


def max_seam_mismatch(mesh: GarmentMesh, X: np.ndarray) -> float:
    """[m] the largest |emitter - receiver| length over the seams of X."""
    return max((abs(s["mismatch_m"]) for s in seam_lengths(mesh, X)), default=0.0)


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


def mirror_pairs(mesh: GarmentMesh, x: np.ndarray) -> list[tuple[str, str]]:
    """Panels that mirror each other across the body's plane of symmetry
    (x = 0) in drape x: each panel paired with the one whose mirrored area
    centroid is nearest (itself for a panel that straddles the plane; those are left out)."""
    names = list(mesh.panel_names) or [str(i) for i in range(int(mesh.tri_panel.max()) + 1)]
    c = np.array([x[mesh.tris[mesh.tri_panel == p]].mean(axis=(0, 1)) for p in range(len(names))])
    mirrored = c * np.array([-1.0, 1.0, 1.0])
    pairs = set()
    for p in range(len(names)):
        q = int(np.argmin(np.linalg.norm(c - mirrored[p], axis=1)))
        if q != p:
            pairs.add((names[min(p, q)], names[max(p, q)]))
    return sorted(pairs)


def panel_symmetry(mesh: GarmentMesh, X: np.ndarray, pairs: list[tuple[str, str]]) -> dict:
    """Whether mirror panels stay mirror images: per pair the relative
    difference of their areas and the difference of their perimeters [m]
    (both 0 for congruent panels), and the largest of each."""
    by = {p.name: p for p in panel_outlines(mesh, X)}

    def area(p: Panel) -> float:
        return abs(_signed_area(p.outline)) - sum(abs(_signed_area(h)) for h in p.holes)

    def perimeter(p: Panel) -> float:
        return float(np.linalg.norm(p.outline - np.roll(p.outline, 1, axis=0), axis=1).sum())

    rows = []
    d_area: list[float] = []
    d_per: list[float] = []
    for a, b in pairs:
        pa, pb = by[a], by[b]
        d_area.append(abs(area(pa) - area(pb)) / max(area(pa), area(pb)))
        d_per.append(abs(perimeter(pa) - perimeter(pb)))
        rows.append({"panels": [a, b], "area_diff_rel": d_area[-1], "perimeter_diff_m": d_per[-1]})
    return {
        "pairs": rows,
        "max_area_diff_rel": max(d_area, default=0.0),
        "max_perimeter_diff_m": max(d_per, default=0.0),
    }


def equalize_seams(mesh: GarmentMesh, X: np.ndarray, iters: int = 30) -> np.ndarray:
    """Make both sides of every seam equally long: each side's vertices are
    scaled about their centroid to the mean of the two lengths, then the
    panels are re-embedded (ARAP, the seam vertices held there, each
    triangle's own current shape as reference), so the rest of each panel
    follows with the least distortion. Returns the new pattern (n, 2)."""
    from .geometry import Embedding, edges2

    seams = seam_lengths(mesh, X)
    if not seams:
        return X.copy()
    vp = vertex_panels(mesh)
    names = list(mesh.panel_names) or [str(i) for i in range(int(vp.max()) + 1)]
    pid = {n: i for i, n in enumerate(names)}
    recv_panel = vp[mesh.seam_edges[:, 0]]
    out = X.copy()
    held: list[np.ndarray] = []
    for s in seams:
        ep, rp = pid[s["emitter_panel"]], pid[s["receiver_panel"]]
        sel = (vp[mesh.seam_emitters] == ep) & (recv_panel == rp)
        target = 0.5 * (s["emitter_m"] + s["receiver_m"])
        for verts, length in (
            (np.unique(mesh.seam_emitters[sel]), s["emitter_m"]),
            (np.unique(mesh.seam_edges[sel]), s["receiver_m"]),
        ):
            c = X[verts].mean(axis=0)
            out[verts] = c + (X[verts] - c) * (target / length)
            held.append(verts)
    hold = np.unique(np.concatenate(held))
    emb = Embedding(mesh.tris, edges2(X, mesh.tris), mesh.n_vertices, hold=hold)
    return emb.run(out, iters=iters)

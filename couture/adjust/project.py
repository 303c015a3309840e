"""The adjusted pattern as a design: the sloper options whose drafted pattern
comes closest to it.

Pattern adjustment (:mod:`couture.adjust.fixed_point`) returns new rest
positions for every mesh vertex; a design (``couture/design/v1``) is a sloper
and its options plus strokes. To make the adjusted pattern the current design
its panels' outlines are fitted by the sloper's continuous options, Gauss-
Newton (chord: Ψ kept from the first step) on the boundary vertices of the
remesher's mesh:

    min over dq, per panel (t, w):  Σ_boundary |X(q) + Ψ dq + t + w × (X - c) - X_adj|²
                                    + λ Σ_k (dq_k / range_k)²

``Ψ`` the motion of every mesh vertex per unit change of each option (the
remesher's Ψ, the same one a drag uses, SC §6), and one small rigid motion
per panel (a translation ``t`` and a turn ``w`` about its centroid ``c``),
since adjustment places each panel anywhere in the plane. Options stay in
their [min, max]; the remesher follows the mesh to the new options (same
vertices) for the next step. Whole-number options (topology) and strokes stay
as they are. What the options cannot express is reported as the RMS and
largest boundary distance left (``fit_rms_m``, ``fit_max_m``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import msgspec
import numpy as np

from couture.mesh import GarmentMesh
from schemas.design import Design

from .fixed_point import align_panels
from .seams import boundary_edges
from .target import MaterialLoop


@dataclass
class Projection:
    design: Design
    """the source design with the fitted options"""
    changed: dict[str, tuple[float, float]] = field(default_factory=dict)
    """option -> (before, after) for the options that moved more than 0.1 mm (or 1e-4 of their range)"""
    fit_rms_m: float = 0.0
    """[m] RMS distance between the fitted design's and the adjusted pattern's boundary vertices"""
    fit_max_m: float = 0.0
    """[m] the largest such distance"""
    start_rms_m: float = 0.0
    """[m] the same RMS for the source design (what the fit had to explain)"""
    steps: int = 0
    mesh: GarmentMesh | None = None
    """the fitted design's mesh, the adjusted one's vertices followed to the
    fitted options (None where the remesher had to mesh anew)"""
    scale: float = 1.0
    """the fitted option changes were scaled by this afterwards (a hem edit's
    correction on the drape, :func:`couture.adjust.service.scaled`)"""
    loop_m: tuple[float, float, float] | None = None
    """[m] with a loop to honour: its cloth length in the source pattern, the
    adjusted pattern (the goal) and the fitted design"""


def _continuous_options(design: Design) -> list:
    from couture.pattern.draft import sloper_of

    return [o for o in sloper_of(design).options if not o.integer]


def _with_options(design: Design, values: dict[str, float]) -> Design:
    params = dict(design.sloper.params)
    params.update({k: float(v) for k, v in values.items()})
    return msgspec.structs.replace(design, sloper=msgspec.structs.replace(design.sloper, params=params))


def project_to_design(
    design: Design,
    mesh: GarmentMesh,
    X_adj: np.ndarray,
    *,
    vertices: int | None = None,
    weights: np.ndarray | None = None,
    loop: MaterialLoop | None = None,
    loop_length: float | None = None,
    steps: int = 3,
    damping: float = 1e-4,
) -> Projection:
    """Fit ``design``'s continuous sloper options to the adjusted rest
    positions ``X_adj`` of ``mesh``: ``garment_mesh(design, vertices)``
    (:func:`couture.adjust.pipeline.garment_mesh`), vertex for vertex. The
    returned design keeps ``design``'s resolution."""
    from couture.remesh.service import RemeshService

    from .pipeline import at_resolution

    source = design
    design = at_resolution(design, vertices)

    X_adj = np.asarray(X_adj, np.float64)
    if X_adj.shape != mesh.X.shape or not np.isfinite(X_adj).all():
        raise ValueError(f"adjusted pattern of shape {X_adj.shape}: expected finite values of shape {mesh.X.shape}")
    opts = _continuous_options(design)
    if not opts:
        raise ValueError(f"sloper {design.sloper.kind!r} has no continuous option to fit")
    values = {o.name: float(design.sloper.params.get(o.name, o.default)) for o in opts}
    lo = np.array([o.min for o in opts])
    hi = np.array([o.max for o in opts])
    scale = np.maximum(hi - lo, 1e-9)
    bnd = np.unique(boundary_edges(mesh.tris).ravel())
    vp = np.full(mesh.n_vertices, -1, np.int64)
    vp[mesh.tris.ravel()] = np.repeat(mesh.tri_panel, 3)
    panels = np.unique(vp[bnd])
    w = np.ones(len(bnd)) if weights is None else np.asarray(weights, np.float64)[bnd]
    if not (np.isfinite(w).all() and (w >= 0).all() and w.sum() > 0):
        raise ValueError("fit weights must be finite, non-negative and not all zero")
    sw = np.repeat(np.sqrt(w), 2)  # one row per coordinate
    service = RemeshService()
    service.set_design(_with_options(design, values), 1)
    X = service.levels["coarse"].mesh.X
    if X.shape != mesh.X.shape:
        raise ValueError("the design's coarse mesh differs from the adjusted mesh: mesh it as garment_mesh does")
    target = align_panels(X_adj, X, mesh.tris, mesh.tri_panel)
    start = float(np.sqrt(((target[bnd] - X[bnd]) ** 2).sum(axis=1).mean()))
    # Ψ at the source design only (a chord method): drafting each option's
    # Jacobian is the cost here, and the outlines are close to linear in the options
    # Ψ (n, 2, 2) of every vertex, column 0: per unit option change
    psi = [service.psi_for(f"param:{o.name}")["coarse"][:, :, 0] for o in opts]
    A_opt = np.column_stack([P[bnd].ravel() for P in psi])
    if loop is not None:
        loop_goal = loop.length(X_adj) if loop_length is None else float(loop_length)
        loop_start = loop.length(X)
    k = 0
    for k in range(1, steps + 1):
        rigid = []
        for p in panels:
            on = vp[bnd] == p
            c = X[bnd][on].mean(axis=0)
            for vec in ((1.0, 0.0), (0.0, 1.0)):
                col = np.zeros((len(bnd), 2))
                col[on] = vec
                rigid.append(col.ravel())
            col = np.zeros((len(bnd), 2))
            d = X[bnd][on] - c
            col[on] = np.column_stack([-d[:, 1], d[:, 0]])
            rigid.append(col.ravel())
        A = np.column_stack([A_opt / scale, *rigid]) * sw[:, None]  # options in fractions of their range
        r = (target[bnd] - X[bnd]).ravel() * sw
        lam = damping * float(np.trace(A.T @ A)) / A.shape[1]
        reg = np.zeros(A.shape[1])
        reg[: len(opts)] = lam
        H, b = A.T @ A + np.diag(reg + 1e-12 * lam), A.T @ r
        if loop is None:
            sol = np.linalg.solve(H, b)
        else:
            # the loop's cloth length as a linearized equality: c · sol = goal - length(X)
            g = loop.gradient(X)
            c = np.zeros(A.shape[1])
            c[: len(opts)] = [float((g * P).sum()) * sc for P, sc in zip(psi, scale, strict=True)]
            if not np.any(c):
                raise ValueError(
                    f"no continuous option of {design.sloper.kind!r} changes the cloth at y = {loop.y0:.3f} m"
                )
            K = np.block([[H, c[:, None]], [c[None, :], np.zeros((1, 1))]])
            sol = np.linalg.solve(K, np.append(b, loop_goal - loop.length(X)))[:-1]
        q = np.array([values[o.name] for o in opts]) + sol[: len(opts)] * scale
        q = np.clip(q, lo, hi)
        values = {o.name: float(v) for o, v in zip(opts, q, strict=False)}
        ups = service.set_design(_with_options(design, values), 1 + k)
        X = service.levels["coarse"].mesh.X
        if ups[0].how == "new" or X.shape != mesh.X.shape:
            break  # remeshed: vertices no longer correspond; keep these options
        target = align_panels(X_adj, X, mesh.tris, mesh.tri_panel)
        if np.abs(sol[: len(opts)]).max() < 1e-5:
            break
    d = np.linalg.norm(target[bnd] - X[bnd], axis=1) if X.shape == mesh.X.shape else np.full(1, np.nan)
    before = {o.name: float(design.sloper.params.get(o.name, o.default)) for o in opts}
    changed = {
        o.name: (before[o.name], values[o.name])
        for o in opts
        if abs(values[o.name] - before[o.name]) > max(1e-4, 1e-4 * (o.max - o.min))
    }
    return Projection(
        design=_with_options(source, {n: v for n, (_, v) in changed.items()}),
        changed=changed,
        fit_rms_m=float(np.sqrt((d**2).mean())),
        fit_max_m=float(d.max()),
        start_rms_m=start,
        steps=k,
        mesh=service.levels["coarse"].mesh if X.shape == mesh.X.shape else None,
        loop_m=None
        if loop is None
        else (loop_start, loop_goal, loop.length(X) if X.shape == mesh.X.shape else float("nan")),
    )

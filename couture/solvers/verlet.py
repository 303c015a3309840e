"""Fast mass-spring solver, Meng et al. 2010 style: the speed end of the trade.

Its own model, derived from the same GarmentMesh and fabric as the ClothModel:
Hookean stretch springs on mesh edges (k = E·h · (area next to the edge) / L²,
so a uniformly stretched patch has about the membrane stiffness), bending
springs between the two vertices opposite each interior edge (rest length
from the flat pattern; k from the fabric's bending stiffness, matched to the
isometric bending energy at a 1-radian fold), real lumped masses for gravity.

Integration (Jakobsen's game-physics Verlet, Meng's [38]): Stoermer-Verlet
with real masses and a real time step ``x' = x + keep (x - x_prev) + dt² f / m``
(f: gravity and bending springs; dt inside the explicit bound of the bending
springs), then Gauss-Seidel projection of the edge lengths (stretch springs as
near-rigid distance constraints, ``stretch_iters`` sweeps a step), seams as
zero-length constraints (PBD), body contact as projection out of the body's
SDF (``model.body.phi_grad``) to the contact offset, pins held. Kinetic
damping (velocity zeroed at kinetic-energy peaks) on top of light viscous
damping. Stationarity measure ("own residual"): ||M Δx|| / (dt² ||F_gravity||)
per step, which at a steady state equals the unbalanced force over (1 - keep).

It converges to its spring model's equilibrium, not to the StVK one: the
result carries the ClothModel's relative residual at that point so accuracy is
comparable across solvers; ``stats['own_residual']`` is the spring model's.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from . import kernels
from .base import ProgressCallback, SolveResult
from .common import bad_start, finite, pinned_positions

# ½ k_s (d0 (1 - cos ½))² = ½ k_b 3|e|²/(A0+A1) · c · 1² at a 1-rad fold (c = 8/27, the model's constant)
_FOLD = 1.0 - np.cos(0.5)


def _topology(tris: np.ndarray):
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1).astype(np.int64)
    opp = np.concatenate([tris[:, 2], tris[:, 0], tris[:, 1]]).astype(np.int64)
    tid = np.tile(np.arange(len(tris)), 3)
    key = e[:, 0] * (int(tris.max()) + 1) + e[:, 1]
    order = np.argsort(key, kind="stable")
    ks = key[order]
    start = np.r_[0, np.nonzero(np.diff(ks))[0] + 1]
    count = np.diff(np.r_[start, len(ks)])
    edges = e[order[start]]
    edge_tris = [tid[order[start]], np.where(count == 2, tid[order[np.minimum(start + 1, len(ks) - 1)]], -1)]
    two = count == 2
    hinge_edges = edges[two]
    hinge_opp = np.column_stack([opp[order[start[two]]], opp[order[start[two] + 1]]])
    return edges, np.column_stack(edge_tris), hinge_edges, hinge_opp


class SpringModel:
    """The Verlet solver's own mass-spring model of a ClothModel's mesh and fabric."""

    def __init__(self, model):
        mesh = model.mesh
        X = mesh.X
        tris = mesh.tris
        fab = model.fabric
        stretch = float(fab.stretch_stiffness)
        bend = float(fab.bend_stiffness)
        e1 = X[tris[:, 1]] - X[tris[:, 0]]
        e2 = X[tris[:, 2]] - X[tris[:, 0]]
        area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        edges, etris, hedges, hopp = _topology(tris)
        L = np.linalg.norm(X[edges[:, 1]] - X[edges[:, 0]], axis=1)
        a_e = area[etris[:, 0]] / 3.0 + np.where(etris[:, 1] >= 0, area[np.maximum(etris[:, 1], 0)] / 3.0, 0.0)
        k_s = 2.0 * stretch * a_e / np.maximum(L, 1e-12) ** 2
        d0 = np.linalg.norm(X[hopp[:, 1]] - X[hopp[:, 0]], axis=1)
        le = np.linalg.norm(X[hedges[:, 1]] - X[hedges[:, 0]], axis=1)
        # the two triangles of each hinge: area ≈ ½ |e| d0 (opposite vertices on both sides)
        a_h = np.maximum(0.5 * le * d0, 1e-300)
        k_b = bend * (8.0 / 27.0) * 3.0 * le**2 / a_h / np.maximum(d0 * _FOLD, 1e-12) ** 2
        self.sp_i = np.ascontiguousarray(np.r_[edges[:, 0], hopp[:, 0]], np.int64)
        self.sp_j = np.ascontiguousarray(np.r_[edges[:, 1], hopp[:, 1]], np.int64)
        self.sp_rest = np.ascontiguousarray(np.r_[L, d0])
        self.sp_k = np.ascontiguousarray(np.r_[k_s, k_b])
        self.n_stretch = len(edges)
        n = model.n
        ksum = np.zeros(n)
        np.add.at(ksum, self.sp_i, self.sp_k)
        np.add.at(ksum, self.sp_j, self.sp_k)
        self.m_fict = np.maximum(ksum, 1e-12 * max(ksum.max(), 1e-300))
        self.f_gravity = np.asarray(getattr(model, "gravity_force", np.zeros((n, 3))), np.float64)
        self.free = np.ascontiguousarray(model.free, bool)
        self.seam_e = np.ascontiguousarray(mesh.seam_emitters, np.int64)
        self.seam_a = np.ascontiguousarray(mesh.seam_edges[:, 0], np.int64)
        self.seam_b = np.ascontiguousarray(mesh.seam_edges[:, 1], np.int64)
        self.seam_w = np.ascontiguousarray(mesh.seam_weights, np.float64)

    def forces(self, x: np.ndarray) -> np.ndarray:
        f = self.f_gravity.copy()
        kernels.spring_forces(x, self.sp_i, self.sp_j, self.sp_rest, self.sp_k, f)
        return f


class VerletSolver:
    name = "verlet"

    def __init__(
        self,
        *,
        keep: float = 0.99,
        dt: float | None = None,
        stretch_iters: int = 8,
        seam_iters: int = 4,
        check_every: int = 5,
        contact: str = "sdf",
        proxy_blend: float = 0.005,
    ):
        """keep: velocity retained per step (1 - viscous damping); dt [s]: time
        step (None: 0.5 of the bending springs' explicit bound, at most 20 ms);
        stretch_iters, seam_iters: projection sweeps per step; check_every: steps
        between convergence checks; contact: what the cloth is projected out of,
        'sdf' (the model's body) or 'proxy' (Meng's ellipsoid hierarchy of the
        mannequin, couture.cloth.proxy; a body that is not the mannequin is used
        as it is); proxy_blend [m]: the proxy's smooth min, which rounds the
        creases where its ellipsoids meet (with 0 the drape does not settle:
        vertices in a crease are pushed along one ellipsoid's normal, then the
        other's)."""
        if contact not in ("sdf", "proxy"):
            raise ValueError(f"unknown contact {contact!r}; use 'sdf' or 'proxy'")
        self.contact = contact
        self.proxy_blend = proxy_blend
        self.keep = keep
        self.dt = dt
        self.stretch_iters = stretch_iters
        self.seam_iters = seam_iters
        self.check_every = check_every
        self._cache: tuple[Any, SpringModel] | None = None
        """(the model, its springs) of the last solve"""

    def contact_body(self, model):
        """The body the cloth is projected out of (None: no body)."""
        body = getattr(model, "body", None)
        if body is None or self.contact == "sdf":
            return body
        scene = getattr(model, "scene", None)
        if getattr(scene, "body", None) == "mannequin":
            from couture.cloth.proxy import load_mannequin_proxy

            return load_mannequin_proxy(blend=self.proxy_blend)
        return body

    def spring_model(self, model) -> SpringModel:
        if self._cache is None or self._cache[0] is not model:
            self._cache = (model, SpringModel(model))
        return self._cache[1]

    def solve(
        self,
        model,
        x0: np.ndarray,
        *,
        tol: float = 1e-4,
        max_iters: int = 20_000,
        max_seconds: float = 60.0,
        callback: ProgressCallback | None = None,
        friction_after: float | None = None,  # no friction schedule here: ignored
        from_placement: bool = False,  # ignored
    ) -> SolveResult:
        t_start = time.perf_counter()
        sm = self.spring_model(model)
        x = pinned_positions(model, x0)
        stats: dict[str, Any] = dict(
            assembly_s=0.0, linear_solve_s=0.0, projection_s=0.0, steps=0, velocity_resets=0, own_residual=float("nan")
        )
        if not finite(x):
            return bad_start(self.name, x, stats)
        mass = np.maximum(np.asarray(model.mass, np.float64), 1e-300)
        free = sm.free
        inv_m = np.where(free, 1.0 / mass, 0.0)
        nb = sm.n_stretch
        bi, bj, brest, bk = sm.sp_i[nb:], sm.sp_j[nb:], sm.sp_rest[nb:], sm.sp_k[nb:]
        kb_sum = np.zeros(model.n)
        np.add.at(kb_sum, bi, bk)
        np.add.at(kb_sum, bj, bk)
        dt = self.dt
        if dt is None:
            bound = float(np.min(np.sqrt(mass / np.maximum(2.0 * kb_sum, 1e-300))))
            dt = min(0.02, 0.5 * bound)
        stats["dt"] = dt
        dt2 = dt * dt
        body = self.contact_body(model)
        stats["contact"] = "none" if body is None else "proxy" if body is not getattr(model, "body", None) else "sdf"
        stats["contact_s"] = 0.0
        offset = float(getattr(model, "contact_offset", 0.0))
        gnorm = float(np.linalg.norm(sm.f_gravity)) or 1.0
        x_prev = x.copy()
        x_good = x.copy()
        ke_hist = [0.0, 0.0]
        history: list[tuple[float, float]] = []
        converged = False
        diag = ""
        own = np.inf
        it = 0
        while True:
            ta = time.perf_counter()
            f = sm.f_gravity.copy()
            kernels.spring_forces(x, bi, bj, brest, bk, f)
            stats["assembly_s"] += time.perf_counter() - ta
            x_old = x.copy()
            ke = kernels.verlet_step(x, x_prev, f, inv_m, free, dt2, self.keep)
            tp = time.perf_counter()
            kernels.project_lengths(x, sm.sp_i[:nb], sm.sp_j[:nb], sm.sp_rest[:nb], inv_m, 1.0, self.stretch_iters)
            if len(sm.seam_e):
                kernels.project_seams(x, sm.seam_e, sm.seam_a, sm.seam_b, sm.seam_w, inv_m, self.seam_iters)
            if body is not None:
                tc = time.perf_counter()
                phi, g = body.phi_grad(x)
                stats["contact_s"] += time.perf_counter() - tc
                inside = (phi < offset) & free
                if inside.any():
                    x[inside] += (offset - phi[inside])[:, None] * g[inside]
            stats["projection_s"] += time.perf_counter() - tp
            it += 1
            if ke_hist[1] > ke_hist[0] and ke < ke_hist[1]:
                x_prev[:] = x  # kinetic damping: zero velocity at the peak
                stats["velocity_resets"] += 1
                ke_hist = [0.0, 0.0]
            else:
                ke_hist = [ke_hist[1], ke]
            if it % self.check_every == 0:
                if not finite(x):
                    diag = f"diverged: non-finite state at step {it}"
                    x = x_good
                    break
                x_good[:] = x
                own = float(np.linalg.norm(mass[:, None] * (x - x_old))) / (dt2 * gnorm)
                now = time.perf_counter() - t_start
                history.append((now, own))
                if own <= tol:
                    converged = True
                    break
                if callback is not None and callback(it, x, own):
                    diag = "stopped by callback"
                    break
                if it >= max_iters:
                    diag = f"max_iters {max_iters} reached (own residual {own:.3g} > tol {tol:.3g})"
                    break
                if now >= max_seconds:
                    diag = f"max_seconds {max_seconds:g} reached after {it} steps (own residual {own:.3g})"
                    break

        stats["steps"] = it
        stats["own_residual"] = own
        r = float(model.relative_residual(x))
        if converged:
            # stationary in its own spring model, not an equilibrium of the cloth model the
            # others solve: say what it converged to, in the measure they all report
            diag = (
                f"converged to its own mass-spring equilibrium (own residual {own:.3g}); "
                f"cloth-model relative residual {r:.3g}"
            )
        wall = time.perf_counter() - t_start
        return SolveResult(
            x=x,
            residual=r if np.isfinite(r) else float("inf"),
            iterations=it,
            wall_time=wall,
            converged=converged,
            method=self.name,
            diagnosis=diag,
            history=history,
            stats=stats,
        )

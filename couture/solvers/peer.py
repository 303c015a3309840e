"""A peer in the same run: NVIDIA Newton's ``SolverStyle3D`` (Style3D's garment solver) as a couture solver.

Optional: needs the ``couture[peer]`` extra (``newton``, which pulls ``warp-lang``);
it runs on the CPU through warp (device ``"cpu"``, float32). Without it
``get_solver("style3d")`` raises a clear error.

It is a model of its own (the only solver here that is), built from the same
:class:`couture.mesh.GarmentMesh`, fabric and scene as the ClothModel:

- geometry: 3D placement ``x0`` (the start state) and the 2D panel rest positions
  ``X`` (``style3d.add_cloth_mesh(panel_verts=X)``: rest deformation gradients and
  areas from the flat pattern), triangles as they are;
- stretch: Style3D's Baraff-Witkin stretch/shear energy
  ``A (ku/2 (|Fu|-1)² + kv/2 (|Fv|-1)² + ks/2 (Fu·Fv)²)`` with
  ``ku = kv = fabric.stretch_stiffness`` (E·h [N/m], the uniaxial stiffness: BW
  has no Poisson coupling) and ``ks = mu`` (the shear modulus E·h/(2(1+nu)):
  for small shear Fu·Fv ≈ 2 eps_uv, so ks/2 (2 eps_uv)² = 2 mu eps_uv², StVK's);
- an orthotropic fabric (warp, weft, shear stiffness; or panels of their own
  fabric): Style3D's stretch is anisotropic in the panel's (u, v) axes, so each
  vertex's panel coordinates are turned so that its panel's warp (grain) lies
  along v and the weft along u, and each triangle gets ``(ku, kv, ks) =
  (weft, warp, shear)`` of its own fabric (``tri_aniso_ke`` per triangle) and
  the particles our lumped masses (each panel's own density). The Poisson
  coupling nu12 is dropped, as above;
- bending: Style3D's is the same quadratic isometric model as ours (Bergou 2006,
  ``½ k 3/(A0+A1) |w x|²``), so its per-edge stiffness is set to
  ``BEND_CONSTANT · fabric.bend_stiffness`` (our ``W = (k_b/2) c Σ 3/(A0+A1) |Kx|²``),
  written into ``edge_bending_properties`` directly (its anisotropic blend
  ``ku sin¹² + kv cos¹² + 4 ks sin² cos²`` is not isotropic for ku = kv = ks);
  with directional or per-panel bending, each of its edges gets our hinge's
  own stiffness (``ClothModel.hinge_stiffness``: the hinge law along the
  grain), matched by the edge's two particles; an edge we have no hinge for
  (across a welded seam) keeps ``fabric.bend_stiffness``;
- mass: ``density = fabric.area_density`` [kg/m²] on the panel areas;
- gravity: 9.81 m/s² along -y (newton's ``up_axis = Y``);
- body: a sphere (``SphereBody``) or a half-space (``PlaneBody``) as newton shapes;
  the mannequin or a graded body as its triangle mesh
  (``couture.cloth.body.load_mannequin_mesh``); contact through newton's
  ``CollisionPipeline`` with particle radius = ``model.contact_offset`` (the
  cloth keeps that far from the surface, as ours), penalty
  ``soft_contact_ke = model.contact_stiffness`` (100 mu), friction coefficient
  ``fabric.friction_kinetic`` when the scene has friction, else 0;
- pins: particles made inactive (``ParticleFlags.ACTIVE`` cleared).

Seams, as Style3D sews them: its 3D mesh is welded along the seams while the
panel (2D) triangles stay apart (``add_cloth_mesh`` takes separate 3D and panel
indices), and ``step`` has no spring or seam term. So each seam emitter ``e``
(sewn to the point ``(1-w) a + w b`` of the other side's edge) is welded to the
nearer end of that edge (``a`` if w <= ½, else ``b``; classes by union-find,
a weld that would put two corners of one triangle together is left out and
counted in ``stats['seams_unwelded']``); a welded particle starts at its
vertices' mean and gives all of them its position. Our seams are not
conforming (the sides have different vertex counts): the weld moves a seam
point by up to half an edge along the seam, and OUR seam springs (5000 mu)
see that as a residual. Self-collision is Style3D's own (on, as users run it).

Quasi-static solve: implicit (projective-dynamics) steps of ``dt`` with
``iterations`` nonlinear x ``linear_iterations`` PCG iterations each, plus
kinetic damping (velocities zeroed at kinetic-energy peaks, as the kinetic
solver does). Own stopping measure ("own residual"): ``||M v|| / (dt ||F_gravity||)``,
the unbalanced force a step leaves over the gravity force; it stops when that is
<= ``tol`` (or at the step / time caps). It converges to its own
model's equilibrium: the result carries OUR ClothModel's relative residual at
that point (``model.relative_residual``) so accuracy is comparable;
``stats['own_residual']`` is the peer's measure. ``wall_time`` includes building
newton's model for the rest shape (its PD matrix depends on it, so an edit pays
it), reported as ``stats['build_s']``; warp's kernel compilation is cached on
disk (``~/.cache/warp``) after the first run.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from .base import ProgressCallback, SolveResult
from .common import bad_start, finite, pinned_positions

INSTALL_HINT = (
    "the style3d peer solver needs NVIDIA's newton package: install couture[peer] (pip install 'couture[peer]')"
)


def available() -> bool:
    """Whether newton (and warp) can be imported."""
    try:
        import newton  # noqa: F401
        import warp  # noqa: F401
    except ImportError:
        return False
    return True


def _import():
    try:
        import newton
        import warp as wp
    except ImportError as e:
        raise ImportError(f"{INSTALL_HINT} ({e})") from e
    wp.config.quiet = True
    wp.init()
    return newton, wp


def _add_body(builder, body, scene, wp, newton, mu: float) -> str:
    """Add the model's body to the builder as a static newton shape; returns its kind."""
    from couture.cloth.body import PlaneBody, SphereBody, load_mannequin_mesh

    cfg = builder.default_shape_cfg.copy()
    cfg.mu = mu
    if isinstance(body, SphereBody):
        c = [float(v) for v in np.asarray(body.center)]
        builder.add_shape_sphere(
            body=-1, xform=wp.transform(wp.vec3(*c), wp.quat_identity()), radius=float(body.radius), cfg=cfg
        )
        return "sphere"
    if isinstance(body, PlaneBody):
        n = np.asarray(body.normal, float)
        n = n / np.linalg.norm(n)
        d = float(np.dot(n, np.asarray(body.point, float)))
        builder.add_shape_plane(plane=(*n.tolist(), d), width=0.0, length=0.0, body=-1, cfg=cfg)
        return "plane"
    name = getattr(scene, "body", None)
    if isinstance(name, str):
        V, F = load_mannequin_mesh("default" if name == "mannequin" else name)
        mesh = newton.Mesh(np.asarray(V, np.float32), np.asarray(F, np.int32).ravel())
        builder.add_shape_mesh(body=-1, mesh=mesh, cfg=cfg)
        return f"mesh:{name}"
    raise ValueError(
        f"the style3d peer takes a SphereBody, a PlaneBody or a named body (scene.body string), not {type(body).__name__}"
    )


class PeerModel:
    """newton's model, Style3D solver, states and collision pipeline for one ClothModel at its rest shape."""

    def __init__(self, model, iterations: int, linear_iterations: int):
        from couture.cloth.model import BEND_CONSTANT, GRAVITY

        newton, wp = _import()
        self.wp = wp
        mesh = model.mesh
        fab = model.fabric
        stretch = float(fab.stretch_stiffness)
        mu_s = float(model.mu)
        with wp.ScopedDevice("cpu"):
            b = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -GRAVITY, 0.0))
            newton.solvers.SolverStyle3D.register_custom_attributes(b)
            from newton.solvers import style3d

            self.weld: np.ndarray | None = None
            self.unwelded = 0
            if getattr(model, "has_seams", False):
                self.weld, self.unwelded = weld_seams(model)
            tris = np.asarray(mesh.tris, np.int64)
            indices = tris if self.weld is None else self.weld[tris]
            panel_verts, tri_ke = peer_membrane(model)
            style3d.add_cloth_mesh(
                b,
                pos=wp.vec3(0.0, 0.0, 0.0),
                rot=wp.quat_identity(),
                vel=wp.vec3(0.0, 0.0, 0.0),
                vertices=self.to_peer(np.asarray(mesh.x0, float)).tolist(),
                indices=indices.ravel().tolist(),
                panel_verts=panel_verts.tolist(),
                panel_indices=tris.ravel().tolist(),
                density=float(model.area_density),
                particle_radius=float(model.contact_offset),
                tri_aniso_ke=[wp.vec3(*k) for k in tri_ke] if tri_ke is not None else wp.vec3(stretch, stretch, mu_s),
                edge_aniso_ke=wp.vec3(1.0, 1.0, 1.0),
            )
            n_peer = model.n if self.weld is None else int(self.weld.max()) + 1
            if b.particle_count != n_peer:
                raise ValueError(f"newton built {b.particle_count} particles for {n_peer} (welded) vertices")
            if len(b.tri_indices) != len(mesh.tris):
                raise ValueError("newton dropped degenerate or inverted rest triangles (2D panel orientation)")
            mu = float(model.friction_kinetic) if "friction" in model.terms else 0.0
            self.body_kind = "none"
            if model.body is not None:
                self.body_kind = _add_body(b, model.body, model.scene, wp, newton, mu)
            m = b.finalize()
            if tri_ke is not None:  # panels of their own density: our lumped masses, summed per particle
                mass = np.asarray(model.mass, float)
                if self.weld is not None:
                    mass = np.bincount(self.weld, weights=mass, minlength=n_peer)
                m.particle_mass.assign(mass.astype(np.float32))
                m.particle_inv_mass.assign(np.where(mass > 0, 1.0 / np.maximum(mass, 1e-300), 0.0).astype(np.float32))
            ebp = m.edge_bending_properties.numpy()
            ebp[:, 0] = BEND_CONSTANT * peer_edge_stiffness(model, m.edge_indices.numpy(), self.weld)
            m.edge_bending_properties.assign(ebp)
            flags = m.particle_flags.numpy()
            pinned = np.nonzero(~model.free)[0]
            flags[pinned if self.weld is None else self.weld[pinned]] &= ~int(newton.ParticleFlags.ACTIVE)
            m.particle_flags.assign(flags)
            m.soft_contact_ke = float(model.contact_stiffness)
            m.soft_contact_kd = 0.0
            m.soft_contact_mu = mu
            if not getattr(model.scene, "gravity", True):
                m.set_gravity((0.0, 0.0, 0.0))
            cfg = newton.solvers.SolverStyle3D.Config(iterations=iterations, linear_iterations=linear_iterations)
            self.solver = newton.solvers.SolverStyle3D(m, config=cfg)
            self.model = m
            self.states = [m.state(), m.state()]
            self.control = m.control()
            self.pipeline = newton.CollisionPipeline(m)
            self.contacts = self.pipeline.contacts()
        self.mass = m.particle_mass.numpy().astype(np.float64)

    def to_peer(self, x: np.ndarray) -> np.ndarray:
        """Our positions (n, 3) -> the peer's particles: a welded particle at its vertices' mean."""
        if self.weld is None:
            return x
        k = int(self.weld.max()) + 1
        out = np.zeros((k, 3))
        np.add.at(out, self.weld, x)
        return out / np.bincount(self.weld, minlength=k)[:, None]

    def from_peer(self, xp: np.ndarray) -> np.ndarray:
        return xp if self.weld is None else xp[self.weld]


def peer_membrane(model) -> tuple[np.ndarray, np.ndarray | None]:
    """(panel coordinates (n, 2) [m], per-triangle (ku, kv, ks) (m, 3) [N/m] or
    None) for Style3D's stretch: the rest positions as they are and None (one
    isotropic ``(E h, E h, mu)``) for one isotropic fabric; else each vertex's
    coordinates turned so that its panel's warp lies along v, and each
    triangle's (weft, warp, shear) stiffness of its own fabric."""
    from couture.cloth.material import tensile_constants

    X = np.asarray(model.X, float)
    mat = getattr(model, "material", None)
    if mat is None or not mat.orthotropic:
        return X, None
    tris = np.asarray(model.mesh.tris, np.int64)
    warp = np.asarray(mat.warp, float)  # (m, 2) unit warp of each triangle, in material space
    vw = np.zeros((len(X), 2))
    vw[tris.reshape(-1)] = np.repeat(warp, 3, axis=0)  # a vertex lies in one panel: one grain
    # u along the weft (the warp turned -90 degrees), v along the warp: a rotation
    weft = np.column_stack([vw[:, 1], -vw[:, 0]])
    P = np.column_stack([np.einsum("ij,ij->i", X, weft), np.einsum("ij,ij->i", X, vw)])
    consts = np.array([tensile_constants(f) for f in mat.fabrics])  # (E1, E2, nu12, G12)
    c = consts[mat.tri_fabric]
    return P, np.column_stack([c[:, 1], c[:, 0], c[:, 3]])


def peer_edge_stiffness(model, edges: np.ndarray, weld: np.ndarray | None) -> np.ndarray:
    """(E,) bending stiffness [N m] of each of newton's bending edges ``edges``
    (E, 4: opposite 0, opposite 1, edge vertex 0, edge vertex 1, in particles):
    ``model.bend_stiffness``, or with per-hinge stiffness our hinge's on the same
    two particles (an edge we have no hinge for keeps ``bend_stiffness``)."""
    k = np.full(len(edges), float(model.bend_stiffness))
    if not getattr(model, "bend_directional", False) or not len(model.bend_stencils):
        return k
    st = np.asarray(model.bend_stencils, np.int64)
    ends = st[:, :2] if weld is None else weld[st[:, :2]]
    ours = dict(zip(map(tuple, np.sort(ends, axis=1).tolist()), model.hinge_stiffness().tolist(), strict=True))
    theirs = np.sort(np.asarray(edges, np.int64)[:, 2:4], axis=1)
    for i, key in enumerate(map(tuple, theirs.tolist())):
        k[i] = ours.get(key, k[i])
    return k


def weld_seams(model) -> tuple[np.ndarray, int]:
    """(particle index per vertex, seams left unwelded): each seam emitter welded to the
    nearer end of its edge, unless that would join two corners of one triangle."""
    mesh = model.mesh
    n = model.n
    parent = np.arange(n)

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    tris = np.asarray(mesh.tris, np.int64)
    nbrs: list[set[int]] = [set() for _ in range(n)]
    for t in tris:
        for i in t:
            nbrs[i].update(int(j) for j in t if j != i)
    members: dict[int, set[int]] = {i: {i} for i in range(n)}
    unwelded = 0
    for e, a, bb, w in zip(
        mesh.seam_emitters, mesh.seam_edges[:, 0], mesh.seam_edges[:, 1], mesh.seam_weights, strict=True
    ):
        ra, rb = root(int(e)), root(int(a if w <= 0.5 else bb))
        if ra == rb:
            continue
        A, B = members[ra], members[rb]
        if any(nbrs[i] & B for i in A):
            unwelded += 1
            continue
        parent[rb] = ra
        members[ra] = A | B
        del members[rb]
    roots = np.array([root(i) for i in range(n)])
    _, weld = np.unique(roots, return_inverse=True)
    return weld.astype(np.int64), unwelded


class Style3DSolver:
    """couture's Solver protocol around newton's SolverStyle3D (see the module docstring)."""

    name = "style3d"

    def __init__(
        self, *, dt: float = 1.0 / 60.0, iterations: int = 10, linear_iterations: int = 10, stall_steps: int = 150
    ):
        """dt [s]: implicit step; iterations, linear_iterations: Style3D's nonlinear and PCG
        iterations per step (its defaults); stall_steps: stop (not converged) when the own
        residual has not fallen below 0.9 of its best for this many steps (float32 contact
        jitter on garments stalls it around 1e-3 to 1e-2)."""
        if dt <= 0 or iterations < 1 or linear_iterations < 1:
            raise ValueError(f"bad style3d options: dt {dt} s, iterations {iterations}, linear {linear_iterations}")
        _import()
        self.dt = float(dt)
        self.iterations = int(iterations)
        self.linear_iterations = int(linear_iterations)
        self.stall_steps = int(stall_steps)

    def solve(
        self,
        model,
        x0: np.ndarray,
        *,
        tol: float = 1e-4,
        max_iters: int = 20_000,
        max_seconds: float = 60.0,
        callback: ProgressCallback | None = None,
        friction_after: float | None = None,  # Style3D's friction acts from the first step: ignored
        from_placement: bool = False,  # ignored
    ) -> SolveResult:
        t_start = time.perf_counter()
        x = pinned_positions(model, x0)
        stats: dict[str, Any] = dict(build_s=0.0, steps=0, velocity_resets=0, own_residual=float("nan"))
        if not finite(x):
            return bad_start(self.name, x, stats)
        pm = PeerModel(model, self.iterations, self.linear_iterations)
        wp = pm.wp
        stats["build_s"] = time.perf_counter() - t_start
        stats["contact"] = pm.body_kind
        stats["seams_unwelded"] = pm.unwelded
        stats["dt"] = self.dt
        mass = pm.mass
        gnorm = float(np.linalg.norm(np.asarray(model.gravity_force))) if "gravity" in model.terms else 0.0
        gnorm = gnorm or 1.0
        s0, s1 = pm.states
        history: list[tuple[float, float]] = []
        converged = False
        diag = ""
        own = np.inf
        ke_prev2 = ke_prev = 0.0
        it = 0
        best, best_it = np.inf, 0
        x_good = x.copy()
        with wp.ScopedDevice("cpu"):
            s0.particle_q.assign(pm.to_peer(x).astype(np.float32))
            s0.particle_qd.zero_()
            while True:
                pm.pipeline.collide(s0, pm.contacts)
                s0.clear_forces()
                pm.solver.step(s0, s1, pm.control, pm.contacts, self.dt)
                s0, s1 = s1, s0
                it += 1
                v = s0.particle_qd.numpy().astype(np.float64)
                ke = 0.5 * float(np.sum(mass * np.einsum("ij,ij->i", v, v)))
                own = float(np.linalg.norm(mass[:, None] * v)) / (self.dt * gnorm)
                if ke_prev > ke_prev2 and ke < ke_prev:
                    s0.particle_qd.zero_()  # kinetic damping: zero velocity at the peak
                    stats["velocity_resets"] += 1
                    ke_prev2 = ke_prev = 0.0
                else:
                    ke_prev2, ke_prev = ke_prev, ke
                xq = pm.from_peer(s0.particle_q.numpy().astype(np.float64))
                now = time.perf_counter() - t_start
                if not np.isfinite(xq).all() or not np.isfinite(own):
                    diag = f"diverged: non-finite state at step {it}"
                    break
                x_good = xq
                history.append((now, own))
                if own <= tol:
                    converged = True
                    break
                if own < 0.9 * best:
                    best, best_it = own, it
                elif it - best_it >= self.stall_steps:
                    diag = f"stalled at own residual {own:.3g} (best {best:.3g} at step {best_it}; tol {tol:.3g})"
                    break
                if callback is not None and callback(it, xq, own):
                    diag = "stopped by callback"
                    break
                if it >= max_iters:
                    diag = f"max_iters {max_iters} reached (own residual {own:.3g} > tol {tol:.3g})"
                    break
                if now >= max_seconds:
                    diag = f"max_seconds {max_seconds:g} reached after {it} steps (own residual {own:.3g})"
                    break
        x = x_good
        stats["steps"] = it
        stats["own_residual"] = own
        r = float(model.relative_residual(x))
        if converged:
            diag = (
                f"converged to Style3D's own equilibrium (own residual {own:.3g}); "
                f"cloth-model relative residual {r:.3g}"
            )
        return SolveResult(
            x=x,
            residual=r if np.isfinite(r) else float("inf"),
            iterations=it,
            wall_time=time.perf_counter() - t_start,
            converged=converged,
            method=self.name,
            diagnosis=diag,
            history=history,
            stats=stats,
        )

"""Cloth statics model (SC §5, §7): stabilized StVK membrane, isometric
bending, lumped mass and gravity, seams, body contact, friction anchors.

Total potential energy of a drape x (n, 3) for rest pattern X (n, 2):

    E(x) = W_membrane + W_bending + W_gravity + W_seams + W_contact + W_friction

``forces(x) = -dE/dx`` and ``stiffness(x) = d²E/dx²`` (membrane part made
positive semi-definite in compression, contact part Gauss-Newton). Each term
is built only when the scene needs it (``model.terms`` lists those built).

Material (plane stress, thin sheet; ``Fabric.stretch_stiffness`` is E·h [N/m]):

    mu = Eh / (2 (1 + nu)),   lam = Eh nu / (1 - nu²)        [N/m]

membrane energy density psi = mu |G|² + lam/2 tr(G)² per unit rest area, G the
Green strain ½(FᵀF - I) of the constant-strain triangle.

Woven fabrics and per-panel fabrics (``couture.cloth.material``): an
orthotropic fabric (warp, weft, shear stiffness) or panels of different
membranes get psi = ½ vᵀ C_t v, v = (G_xx, G_yy, 2 G_xy), with each
triangle's plane-stress orthotropic C_t turned to its panel's grain (term
'membrane_orthotropic'); directional or per-panel bending gives each hinge
its own k_b (k(θ) of the hinge's direction to the warp, so that a strip cut
along warp, weft or bias bends with that rigidity) in the bending energy below. An isotropic fabric keeps the membrane above and one k_b.

Bending (Bergou et al. 2006, isometric bending model): per interior edge
stencil (x0, x1 on the edge, x2, x3 opposite) a weight vector K (4,) that
annihilates every affine map of the flat rest pattern (flat and rigidly
moved sheets have zero bending energy), scaled so that K·x = |e| θ for a
small hinge fold θ of one triangle: K_2 = |e|²/(2 A0) (= the sum of the
cotangents of triangle 0's angles at the edge), likewise K_3, and K_0, K_1
from the affine null conditions. Then

    W_bending = (k_b / 2) · c · Σ_e 3 / (A0 + A1) · |K_e x|²,   c = 0.29 / 0.938 ≈ 0.309.

Why that c: for a smooth bend z = ½ Xᵀ κ X, an edge with in-plane
tangent t and normal ν sees K·x = ½ Σ K_i (X_iᵀ κ X_i); on the equilateral
lattice that is (|e|²/(2√3)) (3 κ_νν - κ_tt), and summing the three edge
directions gives, per unit area, 3 [κ1² + κ2² - (2/3) κ1 κ2]: a Kirchhoff
plate with effective Poisson ratio ν_b = -1/3 and, with c = 1, three times
the cylinder energy (k_b/2) ∫ κ² dA (checked numerically: 3.01). The
quality constrained-Delaunay meshes the remesher builds (``triangle``,
min angle 30°) are not equilateral; on them c = 1 gives 3.39..3.46 times
the continuum for a bend imposed on every vertex (mean over bending
directions, meshes of 0.5k..5k vertices; ±4 % over directions), so
c = 1/3.45 ≈ 0.29 (``BEND_IMPOSED_FIT``) matches the continuum for imposed
bends. But an imposed affine bend is not an equilibrium of the discrete
energy on an irregular mesh: with the bend held only on a border band (its
position and slope) the interior's hinge field relaxes off the affine field
at mesh scale and settles, in the interior, at ``BEND_RELAXED_RESPONSE`` =
0.938 of the continuum with c = 0.29 (``couture bench bend_relaxation``,
bench/results/bend_relaxation.json; gravity off, the fabric's membrane,
radii 2..60 cm, four directions; window means per mesh kind: triangle
sheets (``grid_sheet``) 0.932..0.939 at h = 1.2..4.8 mm, the cantilever
bench's strips 0.932..0.942, a panel meshed by the remesher 0.936..0.951 at
h = 3.2..8.7 mm, the default skirt's gore at the fine level (8.6 mm) 0.940;
single bends 0.91..0.97; relaxed over imposed the same 0.93..0.95; the
equilateral lattice does not relax (1.000 in a linear solve), a
right-triangle grid barely (0.99)). It does not go away with refinement or
radius, so every equilibrium bent about 6 % softer than the fabric's table
(the ASTM cantilever strips 3-5 % short in overhang, docs/fabrics.md).
Hence c = ``BEND_IMPOSED_FIT`` / ``BEND_RELAXED_RESPONSE``: the relaxed
equilibrium's energy is the continuum's (tests/test_cloth_physics.py), an
imposed bend costs 1/0.938 = 1.066 times it. Coarse meshes relax alike (a
remesher panel at 21.6 mm 0.952); the skirt's coarse gore (22 mm) reads
0.997, but it leaves only a few edges free between its held bands, a limit
of the measurement (its 14 mm gore: 0.941). The relaxation keeps ν_b at
-1/3 (-0.35 relaxed against -0.34 imposed on triangle sheets, saddle
against cylinder).
The ν_b = -1/3 coupling matters only where curvature is
not developable: in a linear small-deflection solve a narrow strip bends
with EI = k_b W (1 - ν_b²) = (8/9) k_b W; a strip clamped across a width
of half its length is 6.8 % stiffer at the tip (its clamp holds the width
flat), the plate's answer, which the quality strip converges to
(tests/test_cloth_physics.py: the reference from equilateral lattices,
where the hinges are the plate exactly); at drape-scale deflections the membrane penalizes the Gaussian curvature that
lateral bending creates, pushing the strip toward developable bending with
EI = k_b W (not checked quantitatively here).

Clamps. Where held triangles (all three vertices pinned) meet free ones, the
hinges on that line (``clamped_hinges``) compare the free side against a flat
held side: for a bend w = κ s²/2 off the clamp only the free side's opposite
vertex moves, so K·x is half an interior hinge's and the hinge, whose strip
lies half in the clamp and should carry half an interior hinge's energy,
carries a quarter: the clamp acts as if it sat half a row inside the held
part (a finite-difference beam whose last two held nodes are level has zero
slope between them, not at the last). Such hinges carry
``CLAMP_HINGE_FACTOR`` = 2 times their stiffness (the free side mirrored
across the clamp line, the beam's second-order clamp) and, all lying along
one line and bending only across it, the strip rigidity D(θ) of their own
direction (``material.strip_law``), not the hinge law calibrated for evenly
spread directions (through the per-hinge path, for an isotropic fabric
too). Measured on the ASTM D1388 cantilever (``bench/fabric.py``, cotton
shirting, isotropic, strip mesh 2.5 mm): overhang against the heavy elastica
-5.9 % before, -2.3 % after; the small-deflection clamped strip
(tests/test_cloth_physics.py) 3.1 % off beam theory at h = 2.5 mm before,
1.9 % after. Pins on single vertices or a row of them hold no triangle and
change nothing; a garment's panels meet by seams, not hinges, so a held
panel makes no clamp either.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import scipy.sparse as sp

from couture.cloth import kernels as K
from couture.cloth.material import lame_parameters as lame_parameters  # re-exported: its home is material
from couture.cloth.material import reference_lame, resolve
from couture.mesh import GarmentMesh

GRAVITY = 9.81
"""[m/s²], along -y (y is up on the mannequin)"""

BEND_IMPOSED_FIT = 0.29
"""c at which a bend imposed on every vertex of a quality mesh costs the continuum's (k_b/2) ∫ κ² dA"""

BEND_RELAXED_RESPONSE = 0.938
"""the interior's bending energy in equilibrium (a bend held on a border band,
the interior relaxed) over the continuum's at c = ``BEND_IMPOSED_FIT``,
measured: mean of the mesh kinds garments and benches use (module docstring)"""

BEND_CONSTANT = BEND_IMPOSED_FIT / BEND_RELAXED_RESPONSE
"""c in W_bending = (k_b/2) c Σ 3/(A0+A1) |K x|², ≈ 0.309: relaxed equilibria
bend with k_b (module docstring); was 0.29, the imposed fit, until issue 30"""

CLAMP_HINGE_FACTOR = 2.0
"""a clamp line's hinges carry this times their stiffness (module docstring)"""

SEAM_STIFFNESS_PER_MU = 5000.0
"""default seam spring stiffness in units of the membrane shear modulus mu (SC source)"""

CONTACT_STIFFNESS_PER_MU = 100.0
"""default contact penalty stiffness in units of mu"""


def penalty_force(pen, k: float, eps: float) -> np.ndarray:
    """Contact normal force [N] of penetrations ``pen`` [m] into the offset
    layer, vectorized ``kernels.contact_law``: 0 for pen <= 0, k pen²/(2 eps)
    on the ramp, then k (pen - eps/2)."""
    pen = np.asarray(pen, dtype=np.float64)
    if eps <= 0:
        return k * np.maximum(pen, 0.0)
    return np.where(pen <= 0, 0.0, np.where(pen < eps, 0.5 * k * pen * pen / eps, k * (pen - 0.5 * eps)))


class Body(Protocol):
    """A rigid body the cloth rests on, as a signed distance field (positive outside)."""

    def phi_grad(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """points (n, 3) [m] -> (phi (n,) [m], grad (n, 3) dimensionless)."""
        ...


@dataclass
class Scene:
    """Which terms a model holds. Absent terms are never built."""

    body: Body | str | None = None
    """None, a Body, or 'mannequin' (the embedded body's SDF, loaded or built lazily)"""
    gravity: bool = True
    seams: bool = True
    """model the mesh's seam springs (if it has any)"""
    friction: bool = False
    """friction anchors against the body (needs a body)"""
    seam_stiffness: float | None = None
    """[N/m] per seam spring; None: SEAM_STIFFNESS_PER_MU * mu"""
    contact_stiffness: float | None = None
    """[N/m] per vertex; None: CONTACT_STIFFNESS_PER_MU * mu"""
    contact_offset: float = 0.01
    """[m] cloth keeps this far from the body surface (SC: 1-1.5 cm)"""
    contact_smoothing: float = 0.001
    """[m] width of the contact stiffness ramp (kernels.contact_law): the penalty
    is C², not C¹, so Newton and large implicit steps see no stiffness jump at
    the offset surface (with 0, vertices hovering at the surface made every
    Newton step on the skirt raise the contact energy ~1000x its predicted
    decrease). Shifts resting penetration by eps/2."""
    friction_stiffness: float | None = None
    """[N/m] tangential anchor springs; None: the contact stiffness"""
    project_membrane: bool = True
    """PSD projection of the membrane Hessian in compression"""
    friction_model: str = "anchors"
    """'anchors': tangential springs that slip in events (kinetic friction as a
    constant force, re-stuck at a balance; ``slip_friction``); 'huber': an
    elasto-plastic potential of each anchored vertex's tangential displacement
    from its anchor (k_t/2 |d|² up to the Coulomb limit c = mu_s f_n, then c |d|:
    ``kernels.huber_anchor_forces``), C¹ and convex, with c lagged (set when the
    anchor is made, refreshed at a balance by ``lag_friction``): no slip events,
    one smooth energy every solver minimizes"""
    friction_slip: float = 1e-3
    """[m] 'huber' friction: the tangential displacement from its anchor at which a
    vertex's friction reaches its Coulomb limit (its stiffness is limit/slip below)"""
    panel_fabrics: dict = field(default_factory=dict)
    """panel name -> that panel's own fabric (``Design.panel_fabrics``); the
    model's ``fabric`` covers every other panel (couture.cloth.material)"""


def bending_stencils(tris: np.ndarray) -> np.ndarray:
    """(e, 4) int32 stencils (v0, v1, opp0, opp1) of the interior (two-triangle) edges.

    opp0 lies in the triangle where the edge runs v0 -> v1 counter-clockwise."""
    return bending_stencils_and_triangles(tris)[0]


def bending_stencils_and_triangles(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``bending_stencils`` and, for each stencil, the triangle holding v0 -> v1
    counter-clockwise (the one opp0 is in), (e,) int64."""
    tris = np.asarray(tris)
    m = len(tris)
    a = tris.reshape(-1)
    b = tris[:, [1, 2, 0]].reshape(-1)
    o = tris[:, [2, 0, 1]].reshape(-1)
    lo = np.minimum(a, b).astype(np.int64)
    hi = np.maximum(a, b).astype(np.int64)
    key = lo * (int(a.max()) + 1 if m else 1) + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    same = np.nonzero(ks[1:] == ks[:-1])[0]
    # drop non-manifold edges (3+ triangles): they are not hinges
    if len(same):
        cnt_ok = np.ones(len(same), bool)
        cnt_ok &= ~np.isin(same - 1, same)
        cnt_ok &= ~np.isin(same + 1, same)
        same = same[cnt_ok]
    h0 = order[same]
    h1 = order[same + 1]
    return np.column_stack([a[h0], b[h0], o[h0], o[h1]]).astype(np.int32), (h0 // 3).astype(np.int64)


def clamped_hinges(stencils: np.ndarray, free: np.ndarray) -> np.ndarray:
    """(e,) bool: the stencils (e, 4) whose one triangle has all three vertices
    held (``free`` (n,) bool False) and the other not: a clamp line's hinges."""
    held = ~np.asarray(free, bool)
    st = np.asarray(stencils)
    if len(st) == 0:
        return np.zeros(0, bool)
    edge = held[st[:, 0]] & held[st[:, 1]]
    return (edge & held[st[:, 2]]) != (edge & held[st[:, 3]])


def bending_weights(X: np.ndarray, stencils: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """K (e, 4) and the per-stencil factor 3 / (A0 + A1) [1/m²] from rest positions X (n, 2)
    (``kernels.bending_weights``, the one implementation the derivative shares)."""
    st = np.ascontiguousarray(stencils, dtype=np.int32)
    Kw = np.empty((len(st), 4))
    fac = np.empty(len(st))
    K.bending_weights(np.ascontiguousarray(X, dtype=np.float64), st, Kw, fac)
    return Kw, fac


@dataclass
class _Pattern:
    """Sparse 3n x 3n block-CSR pattern and the element -> data-slot maps."""

    n: int
    indptr: np.ndarray
    indices: np.ndarray
    blk_base: np.ndarray
    blk_stride: np.ndarray
    indptr3: np.ndarray
    indices3: np.ndarray
    keys: np.ndarray = field(repr=False)

    @classmethod
    def build(cls, n: int, stencil_lists: list[np.ndarray]) -> "_Pattern":
        rows = [np.arange(n, dtype=np.int64)]
        cols = [np.arange(n, dtype=np.int64)]
        for st in stencil_lists:
            if len(st) == 0:
                continue
            k = st.shape[1]
            rows.append(np.repeat(st, k, axis=1).reshape(-1).astype(np.int64))
            cols.append(np.tile(st, (1, k)).reshape(-1).astype(np.int64))
        key = np.sort(np.concatenate(rows) * n + np.concatenate(cols))
        key = key[np.concatenate(([True], key[1:] != key[:-1]))]
        r = key // n
        c = key % n
        indptr = np.zeros(n + 1, np.int64)
        np.add.at(indptr, r + 1, 1)
        indptr = np.cumsum(indptr)
        rowlen = np.diff(indptr)
        indptr3 = np.zeros(3 * n + 1, np.int64)
        indptr3[1:] = np.cumsum(np.repeat(3 * rowlen, 3))
        s = np.arange(len(key))
        blk_base = indptr3[3 * r] + 3 * (s - indptr[r])
        blk_stride = 3 * rowlen[r]
        indices3 = np.empty(indptr3[-1], np.int32)
        a = np.arange(3)
        pos = blk_base[:, None, None] + a[None, :, None] * blk_stride[:, None, None] + a[None, None, :]
        indices3[pos] = (3 * c[:, None, None] + a[None, None, :]).astype(np.int32)
        return cls(
            n,
            indptr,
            c.astype(np.int32),
            blk_base.astype(np.int64),
            blk_stride.astype(np.int64),
            indptr3,
            indices3,
            key,
        )

    def slots(self, stencils: np.ndarray) -> np.ndarray:
        """(e, k, k) scalar-CSR slots of every vertex pair of each stencil (e, k)."""
        k = stencils.shape[1]
        r = np.repeat(stencils, k, axis=1).astype(np.int64)
        c = np.tile(stencils, (1, k)).astype(np.int64)
        s = np.searchsorted(self.keys, r * self.n + c)
        return s.reshape(len(stencils), k, k).astype(np.int64)

    def scalar_matrix(self, vals: np.ndarray) -> sp.csr_matrix:
        return sp.csr_matrix((vals, self.indices, self.indptr), shape=(self.n, self.n))


class ClothModel:
    """Energy, forces and stiffness of a garment mesh in a scene (see module docstring).

    State (x) is passed in; the model holds only the mesh, material, scene
    terms and the friction anchors (updated by ``update_friction``).
    """

    ALL_TERMS = ("membrane", "membrane_orthotropic", "bending", "gravity", "seams", "contact", "friction")
    """'membrane' is the isotropic StVK membrane of one fabric; a garment with an
    orthotropic fabric, or panels of different membranes or densities, gets
    'membrane_orthotropic' (per-triangle elasticity, couture.cloth.material) instead"""

    def __init__(self, mesh: GarmentMesh, fabric, scene: Scene | None = None):
        scene = Scene() if scene is None else scene
        self.mesh = mesh
        self.fabric = fabric
        self.scene = scene
        self.n = mesh.n_vertices
        self.tris = mesh.tris
        # mu, lam, bend_stiffness and area_density: the design fabric's (for an
        # orthotropic one, the isotropic fabric of its mean stiffness): what the
        # default seam and contact stiffness, the residual floor and the
        # sensitivity's bending floor scale with. The terms read ``material``.
        self.mu, self.lam = reference_lame(fabric)
        self.bend_stiffness = float(fabric.bend_stiffness)
        self.area_density = float(fabric.area_density)
        self.material = resolve(mesh, fabric, scene.panel_fabrics)
        self.free = np.ones(self.n, bool)
        self.free[mesh.pinned] = False

        self.membrane_term = "membrane_orthotropic" if self.material.orthotropic else "membrane"
        self.bend_directional = self.material.directional_bending
        if self.material.orthotropic:
            self.elasticity = np.ascontiguousarray(self.material.elasticity())
            """(m, 3, 3) Voigt elasticity [N/m] per triangle on the material axes"""
            self.tri_density = self.material.density()
        else:
            self.tri_density = np.full(len(self.tris), self.area_density)
        terms = [self.membrane_term, "bending"]
        if scene.gravity:
            terms.append("gravity")
        self.has_seams = bool(scene.seams and len(mesh.seam_emitters))
        if self.has_seams:
            terms.append("seams")
        self.body: Body | None = None
        if scene.body is not None:
            if isinstance(scene.body, str):
                from couture.cloth import body as body_mod

                # 'mannequin' is the default body; any other string names a body of couture.bodies
                name = "default" if scene.body == "mannequin" else scene.body
                from couture import bodies

                if name not in bodies.names():
                    raise ValueError(
                        f"unknown body {scene.body!r}; use a Body, 'mannequin' or one of {list(bodies.names())}"
                    )
                self.body = body_mod.load_mannequin_sdf(name=name)
            else:
                self.body = scene.body
            terms.append("contact")
            if scene.friction:
                terms.append("friction")
        elif scene.friction:
            raise ValueError("Scene.friction needs a body")
        self.terms: tuple[str, ...] = tuple(terms)

        self.seam_stiffness = (
            scene.seam_stiffness if scene.seam_stiffness is not None else SEAM_STIFFNESS_PER_MU * self.mu
        )
        self.contact_stiffness = (
            scene.contact_stiffness if scene.contact_stiffness is not None else CONTACT_STIFFNESS_PER_MU * self.mu
        )
        self.contact_offset = float(scene.contact_offset)
        self.contact_smoothing = float(scene.contact_smoothing)
        self.friction_stiffness = (
            scene.friction_stiffness if scene.friction_stiffness is not None else self.contact_stiffness
        )
        if scene.friction_model not in ("anchors", "huber"):
            raise ValueError(f"Scene.friction_model {scene.friction_model!r}: use 'anchors' or 'huber'")
        self.friction_model = scene.friction_model
        self.friction_slip = float(scene.friction_slip)
        if not (np.isfinite(self.friction_slip) and self.friction_slip > 0):
            raise ValueError(f"Scene.friction_slip {scene.friction_slip!r}: a positive length [m]")
        self.friction_static = float(getattr(fabric, "friction_static", 0.5))
        self.friction_kinetic = float(getattr(fabric, "friction_kinetic", 0.3))
        """the design fabric's Coulomb coefficients (``friction_coefficients``:
        per vertex where panels' own fabrics differ)"""
        self.vertex_friction: tuple[np.ndarray, np.ndarray] | None = None
        mus = [
            (float(getattr(f, "friction_static", 0.5)), float(getattr(f, "friction_kinetic", 0.3)))
            for f in self.material.fabrics
        ]
        if len(set(mus)) > 1 and "friction" in self.terms:
            # each vertex takes its panel's (a vertex is in one panel: panels meet by seam springs)
            vf = np.zeros(self.n, np.int64)
            vf[self.tris.reshape(-1)] = np.repeat(self.material.tri_fabric, 3)
            table = np.array(mus)
            self.vertex_friction = (table[vf, 0], table[vf, 1])

        # topology: stencils and the sparse pattern, built once per mesh
        self.bend_stencils, bend_tris = bending_stencils_and_triangles(self.tris)
        self.bend_clamped = clamped_hinges(self.bend_stencils, self.free)
        """(e,) bool: the hinges between a held triangle and a free one (module docstring)"""
        if self.bend_directional or self.bend_clamped.any():
            self.bend_dir, self.bend_warp = self.material.bending(bend_tris, self.bend_clamped)
            """(e, 6) hinge law (``material.hinge_law``; a clamp's hinges
            ``CLAMP_HINGE_FACTOR`` x ``material.strip_law``) and (e, 2) unit warp of
            every hinge (``kernels.hinge_stiffness``)"""
            self.bend_dir[self.bend_clamped, :3] *= CLAMP_HINGE_FACTOR
            self.bend_directional = True
        if self.has_seams:
            self.seam_stencils = np.column_stack([mesh.seam_emitters, mesh.seam_edges]).astype(np.int32)
            w = mesh.seam_weights
            self.seam_w = np.column_stack([np.ones_like(w), -(1.0 - w), -w])
        else:
            self.seam_stencils = np.zeros((0, 3), np.int32)
            self.seam_w = np.zeros((0, 3))
        self.pattern = _Pattern.build(self.n, [self.tris, self.bend_stencils, self.seam_stencils])
        self.tri_slots = self.pattern.slots(self.tris)
        self.bend_slots = self.pattern.slots(self.bend_stencils)
        self.seam_slots = self.pattern.slots(self.seam_stencils)
        self.diag_slots = self.pattern.slots(np.arange(self.n, dtype=np.int32)[:, None])[:, 0, 0].copy()
        p = self.pattern
        self._K = sp.csr_matrix((np.zeros(len(p.indices3)), p.indices3, p.indptr3), shape=(3 * self.n, 3 * self.n))
        self._K.has_sorted_indices = True

        # friction anchors: allocated only with a friction term, empty until contact
        if "friction" in self.terms:
            self.anchored = np.zeros(self.n, bool)
            self.sliding = np.zeros(self.n, bool)
            self.anchor = np.zeros((self.n, 3))
            self.anchor_normal = np.zeros((self.n, 3))
            self.slipping = np.zeros(self.n, bool)
            self.slip_force = np.zeros((self.n, 3))
            self.friction_limit = np.zeros(self.n)
            """[N] lagged Coulomb limit mu_s f_n per anchor ('huber')"""

        self.set_rest_positions(mesh.X)

    # ------------------------------------------------------------------
    # rest-shape dependent data (cheap to refresh on a pattern edit)
    # ------------------------------------------------------------------

    def set_rest_positions(self, X: np.ndarray) -> None:
        """Recompute everything that depends on X (n, 2); same topology and pattern."""
        self.X = np.ascontiguousarray(X, dtype=np.float64)
        m = len(self.tris)
        self.Dminv = np.empty((m, 2, 2))
        self.tri_area = np.empty(m)
        K.membrane_rest(self.X, self.tris, self.Dminv, self.tri_area)
        self.mass = np.zeros(self.n)
        np.add.at(self.mass, self.tris.reshape(-1), np.repeat(self.tri_area * self._rho / 3.0, 3))
        self._rebuild_constant()

    @property
    def _rho(self):
        """area density [kg/m²]: the fabric's, or per triangle (m,) with several"""
        return self.tri_density if self.material.orthotropic else self.area_density

    def set_bend_stiffness(self, bend_stiffness: float) -> None:
        """Set one k_b [N m] for every hinge (directions and panels dropped; a
        clamp's hinges keep their factor) without a rebuild."""
        self.bend_stiffness = float(bend_stiffness)
        self.bend_directional = bool(self.bend_clamped.any())
        if self.bend_directional:
            law = np.zeros((len(self.bend_stencils), 6))
            law[:, 0] = self.bend_stiffness
            law[self.bend_clamped, 0] *= CLAMP_HINGE_FACTOR
            law[:, 3] = 1.0
            self.bend_dir = law
        self._rebuild_constant()

    def hinge_stiffness(self, X: np.ndarray | None = None) -> np.ndarray:
        """(e,) bending stiffness [N m] of every hinge at rest shape X (default the model's)."""
        if not self.bend_directional:
            return np.full(len(self.bend_stencils), self.bend_stiffness)
        X = self.X if X is None else np.ascontiguousarray(X, dtype=np.float64)
        k = np.empty(len(self.bend_stencils))
        K.hinge_stiffness(X, self.bend_stencils, self.bend_dir, self.bend_warp, k)
        return k

    def _bend_vals(self, X: np.ndarray) -> np.ndarray:
        vals = np.zeros(len(self.pattern.indices))
        if len(self.bend_stencils):
            Kw, fac = bending_weights(X, self.bend_stencils)
            if self.bend_directional:
                coef = self.hinge_stiffness(X) * BEND_CONSTANT * fac
            else:
                coef = self.bend_stiffness * BEND_CONSTANT * fac
            K.stencil_scatter(Kw, coef, self.bend_slots, vals)
        return vals

    def _rebuild_constant(self) -> None:
        """Scalar matrices of the x-independent Hessians (bending, seams) and
        their 3n-expanded data, added to every stiffness refill."""
        nnz = len(self.pattern.indices)
        self.bend_vals = self._bend_vals(self.X)
        self.seam_vals = np.zeros(nnz)
        if self.has_seams:
            K.stencil_scatter(
                self.seam_w, np.full(len(self.seam_w), float(self.seam_stiffness)), self.seam_slots, self.seam_vals
            )
        self.Qbend = self.pattern.scalar_matrix(self.bend_vals)
        self.Qseam = self.pattern.scalar_matrix(self.seam_vals)
        self.Qconst = self.pattern.scalar_matrix(self.bend_vals + self.seam_vals)
        self._const_data = np.zeros(len(self.pattern.indices3))
        K.scalar_to_block_diag(
            self.bend_vals + self.seam_vals, self.pattern.blk_base, self.pattern.blk_stride, self._const_data
        )
        self._bend_const = np.zeros_like(self._const_data)
        K.scalar_to_block_diag(self.bend_vals, self.pattern.blk_base, self.pattern.blk_stride, self._bend_const)
        self._seam_const = self._const_data - self._bend_const
        g = np.zeros((self.n, 3))
        if "gravity" in self.terms:
            g[:, 1] = -GRAVITY * self.mass
        self.gravity_force = g

    # ------------------------------------------------------------------
    # energy, forces, stiffness
    # ------------------------------------------------------------------

    def _check_terms(self, terms):
        if terms is None:
            return self.terms
        bad = [t for t in terms if t not in self.terms]
        if bad:
            raise ValueError(f"terms {bad} are not in this model {self.terms}")
        return tuple(terms)

    def _contact(self, x):
        phi, grad = self.body.phi_grad(x)
        return np.ascontiguousarray(phi, dtype=np.float64), np.ascontiguousarray(grad, dtype=np.float64)

    def _contact_hess(self, x, phi):
        """SDF Hessians (n, 3, 3) of the vertices inside the contact layer (zeros
        elsewhere, and everywhere for a body without ``phi_hess``)."""
        hess = np.zeros((self.n, 3, 3))
        phi_hess = getattr(self.body, "phi_hess", None)
        inside = np.nonzero(phi < self.contact_offset)[0]
        if phi_hess is not None and len(inside):
            hess[inside] = phi_hess(np.ascontiguousarray(x[inside]))
        return hess

    def energy(self, x: np.ndarray, terms=None) -> float:
        """Total potential energy [J] (or the sum over ``terms``)."""
        return self._energy_forces(x, self._check_terms(terms), want_forces=False)[0]

    def forces(self, x: np.ndarray, terms=None) -> np.ndarray:
        """-dE/dx, shape (n, 3) [N] (gravity, elasticity, seams, contact, friction anchors)."""
        return self._energy_forces(x, self._check_terms(terms), want_forces=True)[1]

    def energy_and_forces(self, x: np.ndarray, terms=None) -> tuple[float, np.ndarray]:
        return self._energy_forces(x, self._check_terms(terms), want_forces=True)

    def _energy_forces(self, x, terms, want_forces):
        x = np.ascontiguousarray(x, dtype=np.float64)
        f = np.zeros((self.n, 3))
        e = 0.0
        if "membrane" in terms:
            if want_forces:
                e += K.membrane_forces(x, self.tris, self.Dminv, self.tri_area, self.mu, self.lam, f)
            else:
                e += K.membrane_energy(x, self.tris, self.Dminv, self.tri_area, self.mu, self.lam)
        elif "membrane_orthotropic" in terms:
            if want_forces:
                e += K.membrane_ortho_forces(x, self.tris, self.Dminv, self.tri_area, self.elasticity, f)
            else:
                e += K.membrane_ortho_energy(x, self.tris, self.Dminv, self.tri_area, self.elasticity)
        lin = None
        if "bending" in terms and "seams" in terms:
            lin = self.Qconst
        elif "bending" in terms:
            lin = self.Qbend
        elif "seams" in terms:
            lin = self.Qseam
        if lin is not None:
            qx = lin @ x
            if want_forces:
                f -= qx
            e += 0.5 * float(np.vdot(x, qx))
        if "gravity" in terms:
            f += self.gravity_force
            e -= float(np.vdot(self.gravity_force, x))
        if "contact" in terms:
            phi, grad = self._contact(x)
            e += K.contact_forces(phi, grad, self.contact_offset, self.contact_stiffness, self.contact_smoothing, f)
        if "friction" in terms and self.friction_model == "huber":
            e += K.huber_anchor_forces(
                x, self.anchored, self.anchor, self.anchor_normal, self.friction_slip, self.friction_limit, f
            )
        elif "friction" in terms:
            e += K.anchor_forces(x, self.anchored, self.anchor, self.anchor_normal, self.friction_stiffness, f)
            if self.slipping.any():
                # kinetic friction on slipping vertices: a constant force, potential -f.x
                f += self.slip_force
                e -= float(np.vdot(self.slip_force, x))
        return e, f

    def stiffness(self, x: np.ndarray, terms=None, project: bool | None = None) -> sp.csr_matrix:
        """d²E/dx² as a (3n, 3n) CSR matrix. With ``project`` (the scene's default)
        it is PSD: the membrane's stress projected in compression and each
        vertex's contact block (Gauss-Newton part plus the body-curvature term)
        clamped to its non-negative eigenvalues; ``project=False`` is the exact
        Hessian. For all terms and the default
        projection the same matrix object is refilled in place every call
        (same indices, new data): copy it to keep it."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        terms_ = self._check_terms(terms)
        project = self.scene.project_membrane if project is None else project
        shared = terms is None and project == self.scene.project_membrane
        data = self._K.data if shared else np.zeros_like(self._K.data)
        p = self.pattern
        if "bending" in terms_ and "seams" in terms_:
            data[:] = self._const_data
        elif "bending" in terms_:
            data[:] = self._bend_const
        elif "seams" in terms_:
            data[:] = self._seam_const
        else:
            data[:] = 0.0
        if "membrane" in terms_:
            K.membrane_stiffness(
                x,
                self.tris,
                self.Dminv,
                self.tri_area,
                self.mu,
                self.lam,
                project,
                self.tri_slots,
                p.blk_base,
                p.blk_stride,
                data,
            )
        elif "membrane_orthotropic" in terms_:
            K.membrane_ortho_stiffness(
                x,
                self.tris,
                self.Dminv,
                self.tri_area,
                self.elasticity,
                project,
                self.tri_slots,
                p.blk_base,
                p.blk_stride,
                data,
            )
        if "contact" in terms_:
            phi, grad = self._contact(x)
            K.contact_stiffness(
                phi,
                grad,
                self._contact_hess(x, phi),
                self.contact_offset,
                self.contact_stiffness,
                self.contact_smoothing,
                project,
                self.diag_slots,
                p.blk_base,
                p.blk_stride,
                data,
            )
        if "friction" in terms_ and self.friction_model == "huber":
            K.huber_anchor_stiffness(
                x,
                self.anchored,
                self.anchor,
                self.anchor_normal,
                self.friction_slip,
                self.friction_limit,
                self.diag_slots,
                p.blk_base,
                p.blk_stride,
                data,
            )
        elif "friction" in terms_:
            K.anchor_stiffness(
                self.anchored,
                self.anchor_normal,
                self.friction_stiffness,
                self.diag_slots,
                p.blk_base,
                p.blk_stride,
                data,
            )
        if shared:
            return self._K
        return sp.csr_matrix((data, p.indices3, p.indptr3), shape=self._K.shape)

    # ------------------------------------------------------------------
    # residual, friction, sensitivity
    # ------------------------------------------------------------------

    @property
    def free_dofs(self) -> np.ndarray:
        """(3n,) bool, False for the dofs of pinned vertices."""
        return np.repeat(self.free, 3)

    @property
    def residual_scale_constant(self) -> bool:
        """True when ``residual_denominator`` does not depend on x (a scene with
        gravity), so solvers may compute it once (couture.solvers.common)."""
        return "gravity" in self.terms

    def residual_denominator(self, x: np.ndarray) -> float:
        """The force the residual is measured against [N]: ||F_gravity|| with
        gravity. Without it, the forces that balance each other at equilibrium,
        sqrt(sum over terms of ||f_term||²) on all vertices (pin reactions
        included), but at least mu·sqrt(A), the membrane force of a unit
        strain over the rest area A: an unloaded scene (no gravity, no pins,
        nothing stretched) then reports about the strain its forces amount to,
        where the internal force alone would give a ratio of 1 at every x."""
        if "gravity" in self.terms:
            return float(np.linalg.norm(self.gravity_force))
        x = np.ascontiguousarray(x, dtype=np.float64)
        total = sum(float(np.sum(self.forces(x, [t]) ** 2)) for t in self.terms)
        floor = self.mu * float(np.sqrt(self.tri_area.sum()))
        return max(float(np.sqrt(total)), floor, 1e-300)

    def relative_residual(self, x: np.ndarray) -> float:
        """||R_free|| / ``residual_denominator(x)`` (couture.solvers.base)."""
        f = self.forces(x)
        return float(np.linalg.norm(f[self.free])) / self.residual_denominator(x)

    def contact_normal_force(self, pen: np.ndarray) -> np.ndarray:
        """Contact force magnitude [N] per vertex for penetrations ``pen`` [m] of
        the offset layer (kernels.contact_law; 0 outside)."""
        return penalty_force(pen, self.contact_stiffness, self.contact_smoothing)

    def friction_coefficients(self, idx=slice(None)):
        """(mu_s, mu_k) of the vertices ``idx``: the design fabric's numbers, or
        arrays where panels' own fabrics give them others."""
        if self.vertex_friction is None:
            return self.friction_static, self.friction_kinetic
        return self.vertex_friction[0][idx], self.vertex_friction[1][idx]

    def friction_excess(self, x: np.ndarray) -> float:
        """Largest amount [N] by which an anchor's tangential force exceeds the static
        Coulomb limit mu_s f_n at x (anchors out of contact: their whole force);
        <= 0 means the anchor forces are admissible static friction, so a state
        with small residual is a Coulomb equilibrium as it stands. 0 without friction."""
        if "friction" not in self.terms or not self.anchored.any():
            return 0.0
        idx = np.nonzero(self.anchored)[0]
        ft = np.linalg.norm(self.forces(x, ["friction"])[idx], axis=1)
        phi, _ = self._contact(np.ascontiguousarray(x[idx], dtype=np.float64))
        fn = self.contact_normal_force(self.contact_offset - phi)
        return float(np.max(ft - self.friction_coefficients(idx)[0] * fn))

    def slip_friction(self, x: np.ndarray) -> int:
        """Let every anchor that holds more than mu_s f_n at x slip: the vertex loses
        its anchor spring and feels instead the kinetic friction force, mu_k f_n
        along the spring's force (a constant force), so it slides as far as the
        cloth pulls it in one solve (an anchor out of contact is released).
        ``stick_slipping`` anchors it again where it came to rest. Returns how many
        slipped. Why not re-anchor at the kinetic limit (``update_friction``): with
        a spring 5000x stiffer than the cloth the re-balanced cloth pushes the
        anchor past mu_s again after a micrometre, and the rounds creep without end."""
        if "friction" not in self.terms or not self.anchored.any() or self.friction_model == "huber":
            return 0
        x = np.ascontiguousarray(x, dtype=np.float64)
        idx = np.nonzero(self.anchored)[0]
        phi, _ = self._contact(np.ascontiguousarray(x[idx]))
        fn = self.contact_normal_force(self.contact_offset - phi)
        fa = self.forces(x, ["friction"])[idx]
        ft = np.linalg.norm(fa, axis=1)
        mu_s, mu_k = self.friction_coefficients(idx)
        over = ft > mu_s * fn
        if not over.any():
            return 0
        j = idx[over]
        self.anchored[j] = False
        self.sliding[j] = False
        touching = fn[over] > 0.0
        self.slipping[j[touching]] = True
        if self.vertex_friction is not None:
            mu_k = mu_k[over][touching]
        self.slip_force[j[touching]] = (mu_k * fn[over][touching] / ft[over][touching])[:, None] * fa[over][touching]
        return int(over.sum())

    def rescale_slipping(self, x: np.ndarray) -> float:
        """Set each slipping vertex's kinetic friction to mu_k times its normal force
        at x (the direction is kept): set once at the slip, a force sized to the
        normal force of that moment would go on pulling after the vertex has slid to
        where the body pushes less (or not at all), and keep the solve from its
        balance. Returns the largest change [N] (0 without slipping vertices)."""
        if "friction" not in self.terms or not self.slipping.any():
            return 0.0
        x = np.ascontiguousarray(x, dtype=np.float64)
        j = np.nonzero(self.slipping)[0]
        phi, _ = self._contact(np.ascontiguousarray(x[j]))
        fn = self.contact_normal_force(self.contact_offset - phi)
        old = self.slip_force[j]
        size = np.linalg.norm(old, axis=1)
        scale = np.divide(self.friction_coefficients(j)[1] * fn, size, out=np.zeros_like(size), where=size > 0)
        new = old * scale[:, None]
        self.slip_force[j] = new
        return float(np.max(np.linalg.norm(new - old, axis=1)))

    def refresh_contacts(self, x: np.ndarray) -> int:
        """Anchor every vertex in contact that has none (where it is: no force) and let
        go of anchors whose vertex left the offset layer. Unlike ``update_friction``
        no anchor moves. Returns how many anchors were let go (those change forces)."""
        if "friction" not in self.terms:
            return 0
        x = np.ascontiguousarray(x, dtype=np.float64)
        phi, grad = self._contact(x)
        contact = phi < self.contact_offset
        gone = self.anchored & ~contact
        self.anchored[gone] = False
        self.sliding[gone] = False
        new = contact & ~self.anchored & ~self.slipping
        self.anchor[new] = x[new]
        self.anchor_normal[new] = grad[new] / np.maximum(np.linalg.norm(grad[new], axis=1), 1e-300)[:, None]
        self.anchored[new] = True
        self.sliding[new] = False
        return int(gone.sum())

    def stick_slipping(self, x: np.ndarray) -> int:
        """Anchor every slipping vertex where it is, with the anchor spring holding the
        same force the kinetic friction did (the balance at x is unchanged); a vertex
        that left the body is let go. Returns how many were slipping."""
        if "friction" not in self.terms or not self.slipping.any():
            return 0
        x = np.ascontiguousarray(x, dtype=np.float64)
        j = np.nonzero(self.slipping)[0]
        phi, _ = self._contact(np.ascontiguousarray(x[j]))
        touching = phi < self.contact_offset
        k = j[touching]
        # -k_t P(x - a) = slip force (tangential to the kept anchor normal): a = x + f / k_t
        self.anchor[k] = x[k] + self.slip_force[k] / self.friction_stiffness
        self.anchored[k] = True
        self.sliding[k] = False
        self.slipping[j] = False
        self.slip_force[j] = 0.0
        return len(j)

    def friction_state(self) -> tuple[np.ndarray, ...] | None:
        """A copy of the friction state (anchors, slipping vertices and their forces),
        None without friction: a solver that returns an earlier state returns its anchors too."""
        if "friction" not in self.terms:
            return None
        return (
            self.anchored.copy(),
            self.sliding.copy(),
            self.anchor.copy(),
            self.anchor_normal.copy(),
            self.slipping.copy(),
            self.slip_force.copy(),
        )

    def set_friction_state(self, state: tuple[np.ndarray, ...] | None) -> None:
        """Put back anchors taken by ``friction_state``."""
        if state is None or "friction" not in self.terms:
            return
        (
            self.anchored[:],
            self.sliding[:],
            self.anchor[:],
            self.anchor_normal[:],
            self.slipping[:],
            self.slip_force[:],
        ) = state

    def release_friction(self) -> None:
        """Drop every friction anchor (no-op without friction): a solve that starts
        far from equilibrium (a fresh placement) lets the cloth settle frictionless first."""
        if "friction" in self.terms:
            self.anchored[:] = False
            self.sliding[:] = False
            self.slipping[:] = False
            self.slip_force[:] = 0.0
            self.friction_limit[:] = 0.0

    def update_friction(self, x: np.ndarray) -> dict:
        """Move, create or release friction anchors (Hasegawa 2003); no-op without friction.

        In contact (phi < offset) a vertex without anchor gets one at its
        current position (sticking). Anchored vertices: the tangential
        spring force |f_t| = k_t |P(x - a)| is compared with the normal force
        f_n = F(offset - phi) (``contact_normal_force``): sticking while |f_t| <= mu_s f_n; beyond it
        the vertex slides and the anchor is dragged along so that |f_t| =
        mu_k f_n (dynamic mode, kept while |f_t| >= mu_k f_n). Anchors of
        vertices out of contact are released. Returns counts.
        """
        if "friction" not in self.terms:
            return {"anchored": 0, "sliding": 0, "created": 0, "released": 0}
        x = np.ascontiguousarray(x, dtype=np.float64)
        if self.friction_model == "huber":
            before = int(self.anchored.sum())
            released = self.lag_friction(x)[1]
            return {
                "anchored": int(self.anchored.sum()),
                "sliding": 0,
                "created": int(self.anchored.sum()) - before + released,
                "released": released,
            }
        self.stick_slipping(x)
        phi, grad = self._contact(x)
        pen = self.contact_offset - phi
        contact = pen > 0.0
        released = self.anchored & ~contact
        self.anchored[released] = False
        self.sliding[released] = False
        created = contact & ~self.anchored
        gn = grad / np.maximum(np.linalg.norm(grad, axis=1), 1e-300)[:, None]
        self.anchor[created] = x[created]
        self.anchor_normal[created] = gn[created]
        self.anchored[created] = True
        self.sliding[created] = False
        idx = np.nonzero(self.anchored & ~created)[0]
        if len(idx):
            n_ = self.anchor_normal[idx]
            d = x[idx] - self.anchor[idx]
            dt = d - np.einsum("ij,ij->i", d, n_)[:, None] * n_
            ft = self.friction_stiffness * np.linalg.norm(dt, axis=1)
            fn = self.contact_normal_force(pen[idx])
            mu_s, mu_k = self.friction_coefficients(idx)
            limit = np.where(self.sliding[idx], mu_k * fn, mu_s * fn)
            slide = ft > limit
            self.sliding[idx] = slide
            if slide.any():
                j = idx[slide]
                if self.vertex_friction is not None:
                    mu_k = mu_k[slide]
                keep = (mu_k * fn[slide] / self.friction_stiffness)[:, None]
                u = dt[slide] / np.linalg.norm(dt[slide], axis=1)[:, None]
                # anchor trails the vertex at the kinetic limit, in the current tangent plane
                nn = gn[j]
                self.anchor[j] = x[j] - keep * (u - np.einsum("ij,ij->i", u, nn)[:, None] * nn)
                self.anchor_normal[j] = nn
        return {
            "anchored": int(self.anchored.sum()),
            "sliding": int(self.sliding.sum()),
            "created": int(created.sum()),
            "released": int(released.sum()),
        }

    def lag_friction(self, x: np.ndarray) -> tuple[float, int]:
        """'huber' friction: refresh the lagged state at x. Vertices in contact without
        an anchor get one where they are (no force); anchors whose vertex left the
        offset layer let go; every anchor's limit becomes mu_s f_n at x. Anchors never
        move: the potential measures the slide from where the vertex first rested.
        Returns (the largest change of a friction force it caused [N], how many
        anchors let go)."""
        if "friction" not in self.terms or self.friction_model != "huber":
            return 0.0, 0
        x = np.ascontiguousarray(x, dtype=np.float64)
        f_old = self.forces(x, ["friction"])
        phi, grad = self._contact(x)
        pen = self.contact_offset - phi
        contact = pen > 0.0
        gone = self.anchored & ~contact
        self.anchored[gone] = False
        new = contact & ~self.anchored
        self.anchor[new] = x[new]
        self.anchor_normal[new] = grad[new] / np.maximum(np.linalg.norm(grad[new], axis=1), 1e-300)[:, None]
        self.anchored[new] = True
        mu_s = self.friction_coefficients()[0]
        self.friction_limit[:] = np.where(self.anchored, mu_s * self.contact_normal_force(pen), 0.0)
        f_new = self.forces(x, ["friction"])
        return float(np.max(np.linalg.norm(f_new - f_old, axis=1), initial=0.0)), int(gone.sum())

    def dforces_dX(self, x: np.ndarray, dX: np.ndarray, terms=None) -> np.ndarray:
        """d forces(x; X + e dX)/de at e = 0, shape (n, 3) [N per unit e].

        Membrane and gravity analytic (the orthotropic elasticity is fixed to
        the material, not to X); bending by the exact derivative of each
        stencil's weights (forward mode) and, for directional bending, of each
        hinge's stiffness (it turns with the hinge), matrix-free.
        Seams, contact and friction do not depend on X."""
        terms = self._check_terms(terms)
        x = np.ascontiguousarray(x, dtype=np.float64)
        dX = np.ascontiguousarray(dX, dtype=np.float64).reshape(self.n, 2)
        df = np.zeros((self.n, 3))
        if "membrane" in terms:
            K.membrane_dforces_dX(x, self.X, dX, self.tris, self.Dminv, self.tri_area, self.mu, self.lam, df)
        elif "membrane_orthotropic" in terms:
            K.membrane_ortho_dforces_dX(x, self.X, dX, self.tris, self.Dminv, self.tri_area, self.elasticity, df)
        if "gravity" in terms:
            # dA_t = A_t tr(Dminv dDm); m_i = rho/3 sum A_t
            d1 = dX[self.tris[:, 1]] - dX[self.tris[:, 0]]
            d2 = dX[self.tris[:, 2]] - dX[self.tris[:, 0]]
            Di = self.Dminv
            tr = Di[:, 0, 0] * d1[:, 0] + Di[:, 0, 1] * d1[:, 1] + Di[:, 1, 0] * d2[:, 0] + Di[:, 1, 1] * d2[:, 1]
            dA = self.tri_area * tr
            dm = np.zeros(self.n)
            np.add.at(dm, self.tris.reshape(-1), np.repeat(dA * self._rho / 3.0, 3))
            df[:, 1] -= GRAVITY * dm
        if "bending" in terms and len(self.bend_stencils):
            if self.bend_directional:
                # each hinge's stiffness turns with its direction: differentiated too
                K.bending_var_dforces_dX(
                    x, self.X, dX, self.bend_stencils, self.bend_dir, self.bend_warp, BEND_CONSTANT, df
                )
            else:
                K.bending_dforces_dX(x, self.X, dX, self.bend_stencils, self.bend_stiffness * BEND_CONSTANT, df)
        return df

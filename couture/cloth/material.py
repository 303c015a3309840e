"""A garment's fabrics as the cloth model's material constants: per triangle
(membrane elasticity, density) and per bending hinge (stiffness), from the
design's fabric, each panel's own fabric (``Design.panel_fabrics``) and each
panel's grain (``GarmentMesh.panel_grain``).

Membrane (orthotropic StVK, plane stress). In the fabric's axes (1 = warp,
the grain line; 2 = weft) the Green strain e = (e11, e22, γ12 = 2 e12) costs
psi = 1/2 eᵀ C e per unit rest area with

    C = 1/(1 - ν12 ν21) [[E1, ν12 E2, 0], [ν12 E2, E2, 0], [0, 0, G12 (1 - ν12 ν21)]]

(E1 h = ``warp_stiffness``, E2 h = ``weft_stiffness``, G12 h =
``shear_stiffness`` [N/m], ν12 = ``poisson_ratio``, ν21 = ν12 E2 / E1), positive
definite iff E1, E2, G12 > 0 and ν12 ν21 < 1. Each triangle gets C rotated
onto the material axes (x, y) of its panel: the warp is (-sin g, cos g) for
the panel's grain g, the weft (cos g, sin g). An isotropic fabric (E1 = E2 =
E, G12 = E / (2 (1 + ν))) gives C = [[λ+2μ, λ, 0], [λ, λ+2μ, 0], [0, 0, μ]],
today's membrane (``lame_parameters``), at every grain.

Bending. A strip cut at angle β to the warp (its long axis there, as
ASTM D1388 cuts warp, weft and bias strips) bends with the rigidity

    D(β) = k_w cos²β + k_f sin²β + (4 k_b - 2 k_w - 2 k_f) cos²β sin²β

(k_w = ``bend_warp``, k_f = ``bend_weft``, k_b = ``bend_bias`` [N m]): the
lowest-order smooth, π-periodic interpolation through D(0) = k_w, D(π/2) =
k_f, D(π/4) = k_b (``strip_rigidity``; identical to the orthotropic plate's
cylindrical rigidity k_w c⁴ + k_f s⁴ + (4 k_b - k_w - k_f) c² s²).

The discrete energy (Bergou et al. hinges, ``couture.cloth.model``) gives each
hinge its own stiffness k(θ), θ the angle between the hinge's in-plane normal
(the axis of the strip it bends) and the warp. But a cylindrical bend along β
bends hinges of every direction, so the strip feels a blend: writing
k(θ) = a0 + a2 cos 2θ + a4 cos 4θ + (higher harmonics, which the blend
ignores), D(β) = a0 + f2 a2 cos 2β + f4 a4 cos 4β. On an equilateral lattice
f2 = 2/3, f4 = 1/3; on the remesher's quality Delaunay meshes they are
smaller, measured (cylinder energies against the isotropic model's, fitted
over 36 bend directions): f2 = 0.54..0.56, f4 = 0.28..0.30 on sheets of
150..2200 vertices; 0.45, 0.22 on the default skirt's gores at 400
vertices, 0.56, 0.26 at 1600, 0.52, 0.24 at 5600. Giving each hinge D
itself (k = D(θ)) would leave a warp strip of the brief's denim (3, 1.5, 1
x 1e-5 N m) at 2.25 (measured) instead of 3.

Those are imposed bends (every vertex on the cylinder). In equilibrium the
hinge field relaxes off the affine bend, most where its hinges are soft, and
the anisotropic response is about a fifth larger: a sheet bent to a
cylinder with its border held and its interior free (the bench's square
mesh, h = 2.5 mm) measures f2 0.475 imposed, 0.576 relaxed, f4 0.208,
0.260; the cantilever bench's strip mesh f2 0.54 imposed, 0.63 in a
small-deflection cantilever (docs/fabrics.md, Cantilever). So
``BEND_HARMONIC_RESPONSE`` takes the relaxed 0.65, 0.33 (1.2 x 0.54, 0.27):
with the imposed values the ASTM cantilever's warp strips came out stiffer
than their table and the weft strips softer, 2-4 % apart in overhang beyond
the isotropic strip's own error; with these, within about 1 % of it. An
imposed cylinder now measures about 0.54 / 0.65 of D's cos 2β part
(tests/test_orthotropic.py).

So the hinges get a0 = b0, a2 = b2 / f2, a4 = b4 / f4 for D's harmonics
(b0, b2, b4), k(θ) = a0 + a2 cos 2θ + a4 cos 4θ, and every strip bends as
the fabric says (on evenly spread hinge directions). That k must stay
positive (a negative hinge makes the bending Hessian indefinite), which it
does while warp, weft and bias are not too far apart, bias at or above the
mean of warp and weft as a rule. Otherwise (the brief's denim, bias 1 below
weft 1.5 and warp 3) the anisotropic parts are scaled back from the
calibrated ones toward D's own, a2 = b2 (1 + s (1/f2 - 1)), a4 likewise,
with the largest s in [0, 1] that keeps every hinge at least
``BEND_HINGE_FLOOR`` x the softest of the three rigidities; strips then bend
with ``effective_strip_rigidity`` (denim: warp 2.67, weft 1.43, bias 1.20
where D gives 3, 1.5, 1; D on every hinge (s = 0) gives 2.32, 1.34, 1.42
with the response above).
Only the cos 2θ and cos 4θ harmonics are used: a positive law with higher
ones (a maximum-entropy spectrum) matches D on evenly spread hinges but
missed it by 21 % on a sheet meshed along the warp, as a cantilever strip
is. A fabric whose D itself turns negative between warp and bias is
refused (FabricError naming ``bend_bias``).

The bias. D(β) is a plate's cylindrical rigidity: the bend with the strip's
width held straight. A narrow strip cut at 45° to the warp of a plate whose
warp and weft differ is not held: its bending couples to twist (D16 ≠ 0) and
a free strip twists to relieve it, bending with D11 - D16² / D66, less than
D(45°). A fabric's bias rigidity is read off such a strip (ASTM D1388 cuts
25 mm strips; the library's bias entries stand for that reading), so the
plate takes D(45°) = k_b + D16² / D66 (``plate_rigidities``, a fixed point),
with D16 = -¼ dD/dβ = (k_w - k_f) / 4 and D66 = (1 - ν_b) b0 / 2 + b4 (the
plate's rotation invariants, ν_b = -1/3 the hinge energy's coupling,
``couture.cloth.model``): cotton shirting's bias plate 1.7 %, denim's 2.7 %
above the table. Measured on the model before (a relaxed sheet's bending
matrix in the strip's axes, docs/fabrics.md): 0.6 / 1.3 / 2.2 % at +45°,
1.1 / 1.9 / 2.8 % at -45° for chiffon, cotton, denim, against 0.9 / 1.8 /
2.8 % from these invariants. Warp and weft strips (D16 = 0) and isotropic
fabrics are unchanged. Every hinge law and clamp law is built from the
plate's rigidities. An isotropic fabric gets its
bend_stiffness on every hinge. ``kernels.hinge_stiffness`` evaluates k as a
function of u = sin²θ and differentiates it with the rest shape.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from couture.mesh import GarmentMesh

ORTHOTROPIC_FIELDS = ("warp_stiffness", "weft_stiffness", "shear_stiffness")
"""Fabric fields that make a membrane orthotropic when any is given"""

BENDING_FIELDS = ("bend_warp", "bend_weft", "bend_bias")
"""Fabric fields that make bending directional when any is given"""


class FabricError(ValueError):
    """A fabric the model cannot build; ``field`` names it (``fabric.bend_bias``,
    ``panel_fabrics.front.poisson_ratio``), as the message does."""

    def __init__(self, field: str, message: str):
        self.field = field
        self.message = message
        super().__init__(f"{field}: {message}")


def _get(fabric, name: str):
    v = getattr(fabric, name, None)
    return None if v is None else float(v)


def lame_parameters(stretch_stiffness: float, poisson_ratio: float) -> tuple[float, float]:
    """Plane-stress Lamé parameters (mu, lam) [N/m] from E·h [N/m] and nu."""
    nu = poisson_ratio
    mu = stretch_stiffness / (2.0 * (1.0 + nu))
    lam = stretch_stiffness * nu / (1.0 - nu * nu)
    return mu, lam


def is_orthotropic(fabric) -> bool:
    """The fabric gives warp, weft or shear stiffness (else an isotropic membrane)."""
    return any(_get(fabric, f) is not None for f in ORTHOTROPIC_FIELDS)


def has_directional_bending(fabric) -> bool:
    """The fabric gives warp, weft or bias bending (else one bend_stiffness)."""
    return any(_get(fabric, f) is not None for f in BENDING_FIELDS)


def tensile_constants(fabric) -> tuple[float, float, float, float]:
    """(E1, E2, nu12, G12) [N/m, N/m, -, N/m]: warp, weft, Poisson coupling,
    shear, with the schema's defaults for fields left out (stretch_stiffness;
    shear stretch_stiffness / (2 (1 + nu)))."""
    E = float(fabric.stretch_stiffness)
    nu = float(fabric.poisson_ratio)
    E1 = _get(fabric, "warp_stiffness")
    E2 = _get(fabric, "weft_stiffness")
    G = _get(fabric, "shear_stiffness")
    return (E if E1 is None else E1, E if E2 is None else E2, nu, E / (2.0 * (1.0 + nu)) if G is None else G)


def reference_stretch_stiffness(fabric) -> float:
    """[N/m] the isotropic stiffness that stands for the fabric where the model
    needs one number (default seam and contact stiffness, residual floor,
    sensitivity floor): stretch_stiffness, or the mean of warp and weft."""
    if not is_orthotropic(fabric):
        return float(fabric.stretch_stiffness)
    E1, E2, _, _ = tensile_constants(fabric)
    return 0.5 * (E1 + E2)


def reference_lame(fabric) -> tuple[float, float]:
    """(mu, lam) [N/m] of ``reference_stretch_stiffness`` and the fabric's nu."""
    return lame_parameters(reference_stretch_stiffness(fabric), float(fabric.poisson_ratio))


def orthotropic_elasticity(fabric, prefix: str = "fabric") -> np.ndarray:
    """(3, 3) C [N/m] in the fabric's axes (warp, weft, γ) (module docstring);
    raises FabricError naming the field when C is not positive definite."""
    E1, E2, nu12, G = tensile_constants(fabric)
    for name, v in (("warp_stiffness", E1), ("weft_stiffness", E2), ("shear_stiffness", G)):
        if _get(fabric, name) is None:
            name = "stretch_stiffness"  # the default it stands for
        if not (np.isfinite(v) and v > 0):
            raise FabricError(f"{prefix}.{name}", f"{v!r} N/m: the membrane needs a positive finite stiffness")
    nu21 = nu12 * E2 / E1
    if not (np.isfinite(nu12) and nu12 * nu21 < 1.0):
        raise FabricError(
            f"{prefix}.poisson_ratio",
            f"{nu12!r} with warp {E1:g} and weft {E2:g} N/m gives nu12 nu21 = {nu12 * nu21:.3g} >= 1: "
            f"the orthotropic membrane is not positive definite (needs nu12 < sqrt(E1/E2) = {np.sqrt(E1 / E2):.3g})",
        )
    d = 1.0 - nu12 * nu21
    return np.array([[E1 / d, nu12 * E2 / d, 0.0], [nu12 * E2 / d, E2 / d, 0.0], [0.0, 0.0, G]])


def rotate_elasticity(C_local: np.ndarray, warp: np.ndarray) -> np.ndarray:
    """C (3, 3) in the fabric's axes -> (m, 3, 3) on the material axes for the
    unit warp directions ``warp`` (m, 2) (the weft is the warp turned -90°):
    v_local = T v with v = (E_xx, E_yy, 2 E_xy), C = Tᵀ C_local T."""
    a0, a1 = warp[:, 0], warp[:, 1]
    b0, b1 = a1, -a0  # weft (cos g, sin g) for warp (-sin g, cos g)
    T = np.empty((len(warp), 3, 3))
    T[:, 0] = np.column_stack([a0 * a0, a1 * a1, a0 * a1])
    T[:, 1] = np.column_stack([b0 * b0, b1 * b1, b0 * b1])
    T[:, 2] = np.column_stack([2 * a0 * b0, 2 * a1 * b1, a0 * b1 + a1 * b0])
    return np.einsum("tpi,pq,tqj->tij", T, C_local, T)


BEND_HARMONIC_RESPONSE = (0.65, 0.33)
"""(f2, f4): the share of a hinge stiffness's cos 2θ and cos 4θ parts that a
strip feels in equilibrium on the remesher's meshes, 1.2 x the imposed
cylinder's (module docstring)"""


def bend_rigidities(fabric) -> tuple[float, float, float]:
    """(k_w, k_f, k_b) [N m] along warp, weft and bias with the schema's
    defaults (bend_stiffness; bias the mean of warp and weft)."""
    k = float(fabric.bend_stiffness)
    kw = _get(fabric, "bend_warp")
    kf = _get(fabric, "bend_weft")
    kw = k if kw is None else kw
    kf = k if kf is None else kf
    kb = _get(fabric, "bend_bias")
    return kw, kf, 0.5 * (kw + kf) if kb is None else kb


def strip_rigidity(kw: float, kf: float, kb: float, beta) -> np.ndarray:
    """D(β) [N m]: the rigidity of a strip cut at β [rad] to the warp (module docstring)."""
    c2 = np.cos(beta) ** 2
    s2 = 1.0 - c2
    return kw * c2 + kf * s2 + (4.0 * kb - 2.0 * kw - 2.0 * kf) * c2 * s2


BEND_PLATE_POISSON = -1.0 / 3.0
"""ν_b: the bending coupling of the hinge energy's plate (``couture.cloth.model``)"""


def bias_twist_relief(kw: float, kf: float, kb_plate: float) -> float:
    """D16² / D66 [N m] at 45° to the warp: how much less than the plate's
    cylindrical rigidity ``kb_plate`` a narrow strip cut on the bias bends
    with when it is free to twist (module docstring, "The bias")."""
    d16 = 0.25 * (kw - kf)
    b0 = 0.25 * (kw + kf + 2.0 * kb_plate)
    b4 = 0.25 * (kw + kf - 2.0 * kb_plate)
    d66 = 0.5 * (1.0 - BEND_PLATE_POISSON) * b0 + b4
    return d16 * d16 / d66


def plate_rigidities(kw: float, kf: float, kb: float) -> tuple[float, float, float]:
    """(k_w, k_f, D(45°)) [N m]: the cylindrical rigidities of the plate whose
    warp, weft and bias strips, free to twist as a cantilever's are, bend with
    (k_w, k_f, k_b) (module docstring, "The bias"); k_w = k_f gives k_b back."""
    if kw == kf:
        return kw, kf, kb
    kp = kb
    for _ in range(100):
        nxt = kb + bias_twist_relief(kw, kf, kp)
        if not 0.0 < nxt < 10.0 * max(kw, kf, kb):
            break
        if abs(nxt - kp) <= 1e-14 * kb:
            return kw, kf, nxt
        kp = nxt
    raise FabricError(
        "bend_bias", f"{kb:g} N m with bend_warp {kw:g} and bend_weft {kf:g}: no plate's free bias strip bends with it"
    )


BEND_HINGE_FLOOR = 0.25
"""no hinge softer than this share of min(k_w, k_f, k_b) (module docstring)"""


def _hinge_harmonics(kw: float, kf: float, kb: float, field: str) -> tuple[float, float, float]:
    """(a0, a2, a4) [N m] of the hinge law k(θ) = a0 + a2 cos 2θ + a4 cos 4θ (module docstring)."""
    f2, f4 = BEND_HARMONIC_RESPONSE
    b0, b2, b4 = (kw + kf + 2.0 * kb) / 4.0, (kw - kf) / 2.0, (kw + kf - 2.0 * kb) / 4.0
    if b2 == 0.0 and b4 == 0.0:
        return b0, 0.0, 0.0
    th = np.linspace(0.0, 0.5 * np.pi, 721)  # k is even and π-periodic
    c2, c4 = np.cos(2.0 * th), np.cos(4.0 * th)

    def parts(s: float) -> tuple[float, float]:
        return b2 * (1.0 + s * (1.0 / f2 - 1.0)), b4 * (1.0 + s * (1.0 / f4 - 1.0))

    def lowest(s: float) -> float:
        a2, a4 = parts(s)
        return float(np.min(b0 + a2 * c2 + a4 * c4))

    if lowest(0.0) < -1e-12 * max(kw, kf, kb):
        u = np.linspace(1e-3, 1 - 1e-3, 999)
        need = float(np.max(0.5 * (kw + kf) - (kw * (1 - u) + kf * u) / (4.0 * u * (1 - u))))
        raise FabricError(
            field,
            f"{kb:g} N m with bend_warp {kw:g} and bend_weft {kf:g}: the strip rigidity "
            f"D(β) = kw cos²β + kf sin²β + (4 kb - 2 kw - 2 kf) cos²β sin²β turns negative between "
            f"warp and bias; bend_bias must be at least {need:.3g} N m",
        )
    floor = BEND_HINGE_FLOOR * min(kw, kf, kb)
    if lowest(1.0) >= floor:
        s = 1.0
    elif lowest(0.0) < floor:
        s = 0.0
    else:  # lowest(s) is concave in s: the s that keep the floor are an interval from 0
        lo, hi = 0.0, 1.0
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if lowest(mid) >= floor else (lo, mid)
        s = lo
    a2, a4 = parts(s)
    return b0, a2, a4


def hinge_law(kw: float, kf: float, kb: float, field: str = "fabric.bend_bias") -> np.ndarray:
    """(6,) (p0, p1, p2, q0, q1, q2): the hinge stiffness k = (p0 + p1 u + p2 u²) /
    (q0 + q1 u + q2 u²) [N m], u = sin²θ (q = (1, 0, 0): a polynomial, the
    kernel takes the general form), for strips of rigidities (k_w, k_f, k_b)
    (module docstring); raises FabricError naming ``field`` for a fabric whose
    strip rigidity turns negative."""
    a0, a2, a4 = _hinge_harmonics(kw, kf, kb, field)
    # cos 2θ = 1 - 2u, cos 4θ = 1 - 8u + 8u²
    return np.array([a0 + a2 + a4, -2.0 * a2 - 8.0 * a4, 8.0 * a4, 1.0, 0.0, 0.0])


def strip_law(kw: float, kf: float, kb: float) -> np.ndarray:
    """(6,) the strip rigidity D(θ) itself (``strip_rigidity``) in ``hinge_law``'s
    form, u = sin²θ: D = k_w + (4 k_b - 3 k_w - k_f) u - (4 k_b - 2 k_w - 2 k_f) u².
    For hinges that all lie along one line (a clamp's, ``couture.cloth.model``):
    they bend only across it, so each carries D of its own direction, not the
    law calibrated for evenly spread hinge directions."""
    d4 = 4.0 * kb - 2.0 * kw - 2.0 * kf
    return np.array([kw, 4.0 * kb - 3.0 * kw - kf, -d4, 1.0, 0.0, 0.0])


def hinge_stiffness_at(law: np.ndarray, theta) -> np.ndarray:
    """k(θ) [N m] of a hinge law (``hinge_law``), θ [rad] from the warp to the hinge's normal."""
    u = np.sin(theta) ** 2
    return (law[0] + u * (law[1] + u * law[2])) / (law[3] + u * (law[4] + u * law[5]))


def effective_strip_rigidity(kw: float, kf: float, kb: float, beta) -> np.ndarray:
    """[N m] what a strip cut at β [rad] to the warp bends with in this model
    (evenly spread hinge directions): ``strip_rigidity`` where the hinge law
    could be calibrated fully, else between it and the blend of D (module docstring)."""
    f2, f4 = BEND_HARMONIC_RESPONSE
    a0, a2, a4 = _hinge_harmonics(kw, kf, kb, "bend_bias")
    return a0 + f2 * a2 * np.cos(2.0 * np.asarray(beta)) + f4 * a4 * np.cos(4.0 * np.asarray(beta))


def check_fabric(fabric, prefix: str = "fabric") -> None:
    """What the model needs of a fabric beyond its ranges
    (``couture.pattern.limits``): a positive definite membrane and a hinge
    law; raises FabricError naming the field."""
    orthotropic_elasticity(fabric, prefix)
    hinge_law(*bend_rigidities(fabric), field=f"{prefix}.bend_bias")


def check_panel_names(panel_fabrics: dict, panel_names: list[str]) -> None:
    """Every panel a fabric is given to is a panel of the mesh; raises FabricError."""
    for name in panel_fabrics:
        if name not in panel_names:
            raise FabricError(f"panel_fabrics.{name}", f"no panel {name!r} in the mesh; panels are {panel_names}")


@dataclass
class GarmentMaterial:
    """Material constants of a garment mesh (``resolve``)."""

    fabrics: list
    """the distinct fabrics in use; ``fabrics[0]`` is the design's"""
    fabric_paths: list[str]
    """each fabric's path in the design (``fabric``, ``panel_fabrics.<panel>``)"""
    tri_fabric: np.ndarray
    """index into ``fabrics`` of every triangle, (m,) int"""
    warp: np.ndarray
    """unit warp direction of every triangle in material space, (m, 2)"""
    orthotropic: bool
    """a per-triangle elasticity is needed: an orthotropic fabric, or panels whose
    membranes or densities differ (else one isotropic fabric: today's membrane)"""
    directional_bending: bool
    """per-hinge bending stiffness is needed (directional or per-panel bending)"""

    @property
    def uniform(self) -> bool:
        return not self.orthotropic

    def elasticity(self) -> np.ndarray:
        """(m, 3, 3) Voigt C [N/m] of every triangle on the material axes."""
        C = np.empty((len(self.tri_fabric), 3, 3))
        for i, (fab, path) in enumerate(zip(self.fabrics, self.fabric_paths, strict=True)):
            sel = self.tri_fabric == i
            if sel.any():
                C[sel] = rotate_elasticity(orthotropic_elasticity(fab, path), self.warp[sel])
        return C

    def density(self) -> np.ndarray:
        """(m,) area density [kg/m²] of every triangle."""
        rho = np.array([float(f.area_density) for f in self.fabrics])
        return rho[self.tri_fabric]

    def bending(self, stencil_tri: np.ndarray, clamped: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(law (e, 6) ``hinge_law`` [N m], warp (e, 2)) of every hinge, from the
        fabric and grain of its first triangle ``stencil_tri`` (e,); the hinges
        ``clamped`` (e,) bool get ``strip_law`` instead (a clamp line's)."""
        laws = np.array(
            [_plate_law(f, f"{p}.bend_bias") for f, p in zip(self.fabrics, self.fabric_paths, strict=True)]
        ).reshape(-1, 6)
        fi = self.tri_fabric[stencil_tri]
        law = laws[fi]
        if clamped is not None and clamped.any():
            strip = np.array([strip_law(*plate_rigidities(*bend_rigidities(f))) for f in self.fabrics]).reshape(-1, 6)
            law[clamped] = strip[fi[clamped]]
        return np.ascontiguousarray(law), np.ascontiguousarray(self.warp[stencil_tri])


def _plate_law(fabric, field: str) -> np.ndarray:
    """The hinge law of a fabric's plate (``plate_rigidities``); a table
    whose strip rigidity turns negative is refused first, naming ``field``."""
    table = bend_rigidities(fabric)
    hinge_law(*table, field=field)
    return hinge_law(*plate_rigidities(*table), field=field)


_MEMBRANE_KEYS = ("stretch_stiffness", "poisson_ratio", "area_density") + ORTHOTROPIC_FIELDS
_BENDING_KEYS = ("bend_stiffness",) + BENDING_FIELDS


def _values(fabric, keys) -> tuple:
    return tuple(_get(fabric, k) for k in keys)


def resolve(mesh: GarmentMesh, fabric, panel_fabrics: dict | None = None) -> GarmentMaterial:
    """Each triangle's fabric (its panel's own in ``panel_fabrics``, by panel
    name, else ``fabric``) and warp direction (its panel's grain); raises
    FabricError for a panel_fabrics name the mesh has no panel of."""
    panel_fabrics = dict(panel_fabrics or {})
    names = list(mesh.panel_names)
    check_panel_names(panel_fabrics, names)
    fabrics = [fabric]
    paths = ["fabric"]
    panel_fab = np.zeros(mesh.n_panels, np.int64)
    for p, name in enumerate(names):
        if name in panel_fabrics:
            fabrics.append(panel_fabrics[name])
            paths.append(f"panel_fabrics.{name}")
            panel_fab[p] = len(fabrics) - 1
    tri_fabric = panel_fab[mesh.tri_panel] if len(mesh.tri_panel) else np.zeros(0, np.int64)
    used = sorted(set(tri_fabric.tolist())) or [0]
    memb = {_values(fabrics[i], _MEMBRANE_KEYS) for i in used}
    bend = {_values(fabrics[i], _BENDING_KEYS) for i in used}
    orthotropic = len(memb) > 1 or any(is_orthotropic(fabrics[i]) for i in used)
    directional = len(bend) > 1 or any(has_directional_bending(fabrics[i]) for i in used)
    return GarmentMaterial(fabrics, paths, tri_fabric, mesh.warp_directions(), orthotropic, directional)

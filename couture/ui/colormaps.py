"""Per-triangle strain, stress and body-contact pressure of a drape, and the
banded colour scales the 3D view paints them with (Volino 2005 §3.4.3:
"strain or stress diagrams ... pressure of the garment on the body skin").

Pure numpy, no viser: the view calls these on every drape it renders, so they
are vectorised over triangles (a 10k-vertex garment takes about a millisecond).

Conventions: ``X`` rest (pattern) positions [m], shape (n, 2); ``x`` draped
positions [m], shape (n, 3); ``tris`` shape (m, 3), counter-clockwise in X.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FABRIC_FIELDS = ("fabric_strain", "warp_strain", "weft_strain", "bias_strain")
"""CLO's fabric mode: strain as a share of the fabric's own wearable stretch
limit [%], the largest of warp, weft and bias, or one direction alone
(``fabric_strain_shares``)"""

FIELDS = ("none", "strain", "stress", "pressure") + FABRIC_FIELDS
"""colour-map choices offered by the 3D view"""


def deformation_gradients(X: np.ndarray, x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Per-triangle deformation gradient F = Ds Dm^-1, shape (m, 3, 2).

    Degenerate rest triangles (zero area) get F = 0 rather than inf.
    """
    X = np.asarray(X, np.float64)
    x = np.asarray(x, np.float64)
    t = np.asarray(tris)
    Dm = np.stack([X[t[:, 1]] - X[t[:, 0]], X[t[:, 2]] - X[t[:, 0]]], axis=-1)  # (m, 2, 2)
    Ds = np.stack([x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]]], axis=-1)  # (m, 3, 2)
    det = Dm[:, 0, 0] * Dm[:, 1, 1] - Dm[:, 0, 1] * Dm[:, 1, 0]
    safe = np.where(np.abs(det) > 1e-300, det, 1.0)
    inv = np.empty_like(Dm)
    inv[:, 0, 0] = Dm[:, 1, 1] / safe
    inv[:, 1, 1] = Dm[:, 0, 0] / safe
    inv[:, 0, 1] = -Dm[:, 0, 1] / safe
    inv[:, 1, 0] = -Dm[:, 1, 0] / safe
    inv[np.abs(det) <= 1e-300] = 0.0
    return Ds @ inv


def green_strain(X: np.ndarray, x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Green-Lagrange strain E = (F^T F - I) / 2 per triangle, shape (m, 2, 2), dimensionless."""
    F = deformation_gradients(X, x, tris)
    C = np.einsum("mki,mkj->mij", F, F)
    return 0.5 * (C - np.eye(2))


def _sym2_eigvals(A: np.ndarray) -> np.ndarray:
    """Eigenvalues of symmetric 2x2 matrices, shape (m, 2), ascending."""
    a, b, d = A[:, 0, 0], 0.5 * (A[:, 0, 1] + A[:, 1, 0]), A[:, 1, 1]
    mean = 0.5 * (a + d)
    rad = np.sqrt(0.25 * (a - d) ** 2 + b * b)
    return np.stack([mean - rad, mean + rad], axis=-1)


def principal_strain(X: np.ndarray, x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Principal Green strains per triangle, shape (m, 2), ascending (min, max)."""
    return _sym2_eigvals(green_strain(X, x, tris))


def lame_membrane(stretch_stiffness: float, poisson_ratio: float) -> tuple[float, float]:
    """Plane-stress Lamé parameters (λ, μ) [N/m] from the membrane stiffness
    E·h [N/m] and Poisson's ratio."""
    E, nu = float(stretch_stiffness), float(poisson_ratio)
    return E * nu / (1.0 - nu * nu), E / (2.0 * (1.0 + nu))


def principal_stress(
    X: np.ndarray, x: np.ndarray, tris: np.ndarray, stretch_stiffness: float, poisson_ratio: float = 0.3
) -> np.ndarray:
    """Principal membrane tensions [N/m] per triangle, shape (m, 2), ascending.

    St. Venant-Kirchhoff: second Piola-Kirchhoff S = λ tr(E) I + 2 μ E, pushed
    to the deformed surface as the Cauchy membrane tension σ = F S F^T / J
    (J = deformed / rest area); its two non-zero eigenvalues are those of
    S C / J with C = F^T F.
    """
    lam, mu = lame_membrane(stretch_stiffness, poisson_ratio)
    F = deformation_gradients(X, x, tris)
    C = np.einsum("mki,mkj->mij", F, F)
    E = 0.5 * (C - np.eye(2))
    trE = E[:, 0, 0] + E[:, 1, 1]
    S = 2.0 * mu * E
    S[:, 0, 0] += lam * trE
    S[:, 1, 1] += lam * trE
    J = np.sqrt(np.maximum(C[:, 0, 0] * C[:, 1, 1] - C[:, 0, 1] * C[:, 1, 0], 0.0))
    M = S @ C
    tr = M[:, 0, 0] + M[:, 1, 1]
    det = M[:, 0, 0] * M[:, 1, 1] - M[:, 0, 1] * M[:, 1, 0]
    rad = np.sqrt(np.maximum(0.25 * tr * tr - det, 0.0))
    ev = np.stack([0.5 * tr - rad, 0.5 * tr + rad], axis=-1)
    return ev / np.where(J > 1e-12, J, 1.0)[:, None]


WEARABLE_TENSION = 98.07
"""[N/m] the standard force per width at which a fabric reaches its wearable
stretch limit: 100 gf/cm, the top load of FAST-3's extensibility test (E100,
warp and weft extension at 100 gf/cm). It sits above draping (a drape loads
cloth with ~1-20 N/m, the range the library's stiffnesses are secants over)
and below strength testing (KES-F EMT's 500 gf/cm); by Laplace's law p = T / r
it presses a 12 cm-radius waist with 0.8 kPa."""


def stretch_limits(fabric, tension: float = WEARABLE_TENSION) -> np.ndarray:
    """(3,) the fabric's wearable stretch limits along warp, weft and bias
    (engineering strain, dimensionless): the strain of a strip cut in that
    direction and pulled with ``tension`` [N/m] alone (uniaxial) in the
    model's small-strain reading, ε = T nᵀ C⁻¹ n for the fabric's membrane C
    in its axes (``couture.cloth.material.orthotropic_elasticity``, warp,
    weft, engineering shear) and n = (c², s², c s) of the strip's direction
    at β = 0, π/2, π/4 from the warp. Warp and weft give T / E1 and T / E2,
    the bias T (1/E1 + 1/E2 + 1/G12 - 2 ν12/E1) / 4: a woven's soft shear
    makes its bias limit the largest. An isotropic fabric gets T / E in every
    direction. Raises FabricError (naming the field) for a fabric the model
    cannot build, ValueError for a tension that is not positive."""
    from couture.cloth.material import orthotropic_elasticity

    t = float(tension)
    if not (np.isfinite(t) and t > 0):
        raise ValueError(f"stretch limit tension {tension!r} N/m: must be positive and finite")
    compliance = np.linalg.inv(orthotropic_elasticity(fabric))
    c = np.sqrt(0.5)
    n = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [c * c, c * c, c * c]])
    return t * np.einsum("di,ij,dj->d", n, compliance, n)


def fiber_strains(X: np.ndarray, x: np.ndarray, tris: np.ndarray, warp: np.ndarray) -> np.ndarray:
    """Per-triangle stretch along warp, weft and bias, shape (m, 3),
    engineering strain |F d| - 1 (dimensionless, negative: compressed) for the
    rest-space unit direction d: the warp ``warp`` (m, 2) (its panel's grain,
    ``GarmentMesh.warp_directions``), the weft (the warp turned -90°), and of
    the two biases (warp ± weft)/√2 the more stretched one."""
    F = deformation_gradients(X, x, tris)
    a = np.asarray(warp, np.float64).reshape(-1, 2)
    if len(a) != len(F):
        raise ValueError(f"fiber_strains: {len(a)} warp directions for {len(F)} triangles")
    b = np.column_stack([a[:, 1], -a[:, 0]])  # weft (cos g, sin g) for warp (-sin g, cos g)
    r = np.sqrt(0.5)

    def stretch(d: np.ndarray) -> np.ndarray:
        return np.linalg.norm(np.einsum("mij,mj->mi", F, d), axis=1) - 1.0

    bias = np.maximum(stretch(r * (a + b)), stretch(r * (a - b)))
    return np.column_stack([stretch(a), stretch(b), bias])


@dataclass
class FabricAxes:
    """Per-triangle fabric directions and stretch limits of a garment
    (``fabric_axes``): what the fabric-mode maps read."""

    warp: np.ndarray
    """unit warp direction of every triangle in material space, (m, 2)"""
    limit: np.ndarray
    """wearable stretch limit along warp, weft and bias of every triangle's
    fabric (``stretch_limits``), (m, 3), dimensionless"""


def fabric_axes(mesh, fabric, panel_fabrics: dict | None = None, tension: float = WEARABLE_TENSION) -> FabricAxes:
    """Each triangle's warp (its panel's grain) and its fabric's stretch limits
    (its panel's own in ``panel_fabrics``, else ``fabric``); raises
    FabricError for a panel the mesh lacks or a fabric the model cannot build."""
    from couture.cloth.material import resolve

    mat = resolve(mesh, fabric, panel_fabrics)
    limits = np.array([stretch_limits(f, tension) for f in mat.fabrics]).reshape(-1, 3)
    return FabricAxes(mat.warp, limits[mat.tri_fabric])


def fabric_strain_shares(strains: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """Strain as a share of the stretch limit [%], (m, 3) for ``strains`` and
    ``limit`` (m, 3) (or (3,)): 100 where a direction reaches its limit,
    negative where it is compressed."""
    return 100.0 * np.asarray(strains, np.float64) / np.asarray(limit, np.float64)


def fabric_strain(shares: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(share [%], dominant direction) per triangle from ``fabric_strain_shares``
    (m, 3): the largest stretch share over warp, weft and bias, 0 where all
    are compressed (a compressed fabric buckles into wrinkles, it does not
    press on the wearer), and which direction it is (0 warp, 1 weft, 2 bias,
    CLO's "dominant direction")."""
    s = np.asarray(shares, np.float64)
    dominant = np.argmax(s, axis=1)
    return np.maximum(s[np.arange(len(s)), dominant], 0.0), dominant


def rest_vertex_areas(X: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Lumped rest area per vertex [m²] (a third of each incident triangle), shape (n,)."""
    X = np.asarray(X, np.float64)
    e1 = X[tris[:, 1]] - X[tris[:, 0]]
    e2 = X[tris[:, 2]] - X[tris[:, 0]]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    out = np.zeros(len(X))
    for k in range(3):
        np.add.at(out, tris[:, k], area / 3.0)
    return out


def contact_pressure(
    X: np.ndarray,
    tris: np.ndarray,
    signed_distance: np.ndarray,
    offset: float = 0.01,
    contact_stiffness: float = 100.0,
    smoothing: float = 0.0,
) -> np.ndarray:
    """Body-contact pressure per vertex [Pa], shape (n,).

    The cloth model's contact force per vertex, over the vertex's lumped rest
    area: the penalty of ``couture.cloth.model.penalty_force`` (the solver's
    law: stiffness ``contact_stiffness`` k [N/m] with a ramp of width
    ``smoothing`` [m]; 0: the plain f = k (offset - d)) of the penetration of
    the ``offset`` [m] layer by ``signed_distance`` d [m] (positive outside
    the body).
    """
    from couture.cloth.model import penalty_force

    d = np.asarray(signed_distance, np.float64)
    force = penalty_force(offset - d, contact_stiffness, smoothing)
    area = rest_vertex_areas(X, tris)
    return force / np.maximum(area, 1e-12)


def solver_contact_stiffness(stretch_stiffness: float, poisson_ratio: float, scale: float = 1.0) -> float:
    """[N/m] the contact stiffness the solver nodes build for this fabric:
    CONTACT_STIFFNESS_PER_MU times the membrane shear modulus, times the
    design's ``contact_stiffness_scale``."""
    from couture.cloth.model import CONTACT_STIFFNESS_PER_MU, lame_parameters

    mu, _ = lame_parameters(stretch_stiffness, poisson_ratio)
    return float(scale) * CONTACT_STIFFNESS_PER_MU * mu


class BodyDistance:
    """Signed distance to a body [m] (positive outside): the solver's own grid
    SDF of that body (``couture.cloth.body.load_mannequin_sdf``, cached on
    disk), so the pressure map shows the contact the solver computed. (A
    nearest-vertex distance was good to about 1 cm, the whole contact layer.)"""

    def __init__(self, name: str = "default"):
        from couture.cloth.body import load_mannequin_sdf

        self.name = name
        self.sdf = load_mannequin_sdf(name=name, verbose=False)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        phi, _ = self.sdf.phi_grad(np.ascontiguousarray(points, dtype=np.float64))
        return phi


# --- colour scales -----------------------------------------------------------

# Control points of perceptually ordered maps (sampled from matplotlib's
# 'viridis' and a blue-white-red diverging map), RGB in 0..1.
_VIRIDIS = np.array(
    [
        [0.267, 0.005, 0.329],
        [0.283, 0.141, 0.458],
        [0.254, 0.265, 0.530],
        [0.207, 0.372, 0.553],
        [0.164, 0.471, 0.558],
        [0.128, 0.567, 0.551],
        [0.135, 0.659, 0.518],
        [0.267, 0.749, 0.441],
        [0.478, 0.821, 0.318],
        [0.741, 0.873, 0.150],
        [0.993, 0.906, 0.144],
    ]
)
_DIVERGING = np.array(
    [
        [0.230, 0.299, 0.754],
        [0.552, 0.690, 0.996],
        [0.866, 0.866, 0.866],
        [0.958, 0.603, 0.482],
        [0.706, 0.016, 0.150],
    ]
)


def _interp(table: np.ndarray, t: np.ndarray) -> np.ndarray:
    t = np.clip(np.asarray(t, np.float64), 0.0, 1.0) * (len(table) - 1)
    i = np.minimum(t.astype(int), len(table) - 2)
    f = (t - i)[..., None]
    return table[i] * (1 - f) + table[i + 1] * f


@dataclass
class ColorScale:
    """A banded colour scale: ``n_bands`` equal intervals over [lo, hi]."""

    lo: float
    hi: float
    n_bands: int = 9
    diverging: bool = False
    unit: str = ""
    label: str = ""

    def band_of(self, values: np.ndarray) -> np.ndarray:
        """Band index of each value, shape like values, int, clamped to 0..n_bands-1."""
        span = self.hi - self.lo
        if not np.isfinite(span) or span <= 0:
            return np.full(np.shape(values), self.n_bands // 2, dtype=np.int32)
        t = (np.nan_to_num(np.asarray(values, np.float64), nan=self.lo) - self.lo) / span
        return np.clip((t * self.n_bands).astype(np.int64), 0, self.n_bands - 1).astype(np.int32)

    def band_colors(self) -> np.ndarray:
        """RGB uint8 of each band, shape (n_bands, 3)."""
        t = (np.arange(self.n_bands) + 0.5) / self.n_bands
        rgb = _interp(_DIVERGING if self.diverging else _VIRIDIS, t)
        return np.round(rgb * 255).astype(np.uint8)

    def edges(self) -> np.ndarray:
        return np.linspace(self.lo, self.hi, self.n_bands + 1)

    def legend_html(self) -> str:
        """A vertical legend: one swatch per band with its value interval."""
        cols = self.band_colors()
        e = self.edges()
        rows = []
        for b in reversed(range(self.n_bands)):
            r, g, bl = (int(c) for c in cols[b])
            rows.append(
                f'<div style="display:flex;align-items:center;gap:6px;font-size:11px;line-height:14px">'
                f'<span style="display:inline-block;width:18px;height:12px;background:rgb({r},{g},{bl})"></span>'
                f"<span>{_fmt(e[b])} … {_fmt(e[b + 1])}</span></div>"
            )
        head = f'<div style="font-size:12px;font-weight:600">{self.label} [{self.unit}]</div>' if self.label else ""
        return f'<div id="couture-legend">{head}{"".join(rows)}</div>'


def _fmt(v: float) -> str:
    return f"{v:.3g}" if v != 0 else "0"


def auto_scale(field: str, values: np.ndarray, n_bands: int = 9) -> ColorScale:
    """A colour scale for ``values`` of the named field, range from robust
    percentiles (2 %, 98 %) so a few extreme triangles do not wash the map out.
    Strain and stress are diverging about zero (compression blue, tension red),
    pressure is sequential from zero."""
    v = np.asarray(values, np.float64)
    v = v[np.isfinite(v)]
    if field == "fabric_strain":  # CLO's fabric mode: no strain to the limit (top band: at or past it)
        return ColorScale(0.0, 100.0, n_bands, False, "% of limit", "strain / fabric's stretch limit")
    if field in FABRIC_FIELDS:
        name = field.split("_")[0]
        return ColorScale(-100.0, 100.0, n_bands, True, "% of limit", f"{name} strain / its stretch limit")
    if field == "pressure":
        hi = float(np.percentile(v, 98)) if v.size else 1.0
        return ColorScale(0.0, hi if hi > 0 else 1.0, n_bands, False, "Pa", "contact pressure")
    a = float(np.percentile(np.abs(v), 98)) if v.size else 1.0
    a = a if a > 0 else 1e-6
    if field == "strain":
        return ColorScale(-a, a, n_bands, True, "", "max principal Green strain")
    return ColorScale(-a, a, n_bands, True, "N/m", "max principal tension")


def field_values(
    field: str,
    X: np.ndarray,
    x: np.ndarray,
    tris: np.ndarray,
    *,
    stretch_stiffness: float = 20.0,
    poisson_ratio: float = 0.3,
    body_distance: BodyDistance | None = None,
    contact_offset: float = 0.01,
    contact_stiffness: float | None = None,
    contact_smoothing: float = 0.001,
    axes: FabricAxes | None = None,
) -> np.ndarray | None:
    """Per-triangle scalar for a colour-map field (None for 'none', or for
    'pressure' without a body). Pressure, defined per vertex, is averaged to
    triangles. The fabric fields (``FABRIC_FIELDS``) read each triangle's warp
    and stretch limits from ``axes`` (``fabric_axes``); without it, an
    isotropic fabric of ``stretch_stiffness`` and ``poisson_ratio`` on the
    straight grain."""
    if field in FABRIC_FIELDS:
        if axes is None:
            from schemas.design import Fabric

            iso = Fabric(stretch_stiffness=stretch_stiffness, poisson_ratio=poisson_ratio)
            axes = FabricAxes(np.tile([0.0, 1.0], (len(tris), 1)), np.tile(stretch_limits(iso), (len(tris), 1)))
        shares = fabric_strain_shares(fiber_strains(X, x, tris, axes.warp), axes.limit)
        if field == "fabric_strain":
            return fabric_strain(shares)[0]
        return shares[:, FABRIC_FIELDS.index(field) - 1]
    if field == "strain":
        return principal_strain(X, x, tris)[:, 1]
    if field == "stress":
        return principal_stress(X, x, tris, stretch_stiffness, poisson_ratio)[:, 1]
    if field == "pressure":
        if body_distance is None:
            return None
        k = (
            solver_contact_stiffness(stretch_stiffness, poisson_ratio)
            if contact_stiffness is None
            else contact_stiffness
        )
        p = contact_pressure(X, tris, body_distance(x), contact_offset, k, contact_smoothing)
        return p[tris].mean(axis=1)
    return None

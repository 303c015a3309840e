"""Woven fabrics (issue 30): the orthotropic membrane along each panel's grain,
directional bending, per-panel fabrics and the grain on the mesh message.

Every new term against central differences (gradient, Hessian, the rest-shape
derivative and its sensitivity matrix), the isotropic limits against today's
membrane, a uniaxial pull along warp, weft and bias against the textbook
compliance, and the refusals of a fabric the model cannot build."""

from __future__ import annotations

import dataclasses
import math

import msgspec
import numpy as np
import pytest
from fdcheck import check_gradient, check_hessian, check_jacobian

from couture.cloth import ClothModel, Scene
from couture.cloth import kernels as K
from couture.cloth.material import (
    BEND_HARMONIC_RESPONSE,
    BEND_HINGE_FLOOR,
    FabricError,
    effective_strip_rigidity,
    hinge_law,
    hinge_stiffness_at,
    lame_parameters,
    plate_rigidities,
    strip_rigidity,
)
from couture.cloth.model import BEND_CONSTANT, CLAMP_HINGE_FACTOR, bending_weights, clamped_hinges
from couture.cloth.testing import random_drape, small_quality_mesh
from couture.mesh import GarmentMesh, grid_sheet
from couture.sensitivity.dfdx import DForcesDX
from schemas.convert import mesh_to_msg, msg_to_mesh
from schemas.design import Fabric
from schemas.messages import MeshMsg, SchemaError, decode, encode

ISO = Fabric(stretch_stiffness=50.0, poisson_ratio=0.3, bend_stiffness=1e-4, area_density=0.15)
DENIM = Fabric(
    stretch_stiffness=2000.0,
    poisson_ratio=0.3,
    bend_stiffness=2e-5,
    area_density=0.4,
    warp_stiffness=3000.0,
    weft_stiffness=1500.0,
    shear_stiffness=50.0,
    bend_warp=3e-5,
    bend_weft=1.5e-5,
    bend_bias=1e-5,
)
"""the brief's denim-like fabric [N/m, N m]"""


def two_panels(grain=(0.3, -0.7), seed=0) -> GarmentMesh:
    """Two small quality-meshed panels 'a' and 'b' side by side (no seams), each on its own grain."""
    a = small_quality_mesh(seed)
    b = small_quality_mesh(seed + 1)
    X = np.vstack([a.X, b.X + np.array([0.12, 0.0])])
    tris = np.vstack([a.tris, b.tris + len(a.X)])
    tri_panel = np.r_[np.zeros(len(a.tris)), np.ones(len(b.tris))].astype(np.int32)
    return GarmentMesh(X=X, tris=tris, tri_panel=tri_panel, panel_names=["a", "b"], panel_grain=np.array(grain))


def iso_as_orthotropic(f: Fabric) -> Fabric:
    E, nu = f.stretch_stiffness, f.poisson_ratio
    return msgspec.structs.replace(
        f,
        warp_stiffness=E,
        weft_stiffness=E,
        shear_stiffness=E / (2 * (1 + nu)),
        bend_warp=f.bend_stiffness,
        bend_weft=f.bend_stiffness,
        bend_bias=f.bend_stiffness,
    )


# ---------------------------------------------------------------- isotropic limits


def test_an_isotropic_fabric_builds_todays_membrane_and_bending_bit_for_bit():
    """All new fields None: the model holds 'membrane' (no orthotropic arrays),
    one k_b, and its forces, stiffness, mass and dF/dX are exactly today's
    kernels with today's Lamé constants (no round-off allowed: same code path)."""
    mesh = two_panels()
    model = ClothModel(mesh, ISO, Scene())
    assert model.terms == ("membrane", "bending", "gravity")
    assert not hasattr(model, "elasticity") and not model.bend_directional
    # a panel given its own fabric equal to the design's changes nothing
    same = ClothModel(mesh, ISO, Scene(panel_fabrics={"b": ISO}))
    assert same.terms == model.terms and not same.bend_directional
    x = random_drape(mesh, seed=3)
    mu, lam = lame_parameters(ISO.stretch_stiffness, ISO.poisson_ratio)
    assert (model.mu, model.lam) == (mu, lam)
    f = np.zeros((model.n, 3))
    K.membrane_forces(x, model.tris, model.Dminv, model.tri_area, mu, lam, f)
    Kw, fac = bending_weights(model.X, model.bend_stencils)
    coef = ISO.bend_stiffness * BEND_CONSTANT * fac
    fb = np.zeros((model.n, 3))
    for e, st in enumerate(model.bend_stencils):
        kx = Kw[e] @ x[st]
        fb[st] -= coef[e] * np.outer(Kw[e], kx)
    assert np.array_equal(model.forces(x, ["membrane"]), f)
    np.testing.assert_allclose(model.forces(x, ["bending"]), fb, rtol=0, atol=1e-13 * np.abs(fb).max())
    mass = np.zeros(model.n)
    np.add.at(mass, model.tris.reshape(-1), np.repeat(model.tri_area * ISO.area_density / 3.0, 3))
    assert np.array_equal(model.mass, mass)
    assert np.array_equal(same.forces(x), model.forces(x))
    assert np.array_equal(same.stiffness(x).data, model.stiffness(x).data)


@pytest.mark.parametrize("grain", [(0.0, 0.0), (0.3, -0.7), (math.pi / 4, math.pi / 2)])
def test_orthotropic_with_isotropic_constants_matches_the_isotropic_kernel(grain):
    """warp = weft = E, shear = E / (2 (1 + nu)), all bendings = k_b: the
    orthotropic membrane and the per-hinge bending give the isotropic model's
    energy, forces, stiffness (projected and exact) and dF/dX to round-off, at any grain."""
    mesh = two_panels(grain)
    iso = ClothModel(mesh, ISO, Scene())
    ort = ClothModel(mesh, iso_as_orthotropic(ISO), Scene())
    assert ort.terms == ("membrane_orthotropic", "bending", "gravity") and ort.bend_directional
    np.testing.assert_allclose(ort.hinge_stiffness(), ISO.bend_stiffness, rtol=1e-14)
    x = random_drape(mesh, seed=5)
    dX = np.random.default_rng(6).normal(size=mesh.X.shape)
    fi, fo = iso.forces(x), ort.forces(x)
    assert np.abs(fi).max() > 0
    np.testing.assert_allclose(fo, fi, rtol=0, atol=1e-12 * np.abs(fi).max())
    assert ort.energy(x) == pytest.approx(iso.energy(x), rel=1e-12)
    for project in (False, True):
        Ki = iso.stiffness(x, project=project).toarray()
        Ko = ort.stiffness(x, project=project).toarray()
        np.testing.assert_allclose(Ko, Ki, rtol=0, atol=1e-12 * np.abs(Ki).max())
    di, do = iso.dforces_dX(x, dX), ort.dforces_dX(x, dX)
    np.testing.assert_allclose(do, di, rtol=0, atol=1e-12 * np.abs(di).max())


# ---------------------------------------------------------------- derivatives


def denim_model(scene=None, grain=(0.3, -0.7)):
    """Panel 'a' in denim (its grain 0.3 rad), panel 'b' isotropic (design fabric)."""
    mesh = two_panels(grain)
    scene = scene or Scene(panel_fabrics={"a": DENIM})
    return mesh, ClothModel(mesh, ISO, scene)


@pytest.mark.parametrize("term", ["membrane_orthotropic", "bending"])
def test_new_terms_gradient_and_hessian_against_central_differences(term):
    mesh, model = denim_model()
    assert term in model.terms and model.bend_directional
    x = random_drape(mesh, seed=7)
    f = model.forces(x, [term])
    check_gradient(
        lambda y: model.energy(y, [term]), -f, x, h=1e-6, rtol=1e-6, floor=np.abs(f).max(), what=f"{term} gradient"
    )
    H = model.stiffness(x, [term], project=False)
    assert abs(H).max() > 0
    check_hessian(lambda y: -model.forces(y, [term]), H, x, h=1e-6, rtol=1e-6, what=f"{term} Hessian")


def test_orthotropic_element_hessians_assemble_and_projection_is_psd():
    """Per-element and CSR Hessians agree; the projected one is PSD in
    compression (a squeezed drape) and equal to the exact one in tension."""
    mesh, model = denim_model()
    x = random_drape(mesh, seed=8, squeeze=0.6)
    for project in (False, True):
        H = np.zeros((len(model.tris), 9, 9))
        K.membrane_ortho_element_hessians(x, model.tris, model.Dminv, model.tri_area, model.elasticity, project, H)
        dofs = (3 * model.tris[:, :, None] + np.arange(3)).reshape(len(model.tris), 9)
        A = np.zeros((3 * model.n, 3 * model.n))
        np.add.at(A, (np.repeat(dofs[:, :, None], 9, 2), np.repeat(dofs[:, None, :], 9, 1)), H)
        Km = model.stiffness(x, ["membrane_orthotropic"], project=project).toarray()
        np.testing.assert_allclose(A, Km, rtol=0, atol=1e-12 * np.abs(Km).max())
        if project:
            assert np.linalg.eigvalsh(H).min() >= -1e-9 * np.abs(H).max()
    stretched = np.column_stack([model.X * 1.05, np.zeros(model.n)])
    a = model.stiffness(stretched, ["membrane_orthotropic"], project=True).toarray()
    b = model.stiffness(stretched, ["membrane_orthotropic"], project=False).toarray()
    np.testing.assert_array_equal(a, b)


def test_rest_shape_derivative_against_rebuilt_models_and_the_sensitivity_matrix():
    """dF/dX of the orthotropic membrane, per-triangle gravity and the
    directional bending (whose hinge stiffness turns with the hinge) against
    models rebuilt at X ± h dX; the sensitivity's assembled ∂F/∂X matrix
    (couture.sensitivity.dfdx) equals the matrix-free one."""
    mesh, model = denim_model()
    scene = model.scene
    x = random_drape(mesh, seed=9)
    rng = np.random.default_rng(10)
    dirs = [rng.normal(size=mesh.X.shape) for _ in range(2)]

    def forces_at(terms):
        return lambda X: ClothModel(GarmentMesh(**{**mesh.__dict__, "X": X}), ISO, scene).forces(x, terms)

    for terms in (None, ["membrane_orthotropic"], ["bending"], ["gravity"]):
        check_jacobian(
            forces_at(terms),
            lambda d, terms=terms: model.dforces_dX(x, d, terms),
            mesh.X,
            h=1e-6,
            rtol=1e-6,
            dirs=dirs,
            what=f"dforces_dX {terms}",
        )
    # the hinge-direction part alone is not zero: a fixed-k model misses it
    fixed = ClothModel(mesh, ISO, scene)
    fixed.bend_directional = False
    assert np.abs(model.dforces_dX(x, dirs[0], ["bending"]) - fixed.dforces_dX(x, dirs[0], ["bending"])).max() > 0
    dofs = np.arange(3 * model.n)
    J = DForcesDX(model, x, dofs)
    for d in dirs:
        ref = model.dforces_dX(x, d).reshape(-1)
        np.testing.assert_allclose(J.apply(d), ref, rtol=0, atol=1e-10 * np.abs(ref).max())


# ---------------------------------------------------------------- clamps


def held_band(mesh: GarmentMesh, width: float = 0.025) -> np.ndarray:
    """The vertices of panel 'a' within ``width`` [m] of its left edge: a clamp
    holding whole triangles (the bench's cantilever holds its strip so)."""
    a = np.unique(mesh.tris[mesh.tri_panel == 0])
    return a[mesh.X[a, 0] < mesh.X[a, 0].min() + width].astype(np.int32)


@pytest.mark.parametrize("fabric", ["iso", "denim"])
def test_a_clamps_hinges_keep_every_derivative(fabric):
    """Held triangles meeting free ones make clamp hinges (``clamped_hinges``):
    twice the strip rigidity D(θ) of their direction (``strip_law``), for an
    isotropic fabric too (then through the per-hinge path); gradient, Hessian
    and rest-shape derivative (matrix-free and the sensitivity's matrix)
    against central differences."""
    mesh = two_panels()
    mesh.pinned = held_band(mesh)
    scene = Scene(panel_fabrics={"a": DENIM}) if fabric == "denim" else Scene()
    model = ClothModel(mesh, ISO, scene)
    clamp = model.bend_clamped
    assert clamp.sum() >= 5 and model.bend_directional
    np.testing.assert_array_equal(clamp, clamped_hinges(model.bend_stencils, model.free))
    k = model.hinge_stiffness()
    kw, kf, kb = plate_rigidities(3e-5, 1.5e-5, 1e-5) if fabric == "denim" else (1e-4,) * 3
    t = model.X[model.bend_stencils[clamp, 1]] - model.X[model.bend_stencils[clamp, 0]]
    t /= np.linalg.norm(t, axis=1)[:, None]
    theta = np.arcsin(np.clip(np.abs(np.sum(t * model.bend_warp[clamp], axis=1)), 0.0, 1.0))
    np.testing.assert_allclose(k[clamp], CLAMP_HINGE_FACTOR * strip_rigidity(kw, kf, kb, theta), rtol=1e-12)
    unheld = ClothModel(GarmentMesh(**{**mesh.__dict__, "pinned": np.zeros(0, np.int32)}), ISO, scene)
    np.testing.assert_allclose(k[~clamp], unheld.hinge_stiffness()[~clamp], rtol=1e-12)
    if fabric == "iso":
        assert not unheld.bend_directional and np.all(k[~clamp] == ISO.bend_stiffness)
    x = random_drape(mesh, seed=11)
    x[~model.free] = unheld.mesh.x0[~model.free]
    f = model.forces(x, ["bending"])
    assert np.abs(f - unheld.forces(x, ["bending"])).max() > 1e-3 * np.abs(f).max()
    check_gradient(
        lambda y: model.energy(y, ["bending"]), -f, x, h=1e-6, rtol=1e-6, floor=np.abs(f).max(), what="gradient"
    )
    H = model.stiffness(x, ["bending"], project=False)
    check_hessian(lambda y: -model.forces(y, ["bending"]), H, x, h=1e-6, rtol=1e-6, what="Hessian")
    rng = np.random.default_rng(12)
    dirs = [rng.normal(size=mesh.X.shape) for _ in range(2)]
    check_jacobian(
        lambda X: ClothModel(GarmentMesh(**{**mesh.__dict__, "X": X}), ISO, scene).forces(x, ["bending"]),
        lambda d: model.dforces_dX(x, d, ["bending"]),
        mesh.X,
        h=1e-6,
        rtol=1e-6,
        dirs=dirs,
        what="dforces_dX bending",
    )
    J = DForcesDX(model, x, np.arange(3 * model.n))
    for d in dirs:
        ref = model.dforces_dX(x, d).reshape(-1)
        np.testing.assert_allclose(J.apply(d), ref, rtol=0, atol=1e-10 * np.abs(ref).max())
    # one k for every hinge keeps the clamp's factor
    model.set_bend_stiffness(2e-4)
    k = model.hinge_stiffness()
    assert np.all(k[clamp] == 4e-4) and np.all(k[~clamp] == 2e-4)


def test_pins_on_single_vertices_make_no_clamp():
    """A pinned row (an edge held, no whole triangle) is no clamp: the isotropic
    model keeps its one k_b and today's path."""
    mesh = two_panels()
    mesh.pinned = np.nonzero(mesh.X[:, 0] < mesh.X[:, 0].min() + 0.005)[0].astype(np.int32)
    model = ClothModel(mesh, ISO, Scene())
    assert len(mesh.pinned) >= 3 and not model.bend_clamped.any() and not model.bend_directional


# ---------------------------------------------------------------- closed forms


def uniaxial_green_strain(E1, E2, nu12, G, grain, sigma):
    """Green strain (2, 2) on the material axes of a sheet in uniaxial 2nd
    Piola-Kirchhoff stress sigma [N/m] along material +y, the warp at ``grain``
    from +y: the textbook orthotropic compliance in the fabric's axes."""
    a = np.array([-math.sin(grain), math.cos(grain)])  # warp
    b = np.array([math.cos(grain), math.sin(grain)])  # weft
    d = np.array([0.0, 1.0])
    s11, s22, s12 = sigma * (d @ a) ** 2, sigma * (d @ b) ** 2, sigma * (d @ a) * (d @ b)
    e11 = s11 / E1 - nu12 * s22 / E1
    e22 = -nu12 * s11 / E1 + s22 / E2
    e12 = s12 / (2 * G)
    return e11 * np.outer(a, a) + e22 * np.outer(b, b) + e12 * (np.outer(a, b) + np.outer(b, a))


@pytest.mark.parametrize(
    "grain,which", [(0.0, "warp"), (math.pi / 2, "weft"), (math.pi / 4, "bias"), (-math.pi / 4, "bias")]
)
def test_uniaxial_pull_along_warp_weft_and_bias_gives_the_orthotropic_stress(grain, which):
    """A sheet stretched to the strain that uniaxial stress sigma along +y gives
    (compliance above) is in equilibrium with free sides (every vertex but the
    ends' carries no force), its ends are held by F S N per unit width, and its
    energy per area is sigma² / (2 E_eff), E_eff = warp, weft or the bias
    modulus 1/E45 = 1/4 (1/E1 + 1/E2 + 1/G12 - 2 nu12/E1)."""
    E1, E2, G, nu = DENIM.warp_stiffness, DENIM.weft_stiffness, DENIM.shear_stiffness, DENIM.poisson_ratio
    E_eff = {"warp": E1, "weft": E2, "bias": 1 / (0.25 * (1 / E1 + 1 / E2 + 1 / G - 2 * nu / E1))}[which]
    W, L = 0.2, 0.3
    mesh = grid_sheet(W, L, 7, 9)
    mesh.panel_grain = np.array([grain])
    model = ClothModel(mesh, DENIM, Scene(gravity=False))
    sigma = 0.02 * E_eff  # 2 % strain along the pull
    Eg = uniaxial_green_strain(E1, E2, nu, G, grain, sigma)
    w, V = np.linalg.eigh(np.eye(2) + 2 * Eg)
    F = V @ np.diag(np.sqrt(w)) @ V.T
    x = np.column_stack([mesh.X @ F.T, np.zeros(model.n)])
    assert model.energy(x) / (W * L) == pytest.approx(sigma**2 / (2 * E_eff), rel=1e-9)
    f = model.forces(x)
    top = np.isclose(mesh.X[:, 1], L)
    bottom = np.isclose(mesh.X[:, 1], 0.0)
    pull = F @ np.array([0.0, sigma]) * W  # F S N over the end's width, what holds the end
    np.testing.assert_allclose(-f[top, :2].sum(axis=0), pull, rtol=1e-9, atol=1e-9 * sigma * W)
    np.testing.assert_allclose(-f[bottom, :2].sum(axis=0), -pull, rtol=1e-9, atol=1e-9 * sigma * W)
    assert np.abs(f[~top & ~bottom]).max() <= 1e-9 * sigma * W


def _plate_tensor(kw: float, kf: float, kp: float) -> np.ndarray:
    """(2, 2, 2, 2) the orthotropic plate with cylindrical rigidities kw, kf
    along warp (axis 0) and weft (axis 1), kp at 45° to them, and the
    coupling invariant U4 = ν_b U1 (ν_b = -1/3, the hinge energy's)."""
    nu = -1.0 / 3.0
    # D(45°) = (D11 + D22 + 2 D12 + 4 D66) / 4 = kp; 8 U4 = 8 nu U1:
    # (D11 + D22 + 6 D12 - 4 D66) = nu (3 D11 + 3 D22 + 2 D12 + 4 D66)
    A = np.array([[2.0, 4.0], [6.0 - 2.0 * nu, -4.0 - 4.0 * nu]])
    b = np.array([4.0 * kp - kw - kf, (3.0 * nu - 1.0) * (kw + kf)])
    d12, d66 = np.linalg.solve(A, b)
    D = np.zeros((2, 2, 2, 2))
    D[0, 0, 0, 0], D[1, 1, 1, 1] = kw, kf
    D[0, 0, 1, 1] = D[1, 1, 0, 0] = d12
    for i, j in ((0, 1), (1, 0)):
        for k, m in ((0, 1), (1, 0)):
            D[i, j, k, m] = d66
    return D


@pytest.mark.parametrize("rigidities", [(3.92e-7, 2.86e-7, 3.39e-7), (1.06e-4, 6.13e-5, 8.37e-5), (3.0, 1.5, 1.0)])
def test_a_free_bias_strip_of_the_plate_bends_with_the_tables_bias_rigidity(rigidities):
    """The plate the hinge law is built for (``plate_rigidities``), written
    as a 4th-order tensor and rotated 45° (a second route to D11, D16, D66
    than the invariants the module uses): its cylindrical rigidity there is
    D(45°), and a strip free to twist, D11 - D16² / D66, is the table's
    bias rigidity; warp and weft unchanged; an isotropic fabric's k_b is its own."""
    kw, kf, kb = rigidities
    pw, pf, pb = plate_rigidities(kw, kf, kb)
    assert (pw, pf) == (kw, kf) and pb > kb
    D = _plate_tensor(kw, kf, pb)
    c = s = math.sqrt(0.5)
    R = np.array([[c, s], [-s, c]])  # rows: the strip's axis (45° from the warp) and its normal
    Dr = np.einsum("ia,jb,kc,ld,abcd->ijkl", R, R, R, R, D)
    d11, d16, d66 = Dr[0, 0, 0, 0], Dr[0, 0, 0, 1], Dr[0, 1, 0, 1]
    assert d11 == pytest.approx(pb, rel=1e-12)
    assert abs(d16) == pytest.approx(abs(kw - kf) / 4, rel=1e-12)
    assert d11 - d16**2 / d66 == pytest.approx(kb, rel=1e-10)
    assert plate_rigidities(2e-5, 2e-5, 1.5e-5) == (2e-5, 2e-5, 1.5e-5)


def test_the_hinge_law_gives_strips_their_rigidity_where_it_can_and_stays_positive():
    """D(β) passes through warp, weft and bias. A mild anisotropy gets the
    calibrated law (mean b0, cos 2θ part b2 / f2, cos 4θ part b4 / f4 for D's
    harmonics), so strips bend with D; denim (bias below both) keeps every
    hinge above the floor, its strips between D's blend and D; every hinge of
    a model gets k at its own θ (from the warp to the hinge's in-plane normal)."""
    kw, kf, kb = DENIM.bend_warp, DENIM.bend_weft, DENIM.bend_bias
    assert strip_rigidity(kw, kf, kb, 0.0) == pytest.approx(kw)
    assert strip_rigidity(kw, kf, kb, math.pi / 2) == pytest.approx(kf)
    assert strip_rigidity(kw, kf, kb, math.pi / 4) == pytest.approx(kb)
    assert strip_rigidity(kw, kf, kb, -math.pi / 4) == pytest.approx(kb)
    theta = np.linspace(0, np.pi, 4096, endpoint=False)
    f2, f4 = BEND_HARMONIC_RESPONSE
    mild = (3.0, 1.5, 2.25)
    k = hinge_stiffness_at(hinge_law(*mild), theta)
    b0, b2, b4 = (mild[0] + mild[1] + 2 * mild[2]) / 4, (mild[0] - mild[1]) / 2, (mild[0] + mild[1] - 2 * mild[2]) / 4
    assert k.min() > 0 and k.mean() == pytest.approx(b0, rel=1e-9)
    assert 2 * np.mean(k * np.cos(2 * theta)) == pytest.approx(b2 / f2, rel=1e-9)
    assert 2 * np.mean(k * np.cos(4 * theta)) == pytest.approx(b4 / f4, rel=1e-9)
    np.testing.assert_allclose(effective_strip_rigidity(*mild, [0, np.pi / 2, np.pi / 4]), mild, rtol=1e-12)
    k = hinge_stiffness_at(hinge_law(kw, kf, kb), theta)
    assert k.min() >= BEND_HINGE_FLOOR * kb * (1 - 1e-6)
    eff = effective_strip_rigidity(kw, kf, kb, np.array([0, np.pi / 2, np.pi / 4]))
    blend = np.array([2.32, 1.34, 1.42]) * 1e-5  # D on every hinge (module docstring)
    assert blend[0] < eff[0] < kw and blend[1] < eff[1] < kf and kb < eff[2] < blend[2]
    # isotropic: one stiffness on every hinge, exactly
    assert np.array_equal(hinge_law(2e-5, 2e-5, 2e-5), [2e-5, 0, 0, 1, 0, 0])
    law = hinge_law(*plate_rigidities(kw, kf, kb))  # a model builds its hinges for the plate
    mesh = grid_sheet(0.2, 0.2, 6, 6)
    for grain in (0.0, 0.4):
        mesh.panel_grain = np.array([grain])
        model = ClothModel(mesh, DENIM, Scene(gravity=False))
        st = model.bend_stencils
        t = model.X[st[:, 1]] - model.X[st[:, 0]]
        # the normal is t turned +90°, the warp is +y turned by the grain: θ = angle(t) - grain
        theta = np.arctan2(t[:, 1], t[:, 0]) - grain
        np.testing.assert_allclose(model.hinge_stiffness(), hinge_stiffness_at(law, theta), rtol=1e-12)


def _cylinder_bending_energy(model, direction):
    """Bending energy of the flat sheet bent into the cylinder z = κ/2 (X·d)², κ = 1/m."""
    X = model.X - model.X.mean(axis=0)
    s = X @ direction
    x = np.column_stack([X, 0.5 * s * s])
    return model.energy(x, ["bending"])


IMPOSED_RESPONSE = (0.54, 0.27)
"""(f2, f4) of a cylinder imposed on a quality mesh (couture.cloth.material docstring)"""


def imposed_strip_rigidity(kw: float, kf: float, kb: float, beta: float) -> float:
    """[N m] the hinge law's (a0, a2, a4) felt through ``IMPOSED_RESPONSE`` by a bend along β."""
    law = hinge_law(kw, kf, kb)
    a4 = law[2] / 8.0
    a2 = -(law[1] + 8.0 * a4) / 2.0
    a0 = law[0] - a2 - a4
    f2, f4 = IMPOSED_RESPONSE
    return a0 + f2 * a2 * math.cos(2 * beta) + f4 * a4 * math.cos(4 * beta)


@pytest.mark.parametrize("grain", [0.0, 0.5])
@pytest.mark.parametrize("rigidities", [(3.0, 1.5, 2.25), (3.0, 1.5, 1.0)])
def test_a_strip_along_warp_weft_or_bias_bends_with_its_rigidity(grain, rigidities):
    """A cylindrical bend imposed on a quality-meshed sheet along the warp,
    the weft and the bias costs the hinge law's a0 + f2 a2 cos 2β + f4 a4 cos 4β
    with the imposed response (``IMPOSED_RESPONSE``, 1/1.2 of the relaxed one
    the law is calibrated to) times the isotropic model's energy at
    k_b = 1 N m, within 6 % (the mesh's hinge directions are not exactly
    even), at any grain; the relaxed strip is ``effective_strip_rigidity``
    (the cantilever bench, docs/fabrics.md)."""
    mesh = grid_sheet(0.4, 0.4, 21, 21)
    mesh.panel_grain = np.array([grain])
    iso = ClothModel(mesh, Fabric(bend_stiffness=1.0, stretch_stiffness=100.0), Scene(gravity=False))
    kw, kf, kb = rigidities
    fab = Fabric(bend_stiffness=1.0, stretch_stiffness=100.0, bend_warp=kw, bend_weft=kf, bend_bias=kb)
    model = ClothModel(mesh, fab, Scene(gravity=False))
    measured = {}
    for beta, name in ((0.0, "warp"), (math.pi / 2, "weft"), (math.pi / 4, "bias")):
        want = float(imposed_strip_rigidity(*plate_rigidities(kw, kf, kb), beta))
        a = grain + beta  # the bend's direction: beta from the warp, the warp at grain from +y
        d = np.array([-math.sin(a), math.cos(a)])
        measured[name] = _cylinder_bending_energy(model, d) / _cylinder_bending_energy(iso, d)
        assert measured[name] == pytest.approx(want, rel=0.06), (name, measured[name], want)
    print(rigidities, "grain", grain, "strip rigidity / (1 N m):", {k: round(v, 3) for k, v in measured.items()})


# ---------------------------------------------------------------- per panel, refusals


def test_each_panel_gets_its_own_membrane_density_and_bending():
    """Panel 'a' in denim, 'b' in the design's fabric: the energy of each
    panel's triangles is that of a model of the one fabric; the mass is each
    panel's area times its density."""
    mesh, model = denim_model()
    x = random_drape(mesh, seed=11)
    for p, fab in ((0, DENIM), (1, ISO)):
        sel = mesh.tri_panel == p
        part = GarmentMesh(X=mesh.X, tris=mesh.tris[sel], panel_grain=mesh.panel_grain[[p]])
        alone = ClothModel(part, fab, Scene(gravity=False))
        e = K.membrane_ortho_energy(x, model.tris[sel], model.Dminv[sel], model.tri_area[sel], model.elasticity[sel])
        assert e == pytest.approx(alone.energy(x, [alone.membrane_term]), rel=1e-12)
        assert model.mass[np.unique(mesh.tris[sel])].sum() == pytest.approx(
            fab.area_density * model.tri_area[sel].sum(), rel=1e-12
        )
    k = model.hinge_stiffness()
    in_b = np.isin(model.bend_stencils[:, 0], np.unique(mesh.tris[mesh.tri_panel == 1]))
    assert in_b.any() and np.allclose(k[in_b], ISO.bend_stiffness, rtol=1e-14, atol=0)
    law = hinge_law(*plate_rigidities(DENIM.bend_warp, DENIM.bend_weft, DENIM.bend_bias))
    curve = hinge_stiffness_at(law, np.linspace(0, np.pi, 1001))
    assert curve.min() * 0.999 <= k[~in_b].min() and k[~in_b].max() <= curve.max() * 1.001


@pytest.mark.parametrize(
    "fabric,field",
    [
        (msgspec.structs.replace(DENIM, poisson_ratio=1.5), "panel_fabrics.a.poisson_ratio"),
        (msgspec.structs.replace(DENIM, bend_bias=1e-7), "panel_fabrics.a.bend_bias"),
    ],
)
def test_a_fabric_the_model_cannot_build_is_refused_naming_its_field(fabric, field):
    """nu12 nu21 >= 1 (C not positive definite) names poisson_ratio; a bias
    rigidity so far below warp and weft that no positive hinge law gives it
    names bend_bias."""
    with pytest.raises(FabricError, match=field.replace(".", r"\.")) as err:
        ClothModel(two_panels(), ISO, Scene(panel_fabrics={"a": fabric}))
    assert err.value.field == field


def test_a_panel_fabric_for_a_panel_the_mesh_lacks_is_refused():
    with pytest.raises(FabricError, match=r"panel_fabrics\.sleeve.*no panel 'sleeve'"):
        ClothModel(two_panels(), ISO, Scene(panel_fabrics={"sleeve": DENIM}))


# ---------------------------------------------------------------- the grain on the bus


def test_the_grain_crosses_the_mesh_message_and_an_old_message_reads_as_straight_grain():
    mesh = two_panels((0.25, -1.0))
    back = msg_to_mesh(decode(encode(mesh_to_msg(mesh)), MeshMsg))
    np.testing.assert_array_equal(back.panel_grain, [0.25, -1.0])
    raw = msgspec.msgpack.decode(encode(mesh_to_msg(mesh)))
    del raw["panel_grain"]  # a message from before the field
    old = msg_to_mesh(decode(msgspec.msgpack.encode(raw), MeshMsg))
    np.testing.assert_array_equal(old.panel_grain, [0.0, 0.0])
    with pytest.raises(SchemaError, match=r"panel_grain.*3 angles for 2 panels"):
        encode(msgspec.structs.replace(mesh_to_msg(mesh), panel_grain=[0.0, 0.1, 0.2]))
    with pytest.raises(ValueError, match="panel_grain has 1 values for 2 panels"):
        GarmentMesh(X=mesh.X, tris=mesh.tris, tri_panel=mesh.tri_panel, panel_names=["a", "b"], panel_grain=[0.1])


def test_the_remesher_puts_each_panels_grain_on_the_mesh():
    """A free-form piece cut on the bias: its grain reaches the mesh, the
    sloper's panels stay on the straight grain."""
    from couture.pattern.validate import validate
    from couture.remesh.meshing import mesh_pattern
    from schemas.design import Design, Piece, Sloper

    piece = Piece(
        name="patch", outline=[(0.0, 0.0), (0.2, 0.0), (0.2, 0.2), (0.0, 0.2)], corners=[0, 1, 2, 3], grain=math.pi / 4
    )
    drafted = validate(Design(sloper=Sloper(kind="skirt"), pieces=[piece]))
    mesh = mesh_pattern(drafted, 300, level="coarse").mesh
    grains = dict(zip(mesh.panel_names, mesh.panel_grain, strict=True))
    assert grains["patch"] == pytest.approx(math.pi / 4)
    assert all(g == 0.0 for name, g in grains.items() if name != "patch") and len(grains) > 1


def test_a_grain_stroke_cuts_a_sloper_panel_on_the_bias():
    """A designer turns a sloper panel's grain with a 'grain' stroke: the
    drafted panel, its mesh and its cutting layout's grain line follow; a bad
    stroke is refused naming it."""
    from couture.pattern import PatternError
    from couture.pattern.cutting import cut_pieces
    from couture.pattern.validate import validate
    from couture.remesh.meshing import mesh_pattern
    from schemas.design import Design, Sloper, Stroke

    bias = Stroke(id="bias-gore0", kind="grain", panel="gore0", params={"angle": math.pi / 4})
    drafted = validate(Design(sloper=Sloper(kind="skirt"), strokes=[bias]))
    grains = {p.name: p.grain for p in drafted.panels}
    assert grains["gore0"] == pytest.approx(math.pi / 4) and grains["gore1"] == 0.0
    mesh = mesh_pattern(drafted, 300, level="coarse").mesh
    assert dict(zip(mesh.panel_names, mesh.panel_grain, strict=True))["gore0"] == pytest.approx(math.pi / 4)
    front = next(c for c in cut_pieces(drafted) if c.panel.name == "gore0")
    tail, head = front.grain
    d = (head - tail) / np.linalg.norm(head - tail)
    assert abs(abs(d[0]) - abs(d[1])) < 1e-9  # the arrow runs at 45 degrees
    for stroke, why in (
        (msgspec.structs.replace(bias, panel="sleeve"), "no panel"),
        (msgspec.structs.replace(bias, params={"angle": 9.0}), "outside"),
        (msgspec.structs.replace(bias, params={}), "missing"),
    ):
        with pytest.raises(PatternError, match=why):
            validate(Design(sloper=Sloper(kind="skirt"), strokes=[stroke]))
    with pytest.raises(PatternError, match="already has a grain"):
        validate(Design(sloper=Sloper(kind="skirt"), strokes=[bias, msgspec.structs.replace(bias, id="again")]))


# ---------------------------------------------------------------- the running system


def _shear_strain(model, x):
    """mean |G_xy|, the Green shear strain on the material axes (x across, y down the panel)."""
    t = model.tris
    F = np.stack([x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]]], axis=2) @ model.Dminv
    return float(np.abs(np.einsum("ti,ti->t", F[:, :, 0], F[:, :, 1])).mean() / 2)


@pytest.mark.slow
def test_a_denim_skirt_drapes_and_its_bias_cut_hangs_differently():
    """The default skirt (coarse, 400 vertices) in the denim-like fabric,
    draped by the solver service as the solver node does (design fabric,
    mesh grain, mannequin with friction): straight grain and bias (every
    panel's grain pi/4) both converge and differ. Straight, the skirt flares
    by shearing the weave (G12 = 50 N/m) along the panel's axes; on the bias
    those axes are the stiff warp and weft (shear there is E45 ≈ 190 N/m
    away), so the material-axis shear strain drops (measured here: 120 and
    167 Newton iterations, about 2 s each; mean |G_xy| 0.016 against 0.003;
    vertices 49 mm apart on average). The bias is cut as a designer cuts it:
    a 'grain' stroke on every gore."""
    from couture.pattern.validate import validate
    from couture.remesh.meshing import mesh_pattern
    from couture.solvers.service import SolveService
    from schemas.design import Design, Sloper, Stroke

    straight = Design(sloper=Sloper(kind="skirt"), fabric=DENIM)
    gores = [p.name for p in validate(straight).panels]
    cut = [Stroke(id=f"bias-{g}", kind="grain", panel=g, params={"angle": math.pi / 4}) for g in gores]
    drapes, shear = {}, {}
    for name, design in (("straight", straight), ("bias", msgspec.structs.replace(straight, strokes=cut))):
        mesh = mesh_pattern(validate(design), 400, level="coarse").mesh
        service = SolveService(method="newton", max_seconds={"coarse": 40.0, "fine": 40.0})
        service.set_design(design)
        service.set_mesh("coarse", mesh, 1)
        result = service.run(levels=("coarse",))[0].result
        model = service.levels["coarse"].model
        assert model.terms[0] == "membrane_orthotropic"
        shear[name] = _shear_strain(model, result.x)
        print(
            f"{name}: {result.iterations} iterations, residual {result.residual:.2e}, "
            f"{result.wall_time:.1f} s, mean |G_xy| {shear[name]:.4f}"
        )
        assert result.converged and result.residual <= service.tol["coarse"], (name, result.diagnosis)
        drapes[name] = result.x
    apart = np.linalg.norm(drapes["straight"] - drapes["bias"], axis=1)
    assert apart.mean() > 0.01, apart.mean()
    assert shear["straight"] > 2.5 * shear["bias"], shear


def test_an_old_design_file_loads_isotropic_and_a_panel_fabric_reaches_the_solver_model():
    """A couture/design/v1 file from before the woven fields decodes with them
    None (no panel fabrics) and drapes on today's isotropic membrane; the
    solver service builds its models with the design's panel fabrics and
    rebuilds them when those change or a mesh turns a panel's grain."""
    from couture.pattern.io import design_from_json
    from couture.solvers.service import SolveService, scene_from_design
    from schemas.design import Design, SceneFlags

    old = (
        b'{"schema": "couture/design/v1", "design": {"sloper": {"kind": "skirt"}, "fabric": {"name": "cotton", '
        b'"stretch_stiffness": 200.0, "poisson_ratio": 0.3, "bend_stiffness": 5e-6, "area_density": 0.15}}}'
    )
    design = design_from_json(old)
    assert design.panel_fabrics == {} and design.fabric.warp_stiffness is None and design.fabric.bend_bias is None
    mesh = two_panels()
    assert ClothModel(mesh, design.fabric, scene_from_design(design)).terms[0] == "membrane"

    flat = SceneFlags(body=False, friction=False)
    service = SolveService(method="newton")
    service.set_design(Design(fabric=ISO, scene=flat))
    service.set_mesh("coarse", mesh, 1)
    assert service.levels["coarse"].model.terms[0] == "membrane"
    assert service.set_design(Design(fabric=ISO, scene=flat, panel_fabrics={"a": DENIM}))
    model = service.levels["coarse"].model
    assert model.terms[0] == "membrane_orthotropic" and model.material.fabrics[1] is DENIM
    turned = GarmentMesh(**{**mesh.__dict__, "panel_grain": np.array([1.0, -0.7])})
    service.set_mesh("coarse", turned, 2)
    assert service.levels["coarse"].model is not model
    assert service.levels["coarse"].model.mesh.panel_grain[0] == 1.0


def test_the_solver_service_refuses_a_fabric_it_cannot_build_keeping_its_design():
    """A panel fabric whose membrane is not positive definite, or one for a
    panel the mesh lacks, is a PatternError naming the field; the service
    keeps the design and models it had."""
    from couture.pattern.errors import PatternError
    from couture.solvers.service import SolveService, check_materials
    from schemas.design import Design, SceneFlags

    flat = SceneFlags(body=False, friction=False)
    service = SolveService(method="newton")
    good = Design(fabric=ISO, scene=flat)
    service.set_design(good)
    service.set_mesh("coarse", two_panels(), 1)
    model = service.levels["coarse"].model
    bad = Design(fabric=ISO, scene=flat, panel_fabrics={"a": msgspec.structs.replace(DENIM, poisson_ratio=1.5)})
    with pytest.raises(PatternError, match=r"panel_fabrics\.a\.poisson_ratio") as err:
        service.set_design(bad)
    assert err.value.element == "panel_fabrics.a.poisson_ratio" and str(err.value).count("poisson_ratio") == 1
    assert service.design is good and service.levels["coarse"].model is model
    with pytest.raises(PatternError, match=r"panel_fabrics\.sleeve.*no panel 'sleeve'"):
        check_materials(Design(panel_fabrics={"sleeve": DENIM}), two_panels())


def test_each_panel_holds_the_body_with_its_own_friction():
    """Friction on: a panel whose own fabric grips harder gets its Coulomb
    coefficients on its vertices (the lagged limit mu_s f_n, the static
    check), the other panel the design fabric's; with one friction for all,
    the model keeps plain numbers."""
    from couture.cloth.body import PlaneBody

    mesh = two_panels()
    grippy = msgspec.structs.replace(DENIM, friction_static=0.9, friction_kinetic=0.8)
    scene = Scene(body=PlaneBody(np.zeros(3), np.array([0, 0, 1.0])), friction=True, friction_model="huber")
    model = ClothModel(mesh, ISO, dataclasses.replace(scene, panel_fabrics={"a": grippy}))
    x = np.column_stack([mesh.X, np.full(mesh.n_vertices, 0.5 * model.contact_offset)])  # inside the layer
    model.lag_friction(x)
    fn = model.contact_normal_force(np.full(mesh.n_vertices, 0.5 * model.contact_offset))
    in_a = np.zeros(mesh.n_vertices, bool)
    in_a[mesh.tris[mesh.tri_panel == 0].reshape(-1)] = True
    np.testing.assert_allclose(model.friction_limit[in_a], 0.9 * fn[in_a], rtol=1e-12)
    np.testing.assert_allclose(model.friction_limit[~in_a], ISO.friction_static * fn[~in_a], rtol=1e-12)
    mu_s, mu_k = model.friction_coefficients(np.array([0]))
    assert (mu_s[0], mu_k[0]) == ((0.9, 0.8) if in_a[0] else (ISO.friction_static, ISO.friction_kinetic))
    same = ClothModel(mesh, ISO, dataclasses.replace(scene, panel_fabrics={"a": DENIM}))
    assert same.vertex_friction is None and same.friction_coefficients() == (0.5, 0.3)

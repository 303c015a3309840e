"""Colour-map fields and picking geometry of the UI (pure numpy)."""

from __future__ import annotations

import numpy as np
import pytest

from couture.mesh import grid_sheet
from couture.ui import colormaps as cm
from couture.ui.geometry import CameraState, MaterialPoint, locate_in_pattern, ray_hit


@pytest.fixture(scope="module")
def sheet():
    return grid_sheet(0.4, 0.3, 12, 9)


def flat(X, sx=1.0, sy=1.0):
    return np.column_stack([sx * X[:, 0], sy * X[:, 1], np.zeros(len(X))])


def test_uniform_stretch_green_strain(sheet):
    # stretch 1.1 in x, 1 in y: E = diag((1.1² - 1) / 2, 0) = diag(0.105, 0)
    ps = cm.principal_strain(sheet.X, flat(sheet.X, 1.1), sheet.tris)
    np.testing.assert_allclose(ps[:, 1], 0.105, atol=1e-12)
    np.testing.assert_allclose(ps[:, 0], 0.0, atol=1e-12)


def test_strain_is_rotation_invariant(sheet):
    x = flat(sheet.X, 1.2, 0.9)
    th = 0.7
    R = np.array([[np.cos(th), 0, np.sin(th)], [0, 1, 0], [-np.sin(th), 0, np.cos(th)]])
    a = cm.principal_strain(sheet.X, x, sheet.tris)
    b = cm.principal_strain(sheet.X, x @ R.T + [0.3, -1.0, 2.0], sheet.tris)
    np.testing.assert_allclose(a, b, atol=1e-12)
    np.testing.assert_allclose(a[:, 0], 0.5 * (0.81 - 1), atol=1e-12)
    np.testing.assert_allclose(a[:, 1], 0.5 * (1.44 - 1), atol=1e-12)


def test_rest_state_has_zero_strain_and_stress(sheet):
    assert np.abs(cm.principal_strain(sheet.X, flat(sheet.X), sheet.tris)).max() < 1e-12
    assert np.abs(cm.principal_stress(sheet.X, flat(sheet.X), sheet.tris, 200.0)).max() < 1e-9


def test_uniaxial_stress_matches_stvk(sheet):
    # small stretch s in x with y held: S = (λ + 2μ) E_xx along x, λ E_xx along y;
    # Cauchy σ = F S F^T / J: σ_xx = s² S_xx / s = s S_xx, σ_yy = S_yy / s
    E, nu, s = 200.0, 0.3, 1.01
    lam, mu = cm.lame_membrane(E, nu)
    exx = 0.5 * (s * s - 1)
    ps = cm.principal_stress(sheet.X, flat(sheet.X, s), sheet.tris, E, nu)
    np.testing.assert_allclose(ps[:, 1], s * (lam + 2 * mu) * exx, rtol=1e-10)
    np.testing.assert_allclose(ps[:, 0], lam * exx / s, rtol=1e-10)


def test_contact_pressure_is_force_over_area(sheet):
    n = len(sheet.X)
    d = np.full(n, 0.02)
    d[0] = 0.004  # 6 mm inside the 1 cm offset
    p = cm.contact_pressure(sheet.X, sheet.tris, d, offset=0.01, contact_stiffness=50.0)
    A = cm.rest_vertex_areas(sheet.X, sheet.tris)
    assert np.isclose(A.sum(), 0.4 * 0.3)
    assert np.isclose(p[0], 50.0 * 0.006 / A[0])
    assert np.count_nonzero(p) == 1


def test_pressure_map_shows_the_solvers_contact():
    """The UI's pressure map uses the solver's contact: its stiffness for the
    fabric (and the design's scale), its C² law and its body SDF, so the map
    equals the contact force a ClothModel computes, over the rest area."""
    from couture.cloth.model import ClothModel, Scene
    from schemas.design import Fabric

    fab = Fabric(stretch_stiffness=35.0, poisson_ratio=0.25)
    model = ClothModel(grid_sheet(0.4, 0.3, 12, 9), fab, Scene(body="mannequin"))
    assert cm.solver_contact_stiffness(35.0, 0.25) == pytest.approx(model.contact_stiffness, rel=1e-12)
    assert cm.solver_contact_stiffness(35.0, 0.25, 2.0) == pytest.approx(2 * model.contact_stiffness, rel=1e-12)
    dist = cm.BodyDistance("default")
    # points around the chest, a few mm either side of the offset layer's edge
    rng = np.random.default_rng(3)
    pts = np.array([0.0, 0.35, 0.16]) + rng.normal(0.0, 0.03, (40, 3))
    phi_model, _ = model.body.phi_grad(pts)
    np.testing.assert_allclose(dist(pts), phi_model, atol=1e-12)
    sheet = grid_sheet(0.4, 0.3, 12, 9)
    d = np.full(len(sheet.X), 0.02)
    d[:5] = [0.0095, 0.009, 0.005, 0.0, -0.002]  # on the ramp, beyond it, at and under the surface
    p = cm.contact_pressure(sheet.X, sheet.tris, d, 0.01, model.contact_stiffness, model.contact_smoothing)
    A = cm.rest_vertex_areas(sheet.X, sheet.tris)
    np.testing.assert_allclose(p[:5] * A[:5], model.contact_normal_force(0.01 - d[:5]), rtol=1e-12)
    k, eps = model.contact_stiffness, model.contact_smoothing
    assert p[0] * A[0] == pytest.approx(0.5 * k * 0.0005**2 / eps)  # the ramp, by hand
    assert p[2] * A[2] == pytest.approx(k * (0.005 - 0.5 * eps))
    assert np.count_nonzero(p) == 5


def test_color_scale_bands_and_legend():
    s = cm.ColorScale(-1.0, 1.0, 4, diverging=True, unit="", label="strain")
    np.testing.assert_array_equal(s.band_of(np.array([-5, -0.9, -0.1, 0.1, 0.9, 5])), [0, 0, 1, 2, 3, 3])
    cols = s.band_colors()
    assert cols.shape == (4, 3) and cols.dtype == np.uint8
    html = s.legend_html()
    assert html.count("background:rgb") == 4 and "-1" in html and "strain" in html
    auto = cm.auto_scale("strain", np.array([0.0, 0.01, -0.02]))
    assert auto.lo == -auto.hi and auto.hi > 0


def test_locate_in_pattern_and_material_point_roundtrip(sheet):
    p = np.array([0.123, 0.211])
    mp = locate_in_pattern(sheet.X, sheet.tris, p)
    np.testing.assert_allclose(mp.on(sheet.X, sheet.tris), p, atol=1e-12)
    # the same material point on a stretched drape
    x = flat(sheet.X, 2.0, 3.0)
    np.testing.assert_allclose(mp.on(x, sheet.tris), [0.246, 0.633, 0.0], atol=1e-12)


def test_ray_hit_finds_the_material_point(sheet):
    x = flat(sheet.X)
    hit = ray_hit(x, sheet.tris, origin=(0.2, 0.1, 1.0), direction=(0.0, 0.0, -1.0))
    assert hit is not None
    mp, t = hit
    assert np.isclose(t, 1.0)
    np.testing.assert_allclose(mp.on(x, sheet.tris), [0.2, 0.1, 0.0], atol=1e-12)
    assert ray_hit(x, sheet.tris, (5.0, 5.0, 1.0), (0.0, 0.0, -1.0)) is None


def test_camera_projection_conventions():
    # camera at +z looking down -z with +y up: OpenCV rotation is diag(1, -1, -1)
    # (a 180° turn about x: wxyz = (0, 1, 0, 0))
    cam = CameraState(np.array([0.0, 0.0, 2.0]), np.array([0.0, 1.0, 0.0, 0.0]), np.deg2rad(60), 1.5, 600, 400)
    np.testing.assert_allclose(cam.project(np.array([[0.0, 0.0, 0.0]]))[0], [0.5, 0.5])
    up = cam.project(np.array([[0.0, 0.5, 0.0]]))[0]
    right = cam.project(np.array([[0.5, 0.0, 0.0]]))[0]
    assert up[1] < 0.5 and right[0] > 0.5  # +y is up on screen, +x right
    # the GL matrix agrees with the OpenCV projection
    p = np.array([0.3, -0.2, 0.1])
    clip = cam.view_proj_gl() @ np.append(p, 1.0)
    ndc = clip[:2] / clip[3]
    uv = cam.project(p[None])[0]
    np.testing.assert_allclose([(ndc[0] + 1) / 2, (1 - ndc[1]) / 2], uv, atol=1e-12)
    assert isinstance(MaterialPoint(0, np.ones(3) / 3), MaterialPoint)


# --- CLO's fabric mode: strain over the fabric's own stretch limit -------------


def _one_triangle_stretched_along(g: float, s: float):
    """A right triangle whose material is stretched by s along the warp of a
    panel cut at grain g (warp (-sin g, cos g)): x = (I + s a aᵀ) X."""
    X = np.array([[0.0, 0.0], [0.1, 0.0], [0.0, 0.1]])
    a = np.array([-np.sin(g), np.cos(g)])
    F = np.eye(2) + s * np.outer(a, a)
    x = np.column_stack([X @ F.T, np.zeros(3)])
    return X, x, np.array([[0, 1, 2]]), a[None, :]


def test_fiber_strains_follow_the_panels_grain_by_hand():
    # 2 % along a warp turned by 30°: warp 0.02, weft 0 (perpendicular, untouched),
    # either bias |(1.02 a ± b) / √2| - 1 = sqrt((1.02² + 1) / 2) - 1 = 0.010050
    X, x, tris, warp = _one_triangle_stretched_along(np.deg2rad(30.0), 0.02)
    e = cm.fiber_strains(X, x, tris, warp)
    np.testing.assert_allclose(e[0], [0.02, 0.0, np.sqrt((1.02**2 + 1) / 2) - 1], atol=1e-12)
    # read on the straight grain instead, the same stretch splits between the axes:
    # |F (0, 1)| = |(0, 1) + 0.02 cos30 a| -> 0.02 cos²30 to first order
    e0 = cm.fiber_strains(X, x, tris, np.array([[0.0, 1.0]]))
    assert abs(e0[0, 0] - 0.02 * np.cos(np.deg2rad(30.0)) ** 2) < 2e-4 and e0[0, 1] > 0.004
    # rigid motion changes nothing
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(cm.fiber_strains(X, x @ R.T + 5.0, tris, warp), e, atol=1e-12)
    with pytest.raises(ValueError, match="2 warp directions for 1 triangles"):
        cm.fiber_strains(X, x, tris, np.zeros((2, 2)))


def test_stretch_limits_by_hand():
    from couture.cloth.material import FabricError
    from schemas.design import Fabric

    T = cm.WEARABLE_TENSION
    iso = Fabric(stretch_stiffness=1000.0, poisson_ratio=0.3)
    # isotropic: T / E in every direction (the bias compliance (2 - 2ν + 2 (1 + ν)) / 4E = 1/E)
    np.testing.assert_allclose(cm.stretch_limits(iso), [T / 1000.0] * 3, rtol=1e-12)
    denim = Fabric(
        stretch_stiffness=3000.0, poisson_ratio=0.3, warp_stiffness=4000.0, weft_stiffness=2500.0, shear_stiffness=122.5
    )
    bias = T * (1 / 4000 + 1 / 2500 + 1 / 122.5 - 2 * 0.3 / 4000) / 4
    np.testing.assert_allclose(cm.stretch_limits(denim), [T / 4000, T / 2500, bias], rtol=1e-12)
    assert bias > 8 * T / 4000  # a woven gives on the bias
    np.testing.assert_allclose(cm.stretch_limits(denim, 2 * T), 2 * cm.stretch_limits(denim), rtol=1e-12)
    with pytest.raises(ValueError, match="tension 0.0 N/m"):
        cm.stretch_limits(denim, 0.0)
    with pytest.raises(FabricError, match="fabric.shear_stiffness"):
        cm.stretch_limits(Fabric(shear_stiffness=-1.0))


def test_fabric_strain_field_by_hand():
    from schemas.design import Fabric

    # 2 % along the warp of a 30° panel in a fabric of warp 1000, weft 500, shear 50 N/m
    X, x, tris, warp = _one_triangle_stretched_along(np.deg2rad(30.0), 0.02)
    fab = Fabric(
        stretch_stiffness=700.0, poisson_ratio=0.3, warp_stiffness=1000.0, weft_stiffness=500.0, shear_stiffness=50.0
    )
    lim = cm.stretch_limits(fab)
    axes = cm.FabricAxes(warp, lim[None, :])
    bias = np.sqrt((1.02**2 + 1) / 2) - 1
    want = 100 * np.array([0.02 / lim[0], 0.0, bias / lim[2]])
    assert want[0] > want[2] > 0  # the warp is nearest its limit: 0.02 / 0.098 = 20 %
    np.testing.assert_allclose(cm.fabric_strain_shares(cm.fiber_strains(X, x, tris, warp), lim)[0], want, atol=1e-9)
    for field, v in zip(cm.FABRIC_FIELDS, [want[0], *want], strict=True):
        np.testing.assert_allclose(cm.field_values(field, X, x, tris, axes=axes), [v], atol=1e-9)
    share, dominant = cm.fabric_strain(np.array([[-30.0, -5.0, -1.0], [10.0, 40.0, 20.0]]))
    np.testing.assert_array_equal(share, [0.0, 40.0])  # compression is not a share of a stretch limit
    np.testing.assert_array_equal(dominant[1:], [1])
    # without axes: an isotropic fabric of the given stiffness on the straight grain
    iso = cm.field_values("warp_strain", X, x, tris, stretch_stiffness=1000.0)
    e0 = cm.fiber_strains(X, x, tris, np.array([[0.0, 1.0]]))[0, 0]
    np.testing.assert_allclose(iso, [100 * e0 / (cm.WEARABLE_TENSION / 1000.0)], rtol=1e-12)
    sc = cm.auto_scale("fabric_strain", np.array([5.0]))
    assert (sc.lo, sc.hi, sc.diverging) == (0.0, 100.0, False) and "limit" in sc.legend_html()
    assert cm.auto_scale("bias_strain", np.array([5.0])).lo == -100.0
    assert set(cm.FABRIC_FIELDS) <= set(cm.FIELDS)


def test_fabric_axes_per_panel_fabric_and_grain(sheet):
    from couture.mesh import GarmentMesh
    from schemas.design import Fabric

    # left half panel 'a' on the straight grain in the design fabric, right half
    # panel 'b' on the bias in its own (softer) fabric
    c = sheet.X[sheet.tris].mean(axis=1)
    tri_panel = (c[:, 0] > 0.2).astype(np.int32)
    mesh = GarmentMesh(
        sheet.X, sheet.tris, tri_panel=tri_panel, panel_names=["a", "b"], panel_grain=np.array([0.0, np.pi / 4])
    )
    stiff, soft = Fabric(stretch_stiffness=2000.0), Fabric(stretch_stiffness=200.0)
    axes = cm.fabric_axes(mesh, stiff, {"b": soft})
    np.testing.assert_allclose(axes.warp[tri_panel == 0], [[0.0, 1.0]] * int((tri_panel == 0).sum()), atol=1e-15)
    np.testing.assert_allclose(axes.warp[tri_panel == 1], [[-np.sqrt(0.5), np.sqrt(0.5)]] * int(tri_panel.sum()))
    np.testing.assert_allclose(axes.limit[tri_panel == 0], cm.WEARABLE_TENSION / 2000.0, rtol=1e-12)
    np.testing.assert_allclose(axes.limit[tri_panel == 1], cm.WEARABLE_TENSION / 200.0, rtol=1e-12)
    # a 1 % stretch along x: the straight-grain panel feels it in its weft, the bias panel in a bias
    x = flat(sheet.X, 1.01)
    warp = cm.field_values("warp_strain", sheet.X, x, sheet.tris, axes=axes)
    weft = cm.field_values("weft_strain", sheet.X, x, sheet.tris, axes=axes)
    bias = cm.field_values("bias_strain", sheet.X, x, sheet.tris, axes=axes)
    lim_a, lim_b = cm.WEARABLE_TENSION / 2000.0, cm.WEARABLE_TENSION / 200.0
    np.testing.assert_allclose(warp[tri_panel == 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(weft[tri_panel == 0], 100 * 0.01 / lim_a, rtol=1e-9)
    np.testing.assert_allclose(bias[tri_panel == 1], 100 * 0.01 / lim_b, rtol=1e-9)
    with pytest.raises(ValueError, match="panel_fabrics.c"):
        cm.fabric_axes(mesh, stiff, {"c": soft})

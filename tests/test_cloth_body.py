"""Body contact, friction anchors, the mannequin SDF, and 'model only what
the scene needs'."""

import numpy as np
import pytest
from fdcheck import along_axes, assert_close

from couture.cloth import ClothModel, Scene
from couture.cloth import body as body_mod
from couture.cloth.body import GridSDFBody, PlaneBody, SphereBody, TriangleMeshDistance, build_grid_sdf
from couture.cloth.testing import newton
from couture.mesh import grid_sheet
from schemas.design import Fabric

FABRIC = Fabric(stretch_stiffness=50.0, bend_stiffness=1e-5)


# ---------------------------------------------------------------- scene terms


def test_model_only_what_the_scene_needs(monkeypatch):
    calls = []

    def loader(*a, **k):
        calls.append(1)
        raise AssertionError("the mannequin SDF must not be loaded for this scene")

    monkeypatch.setattr(body_mod, "load_mannequin_sdf", loader)
    sheet = grid_sheet(0.2, 0.2, 6, 6)
    model = ClothModel(sheet, FABRIC, Scene(body=None, gravity=True, seams=True))
    assert model.terms == ("membrane", "bending", "gravity")  # no seams in a plain sheet
    assert model.body is None and not hasattr(model, "anchored")
    assert calls == []
    assert ClothModel(sheet, FABRIC, Scene(gravity=False)).terms == ("membrane", "bending")
    with pytest.raises(ValueError):
        ClothModel(sheet, FABRIC, Scene(friction=True))  # friction needs a body
    with pytest.raises(AssertionError):
        ClothModel(sheet, FABRIC, Scene(body="mannequin"))  # only now is the loader called
    assert calls == [1]
    with pytest.raises(ValueError):
        model.forces(sheet.x0, ["contact"])

    # a body far away: contact and friction terms exist, but nothing touches
    far = SphereBody(center=np.array([0.0, 10.0, 0.0]), radius=0.1)
    model = ClothModel(sheet, FABRIC, Scene(body=far, friction=True))
    assert model.terms == ("membrane", "bending", "gravity", "contact", "friction")
    stats = model.update_friction(sheet.x0)
    assert stats["anchored"] == 0 and not model.anchored.any()
    assert np.all(model.forces(sheet.x0, ["contact"]) == 0)
    assert np.all(model.forces(sheet.x0, ["friction"]) == 0)


def test_pinned_vertices_free_mask():
    sheet = grid_sheet(0.2, 0.2, 6, 6)
    sheet.pinned = np.array([0, 3], np.int32)
    model = ClothModel(sheet, FABRIC, Scene())
    assert model.free.sum() == model.n - 2 and not model.free[[0, 3]].any()
    assert model.free_dofs.sum() == 3 * (model.n - 2)


# ---------------------------------------------------------------- contact


def test_sphere_sdf_closed_form():
    s = SphereBody(center=np.array([1.0, 2.0, 3.0]), radius=0.5)
    p = np.array([[1.0, 2.0, 4.0], [1.0, 2.3, 3.0], [1.0, 2.0, 3.0]])
    phi, g = s.phi_grad(p)
    np.testing.assert_allclose(phi, [0.5, -0.2, -0.5])
    np.testing.assert_allclose(g[:2], [[0, 0, 1], [0, 1, 0]])


def test_point_inside_offset_is_pushed_out():
    sphere = SphereBody(center=np.array([0.1, 0.1, -0.3]), radius=0.3)
    sheet = grid_sheet(0.2, 0.2, 9, 9)
    # the flat sheet at z = 0 cuts 5 mm into the 1 cm offset layer around the sphere top
    x0 = sheet.x0 + np.array([0.0, 0.0, -0.005])
    model = ClothModel(sheet, FABRIC, Scene(body=sphere, gravity=False, contact_offset=0.01))
    phi, grad = sphere.phi_grad(x0)
    inside = phi < 0.01
    assert inside.any() and (~inside).any()
    f = model.forces(x0, ["contact"])
    assert np.all(np.einsum("ij,ij->i", f[inside], grad[inside]) > 0)  # outward
    assert np.all(f[~inside] == 0)
    x, hist = newton(model, x0, tol=1e-12, max_iters=200, use_exact=False)
    assert hist[-1] < 1e-12
    # the sheet is free (no gravity, no pins): any placement whose contact forces
    # vanish is an equilibrium, just outside the layer or grazing it, where the C²
    # law's force k pen²/(2 eps) is below the residual (pen < 0.1 mm: ~1e-5 N).
    # The PSD stiffness: the exact one is indefinite here (the sphere's curvature
    # term), and this plain Newton has no shift to make it definite
    assert sphere.phi_grad(x)[0].min() > 0.01 - 1e-4


def test_sheet_sags_onto_sphere_with_small_penetration():
    """SC Fig. 5 style: a sheet held at its corners just above a sphere sags
    onto it; the contact springs carry the load with penetration of the
    offset layer bounded by weight / k_c + eps / 2 (eps: contact smoothing)."""
    sphere = SphereBody(center=np.array([0.0, 0.0, 0.0]), radius=0.1)
    sheet = grid_sheet(0.16, 0.16, 11, 11)
    X = sheet.X - 0.08
    sheet.x0 = np.column_stack([X[:, 0], np.full(len(X), 0.112), X[:, 1]])
    corners = np.nonzero((np.abs(X[:, 0]) > 0.079) & (np.abs(X[:, 1]) > 0.079))[0]
    assert len(corners) == 4
    sheet.pinned = corners.astype(np.int32)
    fab = Fabric(stretch_stiffness=20.0, bend_stiffness=1e-6, area_density=0.15)
    k_c = 500.0
    model = ClothModel(sheet, fab, Scene(body=sphere, contact_stiffness=k_c))
    x, hist = newton(model, sheet.x0, tol=1e-9, max_iters=200)
    assert hist[-1] < 1e-9
    phi = sphere.phi_grad(x)[0]
    weight = model.mass.sum() * 9.81
    assert (phi < 0.01).sum() >= 3  # a contact patch carries the sheet
    # contact_law: a vertex carrying the whole weight W sits at pen = sqrt(2 eps W / k_c) (ramp)
    # or W / k_c + eps / 2 (beyond it); both are <= W / k_c + eps / 2 (AM-GM)
    assert phi.min() > 0.01 - (weight / k_c + 0.5 * model.contact_smoothing)
    f_contact = model.forces(x, ["contact"])
    assert 0.2 * weight < f_contact[:, 1].sum() < weight


# ---------------------------------------------------------------- friction


def incline_scene(angle_deg):
    a = np.deg2rad(angle_deg)
    n = np.array([-np.sin(a), np.cos(a), 0.0])
    t = np.array([np.cos(a), np.sin(a), 0.0])  # up the slope
    plane = PlaneBody(point=np.zeros(3), normal=n)
    sheet = grid_sheet(0.1, 0.1, 6, 6)
    offset = 0.01
    x0 = np.outer(sheet.X[:, 0], t) + np.outer(sheet.X[:, 1], [0, 0, 1.0]) + 0.9 * offset * n
    sheet.x0 = x0
    model = ClothModel(
        sheet,
        Fabric(stretch_stiffness=50.0, bend_stiffness=1e-5, friction_static=0.5, friction_kinetic=0.3),
        Scene(body=plane, friction=True, contact_stiffness=200.0, contact_offset=offset),
    )
    return model, x0, t


def friction_cycles(model, x, cycles):
    pos = []
    for _ in range(cycles):
        model.update_friction(x)
        x, hist = newton(model, x, tol=1e-10, max_iters=50)
        assert hist[-1] < 1e-10
        pos.append(x.copy())
    return pos


def test_friction_sticks_below_static_angle():
    # tan 20° = 0.36 < mu_s = 0.5: the sheet stays (up to the spring's elastic give)
    model, x0, t = incline_scene(20.0)
    model.update_friction(x0)  # everything touches: anchors everywhere
    assert model.anchored.all()
    pos = friction_cycles(model, x0, 4)
    assert not model.sliding.any()
    slide = [(p - x0) @ t for p in pos]
    assert np.allclose(slide[-1], slide[0], atol=1e-12)  # no progressive sliding
    give = model.mass.max() * 9.81 * np.sin(np.deg2rad(20)) / model.friction_stiffness
    assert np.abs(slide[-1]).max() < 2 * give


def test_friction_slides_above_static_angle():
    # tan 35° = 0.70 > mu_s = 0.5: the anchors slide (kinetic mode) and the sheet keeps going down
    model, x0, t = incline_scene(35.0)
    pos = friction_cycles(model, x0, 4)
    assert model.sliding.all()
    down = [-float(np.mean((p - x0) @ t)) for p in pos]
    # each cycle the sheet slides by the unbalanced force over the anchor stiffness:
    # M g (sin a - mu_k cos a) / (n k_t)
    a = np.deg2rad(35.0)
    step = model.mass.sum() * 9.81 * (np.sin(a) - 0.3 * np.cos(a)) / (model.n * model.friction_stiffness)
    np.testing.assert_allclose(np.diff(down), step, rtol=0.02)
    # kinetic mode: the tangential anchor force equals mu_k times the normal force
    x = pos[-1]
    model.update_friction(x)
    phi, _ = model.body.phi_grad(x)
    fn = model.contact_normal_force(model.contact_offset - phi)
    ft = np.linalg.norm(model.forces(x, ["friction"]), axis=1)
    np.testing.assert_allclose(ft, 0.3 * fn, rtol=1e-9)


def test_kinetic_friction_follows_the_normal_force():
    """A slipping vertex's kinetic friction is mu_k times the normal force where the
    vertex is now, along the direction it slipped in; off the body it is zero."""
    model, x0, t = incline_scene(35.0)
    model.update_friction(x0)
    x1 = x0 - 0.01 * t  # 1 cm down the slope: every anchor pulls far beyond mu_s f_n
    assert model.slip_friction(x1) == model.n and model.slipping.all()
    before = model.slip_force.copy()
    n = model.body.normal
    x2 = x1.copy()
    x2[::2] -= 0.002 * n  # deeper: pushed harder
    x2[1::7] += 0.05 * n  # lifted off the body
    assert model.rescale_slipping(x2) > 0
    phi = (x2 - model.body.point) @ n  # the plane's signed distance, independently of the model
    pen = model.contact_offset - phi
    k, eps = model.contact_stiffness, model.contact_smoothing
    fn = np.where(pen <= 0, 0.0, np.where(pen < eps, 0.5 * k * pen**2 / eps, k * (pen - 0.5 * eps)))
    np.testing.assert_allclose(np.linalg.norm(model.slip_force, axis=1), 0.3 * fn, rtol=1e-12, atol=1e-15)
    touching = fn > 0
    unit = before[touching] / np.linalg.norm(before[touching], axis=1)[:, None]
    np.testing.assert_allclose(model.slip_force[touching], unit * 0.3 * fn[touching][:, None], rtol=1e-12)
    assert not model.slip_force[~touching].any()


def test_friction_anchor_released_when_contact_ends():
    model, x0, t = incline_scene(20.0)
    model.update_friction(x0)
    assert model.anchored.all()
    lifted = x0 + 0.05 * model.body.normal
    stats = model.update_friction(lifted)
    assert stats["released"] == model.n and not model.anchored.any()


# ---------------------------------------------------------------- mesh SDF


def winding_number(V, F, points):
    """Generalized winding number (Van Oosterom-Strackee solid angles)."""
    out = np.zeros(len(points))
    for i, p in enumerate(points):
        a, b, c = (V[F[:, k]] - p for k in range(3))
        la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
        num = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = (
            la * lb * lc
            + np.einsum("ij,ij->i", a, b) * lc
            + np.einsum("ij,ij->i", b, c) * la
            + np.einsum("ij,ij->i", c, a) * lb
        )
        out[i] = np.sum(2 * np.arctan2(num, den)) / (4 * np.pi)
    return out


def test_triangle_mesh_distance_on_a_cube():
    import trimesh

    cube = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    dist = TriangleMeshDistance(cube.vertices, cube.faces)
    p = np.array([[0, 0, 0], [0.2, 0.1, 0.0], [1.0, 0, 0], [1.0, 1.0, 0.0], [1.0, 1.0, 1.0], [0.5, 0.5, 0.6]])
    ref = [-0.5, -0.3, 0.5, np.sqrt(0.5), np.sqrt(0.75), np.sqrt(0.1**2)]
    np.testing.assert_allclose(dist(p), ref, atol=1e-12)
    grid = build_grid_sdf(cube.vertices, cube.faces, spacing=0.05, margin=0.1)
    # node values: the trilinear interpolant reproduces them; the cubic B-spline
    # (the default) approximates: it smooths the medial-axis kink at the centre
    # and uses repeated end nodes at the grid's border
    grid.interpolation = "trilinear"
    phi, grad = grid.phi_grad(np.array([[0.0, 0.0, 0.6], [0.0, 0.0, 0.0]]))
    np.testing.assert_allclose(phi, [0.1, -0.5], atol=1e-9)
    np.testing.assert_allclose(grad[0], [0, 0, 1], atol=1e-9)
    # the B-spline reproduces the SDF exactly where it is linear over the 4-node support
    grid.interpolation = "bspline"
    phi, grad = grid.phi_grad(np.array([[0.0, 0.0, 0.55], [0.02, -0.01, 0.53]]))
    np.testing.assert_allclose(phi, [0.05, 0.03], atol=1e-9)
    np.testing.assert_allclose(grad, [[0, 0, 1], [0, 0, 1]], atol=1e-9)


def test_grid_sdf_gradient_is_the_interpolant_derivative():
    rng = np.random.default_rng(0)
    g = GridSDFBody(origin=np.zeros(3), spacing=0.1, values=rng.normal(size=(5, 6, 7)))
    p = rng.uniform(0.01, 0.39, size=(50, 3))
    phi, grad = g.phi_grad(p)
    assert_close(grad, along_axes(lambda q: g.phi_grad(q)[0], p, 1e-7), 1e-7, floor=10.0, what="grid SDF gradient")
    # outside the grid: distance to the box added, pointing away
    phi_out, grad_out = g.phi_grad(np.array([[0.2, 0.2, 1.6]]))
    assert phi_out[0] == pytest.approx(g.phi_grad(np.array([[0.2, 0.2, 0.6]]))[0][0] + 1.0)
    np.testing.assert_allclose(grad_out[0], [0, 0, 1])


@pytest.mark.slow
def test_mannequin_sdf_sign_gradient_and_accuracy():
    """Builds the 1 cm grid once (about 20 s, then cached)."""
    import trimesh

    sdf = body_mod.load_mannequin_sdf()
    V, F = body_mod.load_mannequin_mesh()
    mesh = trimesh.Trimesh(V, F, process=False)
    assert mesh.is_watertight and mesh.volume > 0
    rng = np.random.default_rng(0)
    pts, fid = trimesh.sample.sample_surface_even(mesh, 3000, seed=0)
    n = mesh.face_normals[fid]
    torso = (np.abs(pts[:, 0]) < 0.12) & (pts[:, 1] > 0.0) & (pts[:, 1] < 0.5)
    assert torso.sum() > 200

    # sign: deep inside the torso, and outside everywhere near the skin
    centre = V[(np.abs(V[:, 0]) < 0.1) & (V[:, 1] > 0.1) & (V[:, 1] < 0.4)].mean(axis=0)
    phi_c, _ = sdf.phi_grad(centre[None])
    assert phi_c[0] < -0.05
    assert winding_number(V, F, centre[None])[0] == pytest.approx(1.0, abs=1e-6)
    out = pts[torso] + 0.02 * n[torso]
    inn = pts[torso] - 0.01 * n[torso]
    assert np.mean(sdf.phi_grad(out)[0] > 0) > 0.99
    assert np.mean(sdf.phi_grad(inn)[0] < 0) > 0.97
    # far points are outside
    assert np.all(sdf.phi_grad(np.array([[0.0, 2.0, 0.0], [1.0, 0.0, 0.0]]))[0] > 0.3)

    # gradient ~ outward normal in the contact layer
    phi, grad = sdf.phi_grad(pts[torso] + 0.012 * n[torso])
    cosang = np.einsum("ij,ij->i", grad, n[torso]) / np.linalg.norm(grad, axis=1)
    assert np.median(cosang) > 0.98 and np.mean(cosang > 0.8) > 0.95
    assert np.median(np.linalg.norm(grad, axis=1)) == pytest.approx(1.0, abs=0.05)

    # trilinear vs exact signed distance in the band where contact happens
    q = pts + rng.uniform(-0.005, 0.03, size=len(pts))[:, None] * n
    exact = TriangleMeshDistance(V, F)(q)
    err = np.abs(sdf.phi_grad(q)[0] - exact)
    assert np.median(err) < 1e-3 and np.quantile(err[torso], 0.95) < 2e-3
    # and the exact distance's sign agrees with the winding number on a sample
    sub = rng.choice(len(q), 60, replace=False)
    inside_w = winding_number(V, F, q[sub]) > 0.5
    assert np.array_equal(inside_w, exact[sub] < 0)


def test_grid_sdf_is_exact_inside_and_near_the_body():
    """The banded build against every node computed exactly: equal inside the
    body and within BAND_NODES spacings outside it; elsewhere at least the band
    (the contact, 1 cm deep, sees the same body). A sphere with a bar through
    it (arms, legs: thin parts far from the rest)."""
    import trimesh

    outer = trimesh.creation.icosphere(subdivisions=3, radius=0.2)
    body_mesh = trimesh.util.concatenate([outer, trimesh.creation.box(extents=(0.05, 0.6, 0.05))])
    V, F = np.asarray(body_mesh.vertices), np.asarray(body_mesh.faces)
    g = body_mod.build_grid_sdf(V, F, spacing=0.01, margin=0.12)
    axes = [g.origin[d] + g.spacing * np.arange(g.values.shape[d]) for d in range(3)]
    P = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    exact = body_mod.TriangleMeshDistance(V, F)(P).reshape(g.values.shape)
    band = body_mod.BAND_NODES * g.spacing
    keep = exact < band
    assert np.array_equal(g.values[keep], exact[keep])
    assert (g.values[~keep] >= band).all() and (~keep).sum() > 0.2 * keep.size

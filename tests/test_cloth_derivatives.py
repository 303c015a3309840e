"""Every term's gradient and Hessian against central finite differences, the
PSD projection, dforces_dX, and the reuse of the sparse pattern."""

import numpy as np
import pytest
from fdcheck import (
    along_axes,
    assert_close,
    check_gradient,
    check_hessian,
    check_jacobian,
    contact_penetrations,
    degenerate_triangles,
)

from couture.cloth import ClothModel, Scene
from couture.cloth import kernels as K
from couture.cloth.body import PlaneBody, SphereBody
from couture.cloth.testing import random_drape, small_quality_mesh
from couture.mesh import GarmentMesh
from schemas.design import Fabric

FABRIC = Fabric(stretch_stiffness=50.0, poisson_ratio=0.3, bend_stiffness=1e-4, area_density=0.15)


def seamed_mesh(seed=0):
    """Two small panels side by side with seam springs from the left panel's
    right edge to the right panel's left edge (unequal vertex counts)."""
    a = small_quality_mesh(seed)
    b = small_quality_mesh(seed + 1)
    Xb = b.X + np.array([0.12, 0.0])
    X = np.vstack([a.X, Xb])
    tris = np.vstack([a.tris, b.tris + len(a.X)])
    em = np.nonzero(np.isclose(a.X[:, 0], a.X[:, 0].max(), atol=2e-3))[0]
    rv = np.nonzero(np.isclose(Xb[:, 0], Xb[:, 0].min(), atol=2e-3))[0] + len(a.X)
    rv = rv[np.argsort(X[rv, 1])]
    edges, w = [], []
    for e in em:
        y = X[e, 1]
        k = int(np.clip(np.searchsorted(X[rv, 1], y) - 1, 0, len(rv) - 2))
        ya, yb = X[rv[k], 1], X[rv[k + 1], 1]
        edges.append((rv[k], rv[k + 1]))
        w.append(np.clip((y - ya) / (yb - ya), 0, 1))
    return GarmentMesh(X=X, tris=tris, seam_emitters=em, seam_edges=np.array(edges), seam_weights=np.array(w))


def model_and_state(scene=None, seed=0):
    mesh = seamed_mesh(seed)
    model = ClothModel(mesh, FABRIC, scene or Scene())
    x = random_drape(mesh, seed=seed)
    return model, x


def fd_gradient_check(model, x, term, h=1e-6, seed=1):
    """The term's forces are minus the gradient of its energy."""
    check_gradient(
        lambda y: model.energy(y, [term]),
        -model.forces(x, [term]),
        x,
        h=h,
        rtol=1e-6,
        seed=seed,
        floor=np.abs(model.forces(x, [term])).max(),
        what=term,
    )


def fd_hessian_check(model, x, term, h=1e-6, seed=2, project=False, rtol=1e-6):
    """The term's stiffness is minus the Jacobian of its forces."""
    H = model.stiffness(x, [term], project=project)
    assert abs(H).max() > 0, f"{term}: analytic Hessian trivially zero"
    check_hessian(lambda y: -model.forces(y, [term]), H, x, h=h, rtol=rtol, seed=seed, what=term)


@pytest.mark.parametrize("term", ["membrane", "bending", "gravity", "seams"])
def test_gradient_fd(term):
    model, x = model_and_state()
    assert term in model.terms
    fd_gradient_check(model, x, term)


@pytest.mark.parametrize("term", ["membrane", "bending", "seams"])
def test_hessian_fd(term):
    model, x = model_and_state()
    fd_hessian_check(model, x, term)


def test_gravity_hessian_is_zero_and_energy_linear():
    model, x = model_and_state()
    assert model.stiffness(x, ["gravity"]).count_nonzero() == 0
    assert model.energy(x, ["gravity"]) == pytest.approx(np.sum(model.mass * 9.81 * x[:, 1]))


def test_random_drape_has_compressed_and_stretched_triangles():
    model, x = model_and_state()
    H = np.empty((len(model.tris), 9, 9))
    K.membrane_element_hessians(x, model.tris, model.Dminv, model.tri_area, model.mu, model.lam, False, H)
    mins = np.linalg.eigvalsh(H).min(axis=1)
    scale = np.abs(H).max()
    assert (mins < -1e-6 * scale).sum() > 5, "the test state must exercise the PSD path"


def test_projected_membrane_hessian_psd_and_exact_in_tension():
    model, x = model_and_state()
    m = len(model.tris)
    H = np.empty((m, 9, 9))
    Hp = np.empty((m, 9, 9))
    K.membrane_element_hessians(x, model.tris, model.Dminv, model.tri_area, model.mu, model.lam, False, H)
    K.membrane_element_hessians(x, model.tris, model.Dminv, model.tri_area, model.mu, model.lam, True, Hp)
    scale = np.abs(H).max()
    assert np.linalg.eigvalsh(Hp).min() > -1e-10 * scale
    # whole assembled matrix PSD too
    Kp = model.stiffness(x, ["membrane"]).toarray()
    assert np.linalg.eigvalsh(Kp).min() > -1e-9 * np.abs(Kp).max()
    # in tension (both principal 2nd PK stresses >= 0) the projection is the identity
    stretched = x.copy()
    stretched[:, :2] = model.X * np.array([1.15, 1.05])
    stretched[:, 2] = 0.002 * np.sin(60 * model.X[:, 0])
    K.membrane_element_hessians(stretched, model.tris, model.Dminv, model.tri_area, model.mu, model.lam, False, H)
    K.membrane_element_hessians(stretched, model.tris, model.Dminv, model.tri_area, model.mu, model.lam, True, Hp)
    np.testing.assert_allclose(Hp, H, rtol=0, atol=1e-12 * np.abs(H).max())


def test_clamp_psd_2x2():
    rng = np.random.default_rng(0)
    Sp = np.empty((2, 2))
    for _ in range(200):
        A = rng.normal(size=(2, 2))
        S = A + A.T
        K._clamp_psd_2x2(S, Sp)
        w, V = np.linalg.eigh(S)
        ref = (V * np.maximum(w, 0)) @ V.T
        np.testing.assert_allclose(Sp, ref, atol=1e-12)


def test_contact_plane_exact_derivatives():
    # a half-space: the Gauss-Newton Hessian is the exact Hessian
    body = PlaneBody(point=np.array([0, 0, 0.0]), normal=np.array([0.2, 0.1, 1.0]))
    model, x = model_and_state(Scene(body=body, contact_offset=0.01))
    assert (body.phi_grad(x)[0] < 0.01).sum() > 5
    fd_gradient_check(model, x, "contact")
    fd_hessian_check(model, x, "contact", h=1e-7)


def test_contact_sphere_exact_hessian_and_its_projection():
    """On a sphere the exact contact Hessian is S n nᵀ - F (I - n nᵀ)/r: central
    differences of the forces match ``stiffness(project=False)``; the projected
    one is each vertex block's PSD part, so it differs from the exact one by
    the convex body's negative curvature term and is PSD."""
    c = np.array([0.05, 0.04, -0.2])
    body = SphereBody(center=c, radius=0.2005)
    model, x = model_and_state(Scene(body=body, contact_offset=0.01))
    phi, grad = body.phi_grad(x)
    inside = phi < 0.01
    assert inside.sum() > 5
    fd_gradient_check(model, x, "contact")
    fd_hessian_check(model, x, "contact", h=1e-7, rtol=1e-5)
    exact = model.stiffness(x, ["contact"], project=False).toarray()
    proj = model.stiffness(x, ["contact"], project=True).toarray()
    assert np.linalg.eigvalsh(proj).min() > -1e-9 * np.abs(proj).max()
    assert np.linalg.eigvalsh(exact).min() < -1e-6 * np.abs(exact).max()  # the curvature term is there
    # the difference is exactly the clamped negative part: -F/r on the tangent plane of in-contact vertices
    pen = np.maximum(0.01 - phi, 0)
    r = np.linalg.norm(x - c, axis=1)
    neg = -(model.contact_normal_force(pen) / r)
    assert np.trace(exact - proj) == pytest.approx(2 * neg[inside].sum(), rel=1e-9)


def test_contact_grid_sdf_exact_hessian():
    """The mannequin's B-spline SDF: ``phi_hess`` is the derivative of ``phi_grad``,
    and the exact contact Hessian over a grid body matches central differences
    (the curvature term included: the Gauss-Newton part alone does not)."""
    from couture.cloth.body import GridSDFBody

    rng = np.random.default_rng(4)
    # a smooth concave-convex field: a sphere's distance plus a ripple, sampled on a 2 cm grid
    n, h_grid = 30, 0.02
    origin = np.array([-0.3, -0.3, -0.5])
    g = origin + h_grid * np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1)
    values = np.linalg.norm(g - [0.05, 0.04, -0.2], axis=-1) - 0.2 + 0.01 * np.sin(12 * g[..., 0])
    body = GridSDFBody(origin=origin, spacing=h_grid, values=values)
    p = rng.uniform(-0.2, 0.2, size=(40, 3)) + [0, 0, -0.2]
    H = body.phi_hess(p)
    assert_close(H, along_axes(lambda q: body.phi_grad(q)[1], p, 1e-6), 1e-5, nontrivial=1.0, what="phi_hess")
    model, x = model_and_state(Scene(body=body, contact_offset=0.01))
    phi, _ = body.phi_grad(x)
    assert (phi < 0.01).sum() > 5
    fd_hessian_check(model, x, "contact", h=1e-7, rtol=1e-5)


def test_friction_anchor_derivatives():
    body = PlaneBody(point=np.array([0, 0, 0.0]), normal=np.array([0.0, 0.3, 1.0]))
    model, x = model_and_state(Scene(body=body, friction=True))
    model.update_friction(x)
    assert model.anchored.sum() > 5
    x2 = x + 0.001  # move off the anchors so the springs pull
    fd_gradient_check(model, x2, "friction")
    fd_hessian_check(model, x2, "friction")


def test_total_stiffness_consistent_with_forces_in_tension():
    model, x = model_and_state(Scene(body=PlaneBody(np.zeros(3), np.array([0, 0, 1.0]))))
    xs = x.copy()
    xs[:, :2] = model.X * 1.1
    xs[:, 2] = 0.003 * np.cos(50 * model.X[:, 1])
    fd_hessian_check(model, xs, "membrane", project=True)  # tension: projection inactive


def test_stiffness_same_object_and_pattern():
    model, x = model_and_state()
    K1 = model.stiffness(x)
    ind, ptr, data1 = K1.indices.copy(), K1.indptr.copy(), K1.data.copy()
    K2 = model.stiffness(x * 1.01)
    assert K2 is K1
    assert np.array_equal(K2.indices, ind) and np.array_equal(K2.indptr, ptr)
    assert not np.array_equal(K2.data, data1)
    dense = K2.toarray()
    np.testing.assert_allclose(dense, dense.T, atol=1e-12 * np.abs(dense).max())
    assert K1.has_sorted_indices


def test_dforces_dX_vs_rebuilt_models():
    mesh = seamed_mesh(0)
    scene = Scene()
    model = ClothModel(mesh, FABRIC, scene)
    x = random_drape(mesh, seed=4)
    rng = np.random.default_rng(5)
    dX = rng.normal(size=mesh.X.shape)
    h = 1e-6

    def forces_at(terms=None):
        return lambda X: ClothModel(GarmentMesh(**{**mesh.__dict__, "X": X}), FABRIC, scene).forces(x, terms)

    for terms in (None, ["membrane"], ["bending"], ["gravity"]):
        check_jacobian(
            forces_at(terms),
            lambda d, terms=terms: model.dforces_dX(x, d, terms),
            mesh.X,
            h=h,
            rtol=1e-6,
            dirs=[dX],
            what=f"dforces_dX {terms}",
        )
    fp = forces_at()(mesh.X + h * dX)
    # seams do not depend on X
    assert np.abs(model.dforces_dX(x, dX, ["seams"])).max() == 0
    # set_rest_positions matches a rebuild
    model.set_rest_positions(mesh.X + h * dX)
    np.testing.assert_allclose(model.forces(x), fp, rtol=0, atol=1e-12 * np.abs(fp).max())


@pytest.mark.parametrize("project", [False, True])
def test_element_hessians_assemble_to_the_membrane_stiffness(project):
    """Both call sites of the membrane Hessian block (the per-element output
    and the CSR assembly) give one matrix, compressed triangles included."""
    model, x = model_and_state()
    H = np.zeros((len(model.tris), 9, 9))
    K.membrane_element_hessians(x, model.tris, model.Dminv, model.tri_area, model.mu, model.lam, project, H)
    assert np.abs(H).max() > 0
    dofs = (3 * model.tris[:, :, None] + np.arange(3)[None, None, :]).reshape(len(model.tris), 9)
    rows = np.repeat(dofs[:, :, None], 9, axis=2).ravel()
    cols = np.repeat(dofs[:, None, :], 9, axis=1).ravel()
    dense = np.zeros((3 * model.n, 3 * model.n))
    np.add.at(dense, (rows, cols), H.ravel())
    Km = model.stiffness(x, ["membrane"], project=project).toarray()
    np.testing.assert_allclose(dense, Km, rtol=0, atol=1e-14 * np.abs(Km).max())


# ---------------------------------------------------------------- degenerate configurations


def _altitude(P):
    """Smallest altitude [m] of the triangle P (3, 2 or 3)."""
    P = np.column_stack([P, np.zeros(3)]) if P.shape[1] == 2 else P
    area2 = np.linalg.norm(np.cross(P[1] - P[0], P[2] - P[0]))
    return area2 / max(np.linalg.norm(P[(i + 1) % 3] - P[i]) for i in range(3))


@pytest.mark.parametrize("case", sorted(degenerate_triangles()))
def test_membrane_derivatives_on_degenerate_triangles(case):
    """One triangle nearly collinear, nearly of zero area, inverted, ...:
    the membrane gradient, its exact Hessian and dF/dX still match central
    differences (steps a small fraction of the smallest altitude: the rest
    shape's inverse grows as 1/altitude, and so do F's derivatives)."""
    X, x = degenerate_triangles()[case]
    model = ClothModel(GarmentMesh(X=X, tris=np.array([[0, 1, 2]], dtype=np.int32)), FABRIC, Scene(gravity=False))
    hx = hX = 1e-5 * _altitude(X)  # F = Ds Dm⁻¹ moves by h / altitude
    f = model.forces(x, ["membrane"])
    check_gradient(lambda y: model.energy(y, ["membrane"]), -f, x, h=hx, rtol=1e-6, floor=np.abs(f).max(), what=case)
    H = model.stiffness(x, ["membrane"], project=False)
    check_hessian(lambda y: -model.forces(y, ["membrane"]), H, x, h=hx, rtol=1e-6, floor=np.abs(H).max(), what=case)

    def forces_at(Xp):
        return ClothModel(GarmentMesh(X=Xp, tris=model.tris), FABRIC, Scene(gravity=False)).forces(x, ["membrane"])

    check_jacobian(forces_at, lambda d: model.dforces_dX(x, d, ["membrane"]), X, h=hX, rtol=1e-6, what=f"{case} dF/dX")


@pytest.mark.parametrize("case", ["sliver rest", "needle rest", "regular"])
def test_bending_dforces_dX_on_a_degenerate_hinge(case):
    """A hinge of two triangles, one wing a degenerate rest shape: the bending
    weights' exact derivative (1/area terms) against central differences."""
    X3, _ = degenerate_triangles()[case]
    # the second wing mirrored across the edge 0-1 (y -> -y), a regular triangle
    X = np.vstack([X3, [[0.55 * X3[1, 0], -0.8 * X3[1, 0]]]])
    tris = np.array([[0, 1, 2], [1, 0, 3]], dtype=np.int32)
    model = ClothModel(GarmentMesh(X=X, tris=tris), FABRIC, Scene(gravity=False))
    assert len(model.bend_stencils) == 1
    rng = np.random.default_rng(3)
    x = np.column_stack([X[:, 0], 0.3 * X[:, 0] * X[:, 1] * 40, X[:, 1]]) + 1e-3 * rng.normal(size=(4, 3))

    def forces_at(Xp):
        return ClothModel(GarmentMesh(X=Xp, tris=tris), FABRIC, Scene(gravity=False)).forces(x, ["bending"])

    check_jacobian(
        forces_at,
        lambda d: model.dforces_dX(x, d, ["bending"]),
        X,
        h=1e-5 * _altitude(X3),
        rtol=1e-6,
        what=f"{case} bending dF/dX",
    )


def test_contact_derivatives_at_the_contact_layer_boundary():
    """Vertices just outside and inside the contact layer's boundary and either
    side of the stiffness ramp's end (contact_penetrations): gradient and
    exact Hessian of the contact term against central differences."""
    body = PlaneBody(point=np.zeros(3), normal=np.array([0.0, 0.0, 1.0]))
    scene = Scene(body=body, contact_offset=0.01, friction=False)
    model, x = model_and_state(scene)
    h = 1e-7
    pens = contact_penetrations(model.contact_smoothing, h)
    x = x.copy()
    x[:, 2] = 0.01 - pens[np.arange(model.n) % len(pens)]  # phi = z: penetration 0.01 - z
    fd_gradient_check(model, x, "contact", h=h)
    fd_hessian_check(model, x, "contact", h=h, project=False)

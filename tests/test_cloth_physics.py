"""Closed forms: StVK uniaxial stretch, cylinder bending, cantilever, weight,
and a hanging sheet solved to zero residual."""

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from couture.cloth import BEND_CONSTANT, GRAVITY, ClothModel, Scene, lame_parameters
from couture.cloth.testing import newton
from couture.mesh import GarmentMesh, grid_sheet
from schemas.design import Fabric


def test_lame_parameters_plane_stress():
    mu, lam = lame_parameters(100.0, 0.3)
    assert mu == pytest.approx(100.0 / 2.6)
    assert lam == pytest.approx(30.0 / 0.91)
    # uniaxial plane-stress modulus 4 mu (mu + lam) / (2 mu + lam) is E h
    assert 4 * mu * (mu + lam) / (2 * mu + lam) == pytest.approx(100.0)


@pytest.mark.parametrize("stretch", [1.05, 1.3, 0.9])
def test_uniaxial_stretch_closed_form(stretch):
    """StVK strip (rest L x W) stretched by s along x, laterally free (plane
    stress). Green strain G_xx = (s²-1)/2; free sides need S_yy = 0, so
    G_yy = -nu G_xx and S_xx = Eh G_xx (see test_lame_parameters_plane_stress).
    The homogeneous state x = (s X, b Y) with b = sqrt(1 - 2 nu G_xx) is then
    in equilibrium with zero force on every interior and side vertex; the
    ends carry the total force s S_xx W (1st Piola-Kirchhoff times width),
    and the energy is L W Eh G_xx² / 2."""
    Eh, nu, L, W = 200.0, 0.3, 0.2, 0.05
    mesh = grid_sheet(L, W, 17, 6)
    model = ClothModel(mesh, Fabric(stretch_stiffness=Eh, poisson_ratio=nu, bend_stiffness=1e-6), Scene(gravity=False))
    Gxx = 0.5 * (stretch**2 - 1)
    b = np.sqrt(1 - 2 * nu * Gxx)
    x = np.column_stack([stretch * mesh.X[:, 0], b * mesh.X[:, 1], np.zeros(model.n)])
    f = model.forces(x, ["membrane"])
    scale = stretch * Eh * abs(Gxx) * W
    right = np.isclose(mesh.X[:, 0], L)
    left = np.isclose(mesh.X[:, 0], 0)
    interior = ~(right | left)
    assert np.abs(f[interior]).max() < 1e-10 * scale
    assert f[right, 0].sum() == pytest.approx(-stretch * Eh * Gxx * W, rel=1e-10)
    assert f[left, 0].sum() == pytest.approx(stretch * Eh * Gxx * W, rel=1e-10)
    assert model.energy(x, ["membrane"]) == pytest.approx(L * W * Eh * Gxx**2 / 2, rel=1e-10)


def cylinder(X, R, angle, center):
    d = np.array([np.cos(angle), np.sin(angle)])
    a = np.array([-np.sin(angle), np.cos(angle)])
    s = (X - center) @ d
    t = (X - center) @ a
    x = np.zeros((len(X), 3))
    x[:, :2] = np.outer(R * np.sin(s / R), d) + np.outer(t, a)
    x[:, 2] = R * (1 - np.cos(s / R))
    return x


CYLINDER_GRIDS = (11, 21, 41, 81)
"""n x n grids of the 0.3 m square: h = 30, 15, 7.5, 3.75 mm"""
CYLINDER_ANGLES = (0, 20, 45, 70, 90)


def test_cylinder_bending_energy_converges_to_continuum():
    """Quality (triangle-library) mesh bent into a cylinder of radius R in
    several directions, every vertex on it (an imposed bend): discrete
    energy vs (k/2) ∫ κ² dA = (k/2) A / R². Interior edges only carry
    hinges, so free edges lose an O(h) strip; the comparison is over the area
    the hinges cover (Σ_e (A0+A1)/3).

    BEND_CONSTANT is calibrated on relaxed equilibria, not imposed bends
    (couture.cloth.model): an affine bend is not an equilibrium of the
    discrete energy on an irregular mesh, and once its interior relaxes it
    keeps BEND_RELAXED_RESPONSE (0.938, measured) of the energy it costs
    imposed, so the imposed bend costs 1/0.938 = 1.066 times the continuum
    (the relaxed one matches it: the next test). Divided by that, the imposed
    energy is the calibration BEND_IMPOSED_FIT (0.29) states: a convergence
    study (it was one 41 x 41 mesh within 5 % of the continuum, measured
    3.8 %): the worst error of E / (1.066 x continuum) over the five
    directions against h, rate fitted on log-log (measured 9.2, 5.0, 3.8,
    1.3 % at h = 30 .. 3.75 mm, rate 0.89), falls at a rate of at least 0.6,
    and on the finest mesh the mean over directions is 1 within 1 %."""
    from couture.cloth.model import BEND_CONSTANT, BEND_IMPOSED_FIT, BEND_RELAXED_RESPONSE, bending_weights

    assert BEND_CONSTANT == pytest.approx(BEND_IMPOSED_FIT / BEND_RELAXED_RESPONSE, rel=1e-15)
    imposed = 1.0 / BEND_RELAXED_RESPONSE  # an imposed bend's energy over the continuum's
    k, R = 1e-3, 0.2
    hs, worst = [], []
    for n in CYLINDER_GRIDS:
        mesh = grid_sheet(0.3, 0.3, n, n)
        model = ClothModel(mesh, Fabric(bend_stiffness=k), Scene(gravity=False))
        _, fac = bending_weights(mesh.X, model.bend_stencils)
        A_cov = np.sum(1.0 / fac)  # Σ (A0+A1)/3
        A = model.tri_area.sum()
        ratios, full = [], []
        for angle in CYLINDER_ANGLES:
            E = model.energy(cylinder(mesh.X, R, np.deg2rad(angle), np.array([0.15, 0.15])), ["bending"])
            ratios.append(E / (0.5 * k * A_cov / R**2) / imposed)
            full.append(E / (0.5 * k * A / R**2) / imposed)
        hs.append(0.3 / (n - 1))
        worst.append(max(abs(r - 1.0) for r in ratios))
    rate = np.polyfit(np.log(hs), np.log(worst), 1)[0]
    assert rate >= 0.6, (rate, worst)
    assert worst[-1] < 0.02, worst
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.01), ratios
    # the whole area, the free-edge strip included, on the finest mesh
    assert np.all(np.abs(np.array(full) - 1.0) < 0.07), full


RELAXED_ANGLES = (0, 30, 45, 90)


@pytest.mark.parametrize("mesher", ["grid_sheet", "remesher"])
def test_relaxed_cylinder_bending_energy_matches_the_continuum(mesher):
    """What BEND_CONSTANT is calibrated to, checked on its own: a quality
    mesh (a triangle-library sheet, h = 2.5 mm; a square panel meshed by the
    remesher as garments are, h = 5 mm) bent onto a cylinder (R = 10 cm),
    held there on a border band three edges wide (position and slope, so the
    continuum's equilibrium is the cylinder itself), its interior relaxed by
    Newton (gravity off, a cotton's membrane): the interior's bending energy,
    over the window at least 40 % of the half-size from the border, is the
    continuum's (k/2) A / R² within 1.5 % on the mean over four directions
    and 3 % each (measured at c = 0.29: 0.919..0.944 and 0.922..0.955 of it
    over directions and radii, ``couture bench bend_relaxation``; the
    calibration divides by their kinds' mean, 0.938). Relaxing lowers the
    energy (the imposed bend is not an equilibrium): 0.92..0.94 of it
    measured, asserted between 0.90 and 0.97."""
    from scipy.spatial import cKDTree

    from couture.cloth.model import bending_weights

    k, R = 1e-5, 0.1
    if mesher == "grid_sheet":
        mesh = grid_sheet(0.1, 0.1, 41, 41)
    else:
        from couture.pattern.drafted import DraftedPattern
        from couture.remesh import mesh_pattern
        from couture.remesh.fixtures import rectangle_panel

        side, h = 0.2, 0.005
        drafted = DraftedPattern(panels=[rectangle_panel("square", side, side, per_edge=8)])
        mesh = mesh_pattern(drafted, int(round(2 * side * side / (np.sqrt(3) * h * h))), level="fine").mesh
    X = mesh.X
    edges = np.sort(np.concatenate([mesh.tris[:, [0, 1]], mesh.tris[:, [1, 2]], mesh.tris[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    border = cKDTree(X[np.unique(uniq[count == 1])])
    h = float(np.linalg.norm(X[uniq[:, 0]] - X[uniq[:, 1]], axis=1).mean())
    mesh.pinned = np.nonzero(border.query(X)[0] <= 3 * h)[0].astype(np.int32)
    fabric = Fabric(stretch_stiffness=1160.0, poisson_ratio=0.3, bend_stiffness=k)
    model = ClothModel(mesh, fabric, Scene(gravity=False, seams=False))
    Kw, fac = bending_weights(X, model.bend_stencils)
    mid = 0.5 * (X[model.bend_stencils[:, 0]] + X[model.bend_stencils[:, 1]])
    window = border.query(mid)[0] >= 0.4 * 0.5 * np.ptp(X[:, 0])
    continuum = 0.5 * k * np.sum(1.0 / fac[window]) / R**2
    center = 0.5 * (X.min(axis=0) + X.max(axis=0))

    def window_energy(x):
        kx = np.einsum("ej,ejk->ek", Kw, x[model.bend_stencils])
        return 0.5 * k * BEND_CONSTANT * np.sum((fac * np.sum(kx * kx, axis=1))[window])

    ratios, relaxation = [], []
    for angle in RELAXED_ANGLES:
        x_imposed = cylinder(X, R, np.deg2rad(angle), center)
        x, hist = newton(model, x_imposed, tol=1e-9, max_iters=40)
        assert hist[-1] < 1e-9, hist[-3:]
        ratios.append(window_energy(x) / continuum)
        relaxation.append(window_energy(x) / window_energy(x_imposed))
    print(mesher, "relaxed / continuum", np.round(ratios, 4), "relaxed / imposed", np.round(relaxation, 4))
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.015), ratios
    assert np.all(np.abs(np.array(ratios) - 1.0) < 0.03), ratios
    assert np.all((np.array(relaxation) > 0.90) & (np.array(relaxation) < 0.97)), relaxation


def test_bending_effective_poisson_minus_one_third():
    """The discrete energy density is a Kirchhoff plate (k/2)[κ1² + κ2² +
    2 ν_b κ1 κ2] with ν_b = -1/3 (derived for the equilateral lattice in
    couture.cloth.model): a saddle (κ1 = -κ2) costs 2 - 2 ν_b = 8/3 times
    the cylinder (small-curvature height fields z = κ (u² ∓ v²)/2)."""
    k, kap = 1e-3, 0.5
    mesh = grid_sheet(0.3, 0.3, 31, 31)
    model = ClothModel(mesh, Fabric(bend_stiffness=k), Scene(gravity=False))
    u, v = (mesh.X - 0.15).T
    cyl = np.column_stack([mesh.X, 0.5 * kap * u**2])
    sad = np.column_stack([mesh.X, 0.5 * kap * (u**2 - v**2)])
    ratio = model.energy(sad, ["bending"]) / model.energy(cyl, ["bending"])
    assert ratio == pytest.approx(8 / 3, rel=0.05)


def cantilever(nx, ny, L=0.2, W=0.1, clamp=0.02, k=0.06, rho=0.15, mesh=None):
    """The strip [-clamp, L] x [0, W] (a triangle-library sheet of about nx x ny
    vertices, or ``mesh``) held for X <= 0, horizontal; its weight per length q
    from its own area (W for the sheet)."""
    mesh = mesh if mesh is not None else grid_sheet(L + clamp, W, nx, ny)
    mesh.X[:, 0] -= clamp
    mesh.pinned = np.nonzero(mesh.X[:, 0] <= 1e-12)[0]
    fabric = Fabric(stretch_stiffness=1e6, poisson_ratio=0.3, bend_stiffness=k, area_density=rho)
    model = ClothModel(mesh, fabric, Scene())
    x0 = np.column_stack([mesh.X[:, 0], np.zeros(model.n), mesh.X[:, 1]])  # horizontal, y up
    tip = np.isclose(mesh.X[:, 0], L)
    q = rho * GRAVITY * model.tri_area.sum() / (L + clamp)
    return mesh, model, x0, tip, q


def test_cantilever_beam_mode_energy():
    """The Euler-Bernoulli deflection w(s) = q/(24 EI)(s⁴ - 4Ls³ + 6L²s²),
    EI = k W, imposed on the clamped plate: discrete bending energy within 5 %
    of the beam's ∫ EI/2 w''² ds (so EI = k W along the beam mode) times
    1 / BEND_RELAXED_RESPONSE, what an imposed bend costs over the continuum
    (test_cylinder_bending_energy_converges_to_continuum; measured 1.063
    times the beam's, 0.997 after dividing)."""
    from couture.cloth.model import BEND_RELAXED_RESPONSE

    L, W, k = 0.2, 0.1, 0.06
    mesh, model, x0, tip, q = cantilever(67, 31, L, W, k=k)
    s = np.clip(mesh.X[:, 0], 0, None)
    EI = k * W
    w = q / (24 * EI) * (s**4 - 4 * L * s**3 + 6 * L**2 * s**2)
    x = x0.copy()
    x[:, 1] = -w
    E_beam = EI / 2 * (q / (2 * EI)) ** 2 * L**5 / 5
    assert model.energy(x, ["bending"]) * BEND_RELAXED_RESPONSE / E_beam == pytest.approx(1.0, abs=0.05)


def _cantilever_tip_error(
    nx: int, ny: int, L: float = 0.2, W: float = 0.1, k: float = 0.06, mesh=None, lattice: bool = False
) -> float:
    """Relative error of the linear (small-load) tip deflection of a clamped
    strip under its weight against the narrow beam's w = q L⁴/(8 EI),
    EI = k W (1 - nu_b²), W the strip's mean width. ``lattice``: ``mesh`` is
    an equilateral lattice, given k / (3 BEND_CONSTANT) so that its plate
    stiffness is k (test_small_deflection_cantilever_converges_to_the_plate)."""
    k_model = k / (3 * BEND_CONSTANT) if lattice else k
    mesh, model, x0, tip, q = cantilever(nx, ny, L, W, k=k_model, mesh=mesh)
    W = model.tri_area.sum() / np.ptp(mesh.X[:, 0])
    free = model.free_dofs
    Kf = model.stiffness(x0)[free][:, free].tocsc()
    u = spla.spsolve(Kf, model.forces(x0).reshape(-1)[free])
    x = x0.copy()
    x.reshape(-1)[free] += u
    EI = k * W * (1 - (-1 / 3) ** 2)
    w_tip = q * L**4 / (8 * EI)
    assert w_tip / L < 0.05  # small deflection
    return float(-x[tip, 1].mean() / w_tip - 1.0)


STRIP_WIDTH = 0.09 / (np.sqrt(3) / 2)
"""[m] the small-deflection strips' width, 0.104: nine lattice spacings of
``equilateral_strip(22)``, so every lattice strip has it exactly"""


def equilateral_strip(rows: int, length: float = 0.22) -> GarmentMesh:
    """An equilateral lattice over [0, length] x [0, STRIP_WIDTH] (mean):
    ``rows`` + 1 columns of vertices at x = j h √3/2 (so the clamp line
    x = 0.02 is one for rows a multiple of 11), every other column offset by
    h/2 along y (the long sides zigzag by h/2); rows a multiple of 22."""
    h = length / rows / (np.sqrt(3) / 2)
    ny = 9 * rows // 22 + 1
    j, i = np.meshgrid(np.arange(rows + 1), np.arange(ny), indexing="ij")
    X = np.column_stack([(j * h * np.sqrt(3) / 2).ravel(), (i * h + 0.5 * h * (j % 2)).ravel()])
    ids = np.arange(len(X)).reshape(rows + 1, ny)
    tris = []
    for r in range(rows):
        a, b, c, d = ids[r, :-1], ids[r, 1:], ids[r + 1, :-1], ids[r + 1, 1:]
        pairs = [(a, c, b), (b, c, d)] if r % 2 == 0 else [(a, d, b), (a, c, d)]
        tris += [np.column_stack(p) for p in pairs]
    T = np.concatenate(tris).astype(np.int32)
    e1, e2 = X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]
    flip = (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) < 0
    T[flip] = T[flip][:, [0, 2, 1]]
    return GarmentMesh(X=X, tris=T)


CANTILEVER_MESHES = [(12, 6), (23, 11), (45, 22), (89, 43)]
"""h = 20, 10, 5, 2.5 mm (the clamped 0.22 m x STRIP_WIDTH strip)"""


def test_small_deflection_cantilever_converges_to_the_plate():
    """Linear (small-load) solve of a clamped strip under its weight. The
    discrete bending energy is a Kirchhoff plate with D = k and nu_b = -1/3
    (test_bending_effective_poisson_minus_one_third), so in the linear regime
    a narrow strip also bends laterally and its beam stiffness is
    EI = k W (1 - nu_b²) (Timoshenko, plates: narrow plate -> beam); with
    EI = k W it is 16 % more than beam theory, all of it from the lateral
    mode (test_cantilever_beam_mode_energy shows EI = k W along the beam mode).
    This strip is not narrow (W ≈ L / 2): its clamp holds the whole width
    flat and stops the lateral bending near it, so the plate's tip deflection
    is below the narrow beam's. The reference is that plate's, computed here
    on equilateral lattices, where the hinge energy is exactly a plate with
    D = 3 c k and nu_b = -1/3 (couture.cloth.model; it does not relax off an
    affine bend), so k / (3 BEND_CONSTANT) gives D = k with no calibration:
    tip errors against the narrow beam -4.34, -5.62, -6.21 % at h = 11.5,
    5.8, 2.9 mm (first order: the steps halve), the plate -6.81 %
    (Richardson; -6.50 % at 1.4 mm, -6.79 % extrapolated from there).

    A convergence study rather than one mesh under a bound set just above its
    measured error: the tip error of the quality (triangle-library) strip
    against the plate, mesh size h = 20 .. 2.5 mm, the rate fitted on log-log
    (measured 17.3, 9.5, 4.4, 1.8 %, rate 1.09), must fall with h at a rate of
    at least 0.6, so the discrete strip tends to the plate (a wrong stiffness
    would leave a constant error and a rate near 0). With the imposed-bend
    calibration (c = 0.29, before issue 30) the same strips read 16.5, 8.8,
    3.8, 1.1 % against the narrow beam (the test then compared with it:
    apparently converged) and 25.0, 16.7, 11.3, 8.5 % against the plate
    (rate 0.52), heading for the 6 % that the relaxation softens
    (BEND_RELAXED_RESPONSE): the relaxation and the clamp's stiffening had
    cancelled. Before the clamp's hinges got their factor
    (``couture.cloth.model``, Clamps) the narrow-beam errors were 17.8, 12.9,
    7.4, 3.1 % (W = 0.1 m): the clamp acted half a row inside the held region.
    The 20 mm mesh (one row of cells in the clamp, five across) is off the
    trend."""
    lattice = {rows: _cantilever_tip_error(0, 0, mesh=equilateral_strip(rows), lattice=True) for rows in (22, 44, 88)}
    coarse = lattice.pop(22)
    steps = (coarse - lattice[44]) / (lattice[44] - lattice[88])
    assert 1.5 < steps < 3.0, (coarse, lattice)  # first-order convergence: the step halves
    plate = 2 * lattice[88] - lattice[44]  # Richardson, first order
    assert -0.09 < plate < -0.05, plate  # stiffer than the narrow beam, softer than EI = k W (-11 %)
    hs, errs = [], []
    for nx, ny in CANTILEVER_MESHES:
        hs.append(0.22 / (nx - 1))
        errs.append((1.0 + _cantilever_tip_error(nx, ny, W=STRIP_WIDTH)) / (1.0 + plate) - 1.0)
    print("plate vs narrow beam", plate, "errors vs the plate", np.round(errs, 4))
    assert all(e > 0 for e in errs), errs  # softer than the continuum, from above
    rate = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert rate >= 0.6, (rate, errs)
    assert errs[-1] < 0.03, errs
    assert all(b < a for a, b in zip(errs[1:], errs[2:], strict=False)), errs


def test_total_weight():
    mesh = grid_sheet(0.4, 0.25, 11, 7, jitter=0.0005, seed=3)
    fabric = Fabric(area_density=0.12)
    model = ClothModel(mesh, fabric, Scene())
    area = model.tri_area.sum()
    assert area == pytest.approx(0.1, rel=1e-2)
    assert model.mass.sum() == pytest.approx(area * 0.12, rel=1e-12)
    f = model.forces(mesh.x0, ["gravity"])
    np.testing.assert_allclose(f.sum(axis=0), [0, -area * 0.12 * GRAVITY, 0], rtol=1e-12, atol=1e-15)
    # with no gravity term there is no weight at all
    assert "gravity" not in ClothModel(mesh, fabric, Scene(gravity=False)).terms


def test_sheet_hanging_from_two_corners_converges():
    mesh = grid_sheet(0.3, 0.3, 13, 13)
    top = np.nonzero(np.isclose(mesh.X[:, 1], 0.3))[0]
    corners = [top[np.argmin(mesh.X[top, 0])], top[np.argmax(mesh.X[top, 0])]]
    mesh.pinned = np.array(corners, np.int32)
    # vertical sheet (y up), slightly rippled so it can leave its plane
    mesh.x0 = np.column_stack([mesh.X, 0.01 * np.sin(7 * mesh.X[:, 0]) * np.sin(5 * mesh.X[:, 1])])
    model = ClothModel(mesh, Fabric(), Scene())
    x, hist = newton(model, mesh.x0, tol=1e-10, max_iters=100)
    assert hist[-1] < 1e-8, hist[-5:]
    np.testing.assert_array_equal(x[corners], mesh.x0[corners])
    assert np.all(np.isfinite(x))
    assert x[:, 1].min() < mesh.x0[:, 1].min()  # it sags


def test_seams_close_the_gap_between_panels():
    """Two panels 2 cm apart, seamed along facing edges that have different
    vertex counts (emitter -> point on receiver edge). Without external load
    the seam springs close the gap (up to force / stiffness of a slight length mismatch)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from test_cloth_derivatives import seamed_mesh

    mesh = seamed_mesh(0)  # panels at x in [0, 0.1] and [0.12, 0.22]
    left = np.nonzero(mesh.X[:, 0] < 0.11)[0]
    pins = left[
        [
            np.argmin(mesh.X[left, 0] + mesh.X[left, 1]),
            np.argmax(mesh.X[left, 1] - mesh.X[left, 0]),
            np.argmin(mesh.X[left, 1] - mesh.X[left, 0]),
        ]
    ]
    mesh.pinned = pins.astype(np.int32)
    model = ClothModel(mesh, Fabric(stretch_stiffness=50.0, bend_stiffness=1e-5), Scene(gravity=False))
    assert "seams" in model.terms
    assert model.seam_stiffness == pytest.approx(5000 * model.mu)

    def gaps(x):
        e, (a, b), w = mesh.seam_emitters, mesh.seam_edges.T, mesh.seam_weights
        return np.linalg.norm(x[e] - (1 - w)[:, None] * x[a] - w[:, None] * x[b], axis=1)

    assert gaps(mesh.x0).min() > 0.015
    x, hist = newton(model, mesh.x0, tol=1e-8, max_iters=60)
    # no gravity: the residual is measured against the forces in balance, here
    # at least mu sqrt(A) (a unit strain's force) since the closed seams carry almost none
    assert hist[-1] < 1e-8
    assert model.residual_denominator(x) == pytest.approx(model.mu * np.sqrt(model.tri_area.sum()))
    assert np.abs(model.forces(x)[model.free]).max() < 1e-9
    # the jittered edges differ slightly in length: what is left is seam force / k_s
    assert gaps(x).max() < 1e-5


def test_residual_without_gravity_is_scaled_by_the_forces_in_balance():
    """Without gravity the relative residual compares the free force with the
    forces that balance each other (each term's own, pin reactions included),
    never with the free force itself (a ratio of 1 at every x): a strip pulled
    by its pinned ends has a residual of ~0 at the closed-form equilibrium and
    grows with a perturbation; an unloaded sheet measures against mu sqrt(A)."""
    Eh, nu, L, W, s_ = 200.0, 0.3, 0.2, 0.05, 1.1
    mesh = grid_sheet(L, W, 17, 6)
    ends = np.nonzero(np.isclose(mesh.X[:, 0], 0) | np.isclose(mesh.X[:, 0], L))[0]
    mesh.pinned = ends.astype(np.int32)
    model = ClothModel(mesh, Fabric(stretch_stiffness=Eh, poisson_ratio=nu, bend_stiffness=1e-9), Scene(gravity=False))
    assert "gravity" not in model.terms and not model.residual_scale_constant
    Gxx = 0.5 * (s_**2 - 1)
    # pinned ends hold the lateral contraction too, so solve for the equilibrium
    x0 = np.column_stack([s_ * mesh.X[:, 0], mesh.X[:, 1], np.zeros(model.n)])
    x, hist = newton(model, x0, tol=1e-11, max_iters=40)
    assert hist[0] > 1e-3 and hist[-1] < 1e-11
    reaction = np.linalg.norm(model.forces(x)[ends])
    assert reaction > 0.5 * s_ * Eh * Gxx * W  # the ends carry about the 1D load
    assert model.residual_denominator(x) >= reaction
    rng = np.random.default_rng(0)
    xp = x + rng.normal(scale=1e-4 * L, size=x.shape) * model.free[:, None]
    assert model.relative_residual(xp) > 1e3 * hist[-1]

    free_sheet = ClothModel(grid_sheet(L, W, 17, 6), Fabric(stretch_stiffness=Eh), Scene(gravity=False))
    X3 = np.column_stack([mesh.X, np.zeros(model.n)])
    assert free_sheet.relative_residual(X3 + [0.3, -0.1, 2.0]) < 1e-12  # a rigid motion of the rest state
    strained = X3.copy()
    strained[:, 0] *= 1.001
    r = free_sheet.relative_residual(strained)
    assert 5e-4 < r < 2e-3  # about the strain (0.1 %) it holds

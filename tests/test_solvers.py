"""Equilibrium solvers: agreement, accuracy, robustness at the extremes, diagnoses.

Scenes use the real couture.cloth.ClothModel (y up, gravity -y); builders in
tests/solver_testmodel.py. Fast: small meshes; heavier scenes in
test_solvers_slow.py.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from solver_testmodel import cloth_hanging_sheet, fabric, horizontal

from couture.cloth import ClothModel, Scene
from couture.mesh import grid_sheet
from couture.solvers import SOLVERS, get_solver
from couture.solvers.cascadic import Prolongation, locate, polish_prolongated, solve_cascadic
from couture.solvers.linalg import (
    IC0,
    FactorizationError,
    ReducedSystem,
    available_backends,
    factorize,
    pcg,
    seam_first_order,
)


def test_registry():
    assert set(SOLVERS) == {"kinetic", "newton", "verlet", "style3d"}
    for name in SOLVERS:
        assert get_solver(name).name == name
    with pytest.raises(ValueError, match="unknown solver"):
        get_solver("nope")


def test_hanging_sheet_kinetic_matches_newton():
    m = cloth_hanging_sheet(10, 10, size=0.5)
    newton = get_solver("newton").solve(m, m.mesh.x0, tol=1e-9, max_iters=300)
    assert newton.converged, newton.diagnosis
    assert newton.residual < 1e-8
    assert m.relative_residual(newton.x) < 1e-8
    kin = get_solver("kinetic").solve(m, m.mesh.x0, tol=1e-6, max_iters=5000)
    assert kin.converged, kin.diagnosis
    # nothing exploded, pins stayed, it actually hangs
    assert np.all(kin.x[~m.free] == m.mesh.x0[~m.free])
    assert kin.x[:, 1].min() < -0.2
    dist = np.linalg.norm(kin.x - newton.x, axis=1).max()
    assert dist < 1e-4 * 0.5, dist  # 1e-4 of the sheet size
    for r in (kin, newton):
        assert r.iterations > 0 and r.wall_time > 0 and r.history
        assert {"assembly_s", "linear_solve_s", "steps"} <= set(r.stats)
    assert kin.stats["cg_iterations"] > 0 and kin.stats["velocity_resets"] > 0


class _RoundedEnergy:
    """A model whose energy is rounded down to 31 significant bits: differences below
    5e-10 to 9e-10 of its size are lost, far above the energy decrease of a Newton step
    near equilibrium (which shrinks with the square of the residual), as on the
    10k-vertex skirt (1e-11 J of noise against a 3e-13 J decrease). Forces and
    stiffness are exact."""

    BITS = 31

    def __init__(self, model):
        self._m = model

    def __getattr__(self, name):
        return getattr(self._m, name)

    def energy(self, x, terms=None):
        mantissa, exponent = np.frexp(float(self._m.energy(x, terms)))
        return float(np.ldexp(np.floor(mantissa * 2.0**self.BITS) / 2.0**self.BITS, exponent))

    def energy_and_forces(self, x, terms=None):
        return self.energy(x, terms), self._m.forces(x, terms)


def test_newton_converges_below_the_energy_round_off():
    m = cloth_hanging_sheet(10, 10, size=0.5)
    noisy = _RoundedEnergy(m)
    res = get_solver("newton").solve(noisy, m.mesh.x0, tol=1e-10, max_iters=300)
    assert res.converged, res.diagnosis
    assert m.relative_residual(res.x) < 1e-10
    clean = get_solver("newton").solve(m, m.mesh.x0, tol=1e-10, max_iters=300)
    assert np.abs(res.x - clean.x).max() < 1e-6
    # from 3 nm off the equilibrium (relative residual ~2e-3) a Newton step lowers the
    # energy by ~1.5e-11 of it (1.2e-12 to 1.8e-12 measured at 1 nm, quadratic in the
    # offset): above the double's resolution of the Armijo test, a thirtieth of the
    # 4.7e-10 the rounded energy resolves, so the force-based test takes the step (150
    # of 150 starts at 2, 3 and 5 nm did; at 0.1 nm the Armijo margin is below the
    # double's ulp and the rounded energy accepts; from the placement round-off decides)
    x = clean.x.copy()
    free = np.asarray(m.free, bool)
    x[free] += np.random.default_rng(0).normal(size=x[free].shape) * 3e-9
    assert m.relative_residual(x) > 1e-4
    near = get_solver("newton").solve(noisy, x, tol=1e-10, max_iters=300)
    assert near.converged, near.diagnosis
    assert m.relative_residual(near.x) < 1e-10
    assert near.stats["slope_steps"] > 0  # the end came from the force-based test


def test_kinetic_converges_below_the_energy_round_off():
    """Kinetic damping's energy test has the same limit: near equilibrium a
    step's energy change drowns in round-off and every step was rejected (the
    coarse skirt stalled at 6.8e-6 for 1500 steps). Within round-off it ranks
    states by the force residual instead."""
    m = cloth_hanging_sheet(10, 10, size=0.5)
    res = get_solver("kinetic").solve(_RoundedEnergy(m), m.mesh.x0, tol=1e-9, max_iters=3000)
    assert res.converged, res.diagnosis
    assert m.relative_residual(res.x) < 1e-9
    assert res.stats["round_off_steps"] > 0
    clean = get_solver("newton").solve(m, m.mesh.x0, tol=1e-10, max_iters=300)
    assert np.abs(res.x - clean.x).max() < 1e-6


def _seamed_tube(nx=8, ny=6, w=0.4, h=0.3):
    """A sheet whose left and right edges are sewn together (a tube), start flat."""
    mesh = horizontal(grid_sheet(w, h, nx, ny))
    X = mesh.X
    left = np.nonzero(np.isclose(X[:, 0], 0))[0]
    right = np.nonzero(np.isclose(X[:, 0], w))[0]
    left = left[np.argsort(X[left, 1])]
    em, edges, wts = [], [], []
    for v in right:
        y = X[v, 1]
        k = min(np.searchsorted(X[left, 1], y, side="right") - 1, len(left) - 2)
        a, b = left[k], left[k + 1]
        em.append(v)
        edges.append((a, b))
        wts.append((y - X[a, 1]) / (X[b, 1] - X[a, 1]))
    mesh.seam_emitters = np.array(em, np.int32)
    mesh.seam_edges = np.array(edges, np.int32)
    mesh.seam_weights = np.array(wts)
    top = np.nonzero(np.isclose(X[:, 1], h))[0]
    mesh.pinned = top[np.argsort(X[top, 0])][[1, len(top) // 2]].astype(np.int32)
    mesh.__post_init__()
    return mesh


EXTREMES = {
    "bend_1e-9": dict(bend=1e-9),
    "bend_1e-2": dict(bend=1e-2),
    "stretch_1": dict(stretch=1.0),
    "stretch_1e5": dict(stretch=1e5),
    "density_0.01": dict(density=0.01),
    "density_1": dict(density=1.0),
    "seam_1e2": dict(seam=1e2),
    "seam_1e6": dict(seam=1e6),
    "degenerate_tris": dict(degenerate=True),
    "huge_displacement": dict(kick=5.0),
}


@pytest.mark.parametrize("case", sorted(EXTREMES))
@pytest.mark.parametrize("solver", ["kinetic", "newton", "verlet"])
def test_extremes_converge_or_diagnose(case, solver):
    p = EXTREMES[case]
    fab = fabric(stretch=p.get("stretch", 500.0), bend=p.get("bend", 1e-6), density=p.get("density", 0.15))
    if "seam" in p:
        mesh = _seamed_tube()
        model = ClothModel(mesh, fab, Scene())
        model = ClothModel(mesh, fab, Scene(seam_stiffness=p["seam"] * model.mu))
    else:
        mesh = horizontal(grid_sheet(0.3, 0.3, 7, 7))
        if p.get("degenerate"):
            # squash a triangle to a sliver: one vertex almost on its opposite edge
            X = mesh.X.copy()
            t = mesh.tris[len(mesh.tris) // 2]
            X[t[0]] = 0.5 * (X[t[1]] + X[t[2]]) + 1e-4 * (X[t[0]] - 0.5 * (X[t[1]] + X[t[2]]))
            mesh.X = X
            mesh.x0 = None
            mesh.__post_init__()
            horizontal(mesh)
        top = np.nonzero(np.isclose(mesh.X[:, 1], 0.3))[0]
        mesh.pinned = top[[np.argmin(mesh.X[top, 0]), np.argmax(mesh.X[top, 0])]].astype(np.int32)
        model = ClothModel(mesh, fab, Scene())
    x0 = mesh.x0.copy()
    if "kick" in p:
        x0 = x0 + np.random.default_rng(1).normal(scale=p["kick"], size=x0.shape)
    tol = 1e-8 if solver == "newton" else 1e-4
    res = get_solver(solver).solve(model, x0, tol=tol, max_iters=4000, max_seconds=8.0)
    assert np.all(np.isfinite(res.x)), "NaN in result"
    assert np.isfinite(res.residual)
    assert res.converged or res.diagnosis, "stopped without saying why"
    assert np.all(res.x[~model.free] == mesh.x0[~model.free])
    # finiteness alone would pass a solver that returns x0 and claims success:
    # the reported residual is the model's, recomputed here from the returned
    # positions, and a converged result meets the tolerance it was given
    r = model.relative_residual(res.x)
    assert r == pytest.approx(res.residual, rel=1e-6, abs=1e-12), (r, res.residual)
    if res.converged:
        assert r <= tol, (r, tol)
    # it went somewhere: the start is not an equilibrium, and the result is not the start
    assert model.relative_residual(x0) > 10 * tol and not np.array_equal(res.x, x0)
    if res.converged:
        assert res.diagnosis == ""


class _Poisoned:
    """Delegates to a ClothModel, forces and energy turn NaN after ``after`` force calls."""

    def __init__(self, model, after):
        self._m = model
        self.calls = 0
        self.after = after

    def __getattr__(self, k):
        return getattr(self._m, k)

    def forces(self, x):
        self.calls += 1
        f = self._m.forces(x)
        return f * np.nan if self.calls > self.after else f

    def energy(self, x, terms=None):
        return np.nan if self.calls > self.after else self._m.energy(x, terms)

    def energy_and_forces(self, x):
        # the adaptive kinetic solver takes both in one pass
        f = self.forces(x)
        return self.energy(x), f


@pytest.mark.parametrize("solver", ["kinetic", "newton", "verlet"])
def test_diverging_model_returns_last_finite_state_with_diagnosis(solver):
    m = cloth_hanging_sheet(7, 7, size=0.3)
    res = get_solver(solver).solve(_Poisoned(m, after=4), m.mesh.x0, tol=1e-10, max_iters=100)
    assert not res.converged
    assert "diverged" in res.diagnosis or "stalled" in res.diagnosis, res.diagnosis
    assert np.all(np.isfinite(res.x))


def test_caps_stop_with_diagnosis():
    m = cloth_hanging_sheet(7, 7, size=0.3)
    r = get_solver("kinetic").solve(m, m.mesh.x0, tol=1e-12, max_iters=5)
    assert not r.converged and "max_iters" in r.diagnosis and r.iterations == 5
    r = get_solver("kinetic").solve(m, m.mesh.x0, tol=1e-12, max_seconds=0.0)
    assert not r.converged and "max_seconds" in r.diagnosis
    r = get_solver("newton").solve(m, m.mesh.x0, tol=1e-14, max_iters=3)
    assert not r.converged and "max_iters" in r.diagnosis


def test_kinetic_stall_diagnosis():
    # a CG capped at one iteration with a tiny window: the solve cannot keep up
    m = cloth_hanging_sheet(7, 7, size=0.3)
    r = get_solver("kinetic", stall_window=5, dt=1e-7).solve(m, m.mesh.x0, tol=1e-12, max_iters=1000)
    assert not r.converged and "stalled" in r.diagnosis, r.diagnosis


def test_callback_can_stop():
    m = cloth_hanging_sheet(7, 7, size=0.3)
    seen = []
    r = get_solver("kinetic").solve(m, m.mesh.x0, callback=lambda i, x, rr: seen.append(rr) or i >= 3)
    assert r.diagnosis == "stopped by callback" and len(seen) == 4


def test_verlet_solves_the_shared_model():
    """Verlet integrates the ClothModel's own forces: its converged drape is that
    model's equilibrium (the residual recomputed here), the one Newton finds."""
    m = cloth_hanging_sheet(10, 10, size=0.5)
    v = get_solver("verlet").solve(m, m.mesh.x0, tol=1e-4, max_seconds=60)
    assert v.converged, v.diagnosis
    assert m.relative_residual(v.x) <= 1e-4 and v.diagnosis == ""
    n = get_solver("newton").solve(m, v.x, tol=1e-9, max_iters=200)
    assert n.converged, n.diagnosis
    dist = np.linalg.norm(v.x - n.x, axis=1).max()
    print(f"verlet {v.iterations} steps {v.wall_time:.2f} s, {1e3 * dist:.3g} mm from Newton at 1e-9")
    # residual 1e-4 of the sheet's weight: well under a millimetre on a 0.5 m sheet
    assert dist < 1e-3, dist


def test_verlet_masses_make_a_unit_step_stable():
    """The fictitious masses bound the stiffness: dt ω_max <= 2 / sqrt(safety) at dt = 1 s,
    checked against the largest eigenvalue of M⁻¹K (not trivially: the bound is tight
    to within the Gershgorin factor)."""
    import scipy.sparse.linalg as sla

    from couture.solvers.verlet import fictitious_masses

    m = cloth_hanging_sheet(8, 8, size=0.4)
    x = m.mesh.x0 + np.random.default_rng(3).normal(scale=0.01, size=m.mesh.x0.shape)
    for safety in (1.0, 2.0):
        mass = fictitious_masses(m, x, safety)
        s = 1.0 / np.sqrt(np.repeat(mass, 3))
        A = sp.diags(s) @ m.stiffness(x) @ sp.diags(s)
        lam = float(sla.eigsh(A, k=1, which="LA", return_eigenvectors=False)[0])
        assert 0.1 * 4.0 / safety < lam <= 4.0 / safety * (1 + 1e-9), (safety, lam)


def test_cascadic_coarse_then_fine():
    coarse = cloth_hanging_sheet(7, 7, size=0.4)
    fine = cloth_hanging_sheet(13, 13, size=0.4)
    P = locate(coarse.mesh.X, coarse.mesh.tris, fine.mesh.X)
    assert np.allclose(P.bary.sum(axis=1), 1) and P.bary.min() > -1e-9
    # prolongation of the rest placement reproduces the fine rest placement (linear map)
    assert np.allclose(P.apply(coarse.mesh.tris, coarse.mesh.x0), fine.mesh.x0, atol=1e-12)
    levels = []
    rc, rf = solve_cascadic(
        coarse,
        fine,
        P,
        get_solver("kinetic"),
        coarse.mesh.x0,
        tol_coarse=1e-4,
        tol_fine=1e-4,
        on_level=lambda lvl, r: levels.append((lvl, r.converged)),
    )
    assert levels == [("coarse", True), ("fine", True)]
    assert np.isfinite(rf.stats["prolongation_residual"])
    # no seams, no body: the polish has nothing to do
    assert rf.stats["prolongation_residual"] == rf.stats["prolongation_residual_raw"]
    scratch = get_solver("kinetic").solve(fine, fine.mesh.x0, tol=1e-4)
    assert rf.iterations < scratch.iterations


# -- polish of the prolongated start (cascadic.polish_prolongated) on a small skirt


@pytest.fixture(scope="module")
def small_skirt():
    """Default skirt meshed at ~330 / ~1160 vertices, coarse drape at 1e-3."""
    from bench.solver import skirt_models
    from schemas.design import Design, Resolution, Sloper

    design = Design(sloper=Sloper(kind="skirt"), resolution=Resolution(coarse_vertices=300, fine_vertices=900))
    makes, meshes, prol, design = skirt_models(design)
    coarse = makes["coarse"]("coarse")
    res = get_solver("kinetic").solve(coarse, meshes["coarse"].x0, tol=1e-3, max_seconds=20)
    assert res.converged, res.diagnosis
    P = Prolongation(*prol)
    return design, meshes, P, coarse, res.x, P.apply(coarse.mesh.tris, res.x)


def _seam_gap(model, x):
    return float(np.linalg.norm(np.einsum("sk,skd->sd", model.seam_w, x[model.seam_stencils]), axis=1).max())


def _max_pen(model, x):
    phi, _ = model.body.phi_grad(x)
    return float((model.contact_offset - phi).max())


def _fine_model(design, mesh):
    from couture.solvers.service import scene_from_design

    return ClothModel(mesh, design.fabric, scene_from_design(design))


def test_polish_prolongated_closes_seams_and_sets_contact_depths(small_skirt):
    design, meshes, P, coarse, xc, x_raw = small_skirt
    fine = _fine_model(design, meshes["fine"])
    assert fine.has_seams and fine.body is not None
    keep = x_raw.copy()
    x = polish_prolongated(fine, x_raw, coarse, xc, P.tri, P.bary)
    assert np.array_equal(x_raw, keep) and x.shape == x_raw.shape and np.isfinite(x).all()
    # (a) seams closed (the plain interpolation gaps by ~1.6 mm)
    assert _seam_gap(fine, x_raw) > 1e-4
    assert _seam_gap(fine, x) < 1e-6
    # (b) no fine vertex deeper than the deepest coarse one (plain: chords cut ~15 mm in)
    deepest = _max_pen(coarse, xc)
    assert _max_pen(fine, x_raw) > deepest
    assert _max_pen(fine, x) <= deepest + 1e-9
    # (c) far closer to fine equilibrium (measured 1.5e4 -> 29)
    r_raw, r = fine.relative_residual(x_raw), fine.relative_residual(x)
    assert 10 * r <= r_raw, (r, r_raw)
    # the cloth stays where it was, up to the fix-ups (mm)
    assert np.linalg.norm(x - x_raw, axis=1).max() < 0.03


def test_polish_prolongated_keeps_pins_and_skips_absent_terms(small_skirt):
    import dataclasses

    from couture.cloth import Scene

    design, meshes, P, coarse, xc, x_raw = small_skirt
    mesh = meshes["fine"]
    phi, _ = coarse.body.phi_grad(x_raw)
    on_seam = np.zeros(mesh.n_vertices, bool)
    on_seam[mesh.seam_emitters] = True
    on_seam[mesh.seam_edges.ravel()] = True
    deep = np.nonzero(~on_seam & (phi < 0.0))[0]
    pins = np.array([mesh.seam_emitters[0], mesh.seam_emitters[len(mesh.seam_emitters) // 2], deep[0], deep[-1]])
    fine = _fine_model(design, dataclasses.replace(mesh, pinned=pins.astype(np.int32)))
    x = polish_prolongated(fine, x_raw, coarse, xc, P.tri, P.bary)
    # (d) pinned vertices (seam emitters, vertices inside the body) do not move; the seams close on them
    assert np.array_equal(x[pins], x_raw[pins])
    assert np.abs(x - x_raw).max() > 1e-4
    assert _seam_gap(fine, x) < 1e-6
    # no body and no seams: nothing to do
    bare = ClothModel(mesh, design.fabric, Scene(body=None, seams=False))
    assert np.array_equal(polish_prolongated(bare, x_raw, bare, xc, P.tri, P.bary), x_raw)
    # seams only: closed, contact left alone (vertices inside the body stay there)
    seams_only = ClothModel(mesh, design.fabric, Scene(body=None, seams=True))
    x = polish_prolongated(seams_only, x_raw, coarse, xc, P.tri, P.bary)
    assert _seam_gap(seams_only, x) < 1e-6
    assert np.array_equal(x[deep], x_raw[deep])


def test_service_warm_start_is_polished_prolongation(small_skirt):
    from couture.solvers.service import SolveService

    design, meshes, P, coarse, xc, x_raw = small_skirt
    svc = SolveService()
    svc.set_design(design)
    svc.set_mesh("coarse", meshes["coarse"], 1)
    svc.set_mesh("fine", meshes["fine"], 1, prolongation=(P.tri, P.bary))
    x, how = svc._warm("fine", xc)
    assert how == "prolongated"
    fine = svc.levels["fine"].model
    assert np.array_equal(x, polish_prolongated(fine, x_raw, svc.levels["coarse"].model, xc, P.tri, P.bary))
    assert _seam_gap(fine, x) < 1e-6 < _seam_gap(fine, x_raw)


def _seam_system(n_side=12, ratio=5000.0):
    mesh = _seamed_tube(n_side, n_side)
    model = ClothModel(mesh, fabric(), Scene(seam_stiffness=ratio * 500 / 2.6))
    x = mesh.x0 + 0.01 * np.random.default_rng(0).normal(size=mesh.x0.shape)
    K = model.stiffness(x)
    order = seam_first_order(model.n, model.free, mesh.seam_emitters, mesh.seam_edges)
    system = ReducedSystem(K, model.mass, model.free, order)
    system.assemble(K, 0.005**2, 1.0)
    return system


def test_ic0_pcg_on_stiff_seams():
    system = _seam_system()
    A = system.matrix()
    b = np.random.default_rng(2).normal(size=system.nr)
    pre = IC0(system)
    pre.factor(system.Ax)
    x, it, rr = pcg(system, b, None, pre, 1e-8, 1000)
    assert rr <= 1e-8 and np.linalg.norm(A @ x - b) <= 1e-7 * np.linalg.norm(b)
    _, it_j, rr_j = pcg(system, b, None, None, 1e-8, 1000)
    assert it < it_j  # the preconditioner earns its keep


@pytest.mark.parametrize("backend", available_backends())
def test_direct_backends(backend):
    system = _seam_system(8)
    A = system.matrix()
    b = np.random.default_rng(3).normal(size=system.nr)
    f = factorize(A, backend)
    assert np.linalg.norm(A @ f.solve(b) - b) <= 1e-8 * np.linalg.norm(b)
    f.refactor(A * 2.0)
    assert np.linalg.norm(2.0 * (A @ f.solve(b)) - b) <= 1e-8 * np.linalg.norm(b)
    # a new sparsity pattern (another mesh) through the same factor object
    B = _seam_system(5).matrix()
    f.refactor(B)
    c = np.random.default_rng(4).normal(size=B.shape[0])
    assert np.linalg.norm(B @ f.solve(c) - c) <= 1e-8 * np.linalg.norm(c)
    # not positive definite: a clear error, and the factor still works afterwards
    Bi = (B - 2.0 * abs(B).max() * sp.identity(B.shape[0])).tocsr()
    with pytest.raises(FactorizationError):
        f.refactor(Bi)
    f.refactor(A)
    assert np.linalg.norm(A @ f.solve(b) - b) <= 1e-8 * np.linalg.norm(b)


@pytest.mark.skipif("pardiso32" not in available_backends(), reason="pypardiso (couture[fast]) not installed")
def test_single_precision_pardiso_refines_to_the_asked_tolerance():
    system = _seam_system(8)
    A = system.matrix()
    b = np.random.default_rng(5).normal(size=system.nr)
    f = factorize(A, "pardiso32")
    raw = f.solve(b, rtol=1.0)  # the single-precision solve as it is (a preconditioner)
    rel = lambda x: np.linalg.norm(A @ x - b) / np.linalg.norm(b)  # noqa: E731
    assert 1e-9 < rel(raw) < 1e-1  # single precision: not a double-accurate solve
    assert rel(f.solve(b, rtol=1e-4)) <= 1e-4
    assert rel(f.solve(b)) <= 1e-10 and f.refinements >= 1 and not f.double_fallback
    # ill-conditioned SPD (Hilbert 9x9, cond ~5e11): single precision cannot
    # reach 1e-10, so the factor switches to double and still answers
    n = 9
    H = sp.csr_matrix(1.0 / (np.arange(n)[:, None] + np.arange(n)[None, :] + 1.0))
    c = np.ones(n)
    g = factorize(H, "pardiso32")
    y = g.solve(c)
    assert g.double_fallback
    assert np.linalg.norm(H @ y - c) <= 1e-8 * np.linalg.norm(c)


def test_auto_backend_is_exact_even_where_approximate_is_allowed():
    """single-precision PARDISO only by name: under MKL 2026.2 its factorization
    is 5-8x slower than double's on a Newton matrix (linalg.resolve_backend)"""
    from couture.solvers.linalg import resolve_backend

    assert resolve_backend("auto") != "pardiso32"
    assert resolve_backend("auto", approximate=True) == resolve_backend("auto")
    with pytest.raises(ValueError, match="unknown backend"):
        resolve_backend("umfpack")


def test_reduced_system_matches_slicing():
    m = cloth_hanging_sheet(6, 6, size=0.3)
    K = m.stiffness(m.mesh.x0 + 0.01)
    order = seam_first_order(m.n, m.free)
    s = ReducedSystem(K, m.mass, m.free, order)
    s.assemble(K, 2.0, 3.0)
    dof = s.dof
    ref = 2.0 * K[dof][:, dof] + 3.0 * sp.diags(np.repeat(m.mass[order], 3))
    assert abs(s.matrix() - ref).max() < 1e-12


def test_surface_guard_refuses_jumps_through_the_body_only():
    """Newton's placement guard (``SurfaceGuard``): a trial state is refused
    when a vertex outside the body's surface ends inside it after moving
    farther than the contact layer is thick; a short move into the layer's
    reach, a move that stays outside and a vertex already inside coming out
    are allowed; without a body (or a model) nothing is refused."""
    from types import SimpleNamespace

    from couture.cloth.body import SphereBody
    from couture.solvers.common import SurfaceGuard

    body = SphereBody(center=np.zeros(3), radius=0.25)
    model = SimpleNamespace(body=body, free=np.ones(3, bool), contact_offset=0.01)
    x = np.array([[0.0, 0.26, 0.0], [0.3, 0.0, 0.0], [0.0, 0.0, -0.2]])  # on the layer, outside, inside
    g = SurfaceGuard(model)
    g.at(x)
    jump = x.copy()
    jump[0] = [0.0, -0.1, 0.0]  # 0.36 m, through the sphere to inside it
    assert g.refuses(jump)
    creep = x.copy()
    creep[0] = [0.0, 0.245, 0.0]  # a 15 mm move ending 5 mm inside
    assert g.refuses(creep)
    short = x.copy()
    short[0] = [0.0, 0.2505, 0.0]  # 9.5 mm, still 0.5 mm outside
    assert not g.refuses(short)
    dip = x.copy()
    dip[0] = [0.0, 0.2495, 0.0]  # 10.5 mm, ending 0.5 mm inside
    assert g.refuses(dip)
    g2 = SurfaceGuard(SimpleNamespace(body=body, free=np.ones(1, bool), contact_offset=0.01))
    g2.at(np.array([[0.0, 0.252, 0.0]]))
    assert not g2.refuses(np.array([[0.0, 0.245, 0.0]]))  # 7 mm, 5 mm inside: left to the contact force
    out = x.copy()
    out[2] = [0.0, 0.0, -0.4]  # the inside vertex comes out, far
    out[1] = [0.5, 0.0, 0.0]  # the outside one moves, stays outside
    assert not g.refuses(out)
    assert not SurfaceGuard(None).refuses(jump)
    assert not SurfaceGuard(SimpleNamespace(body=None, free=np.ones(3, bool))).refuses(jump)

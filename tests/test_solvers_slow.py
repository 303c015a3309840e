"""Heavier solver scenes: SC Fig. 6 stability benchmarks and the SC Fig. 5 sphere drape."""

from __future__ import annotations

import numpy as np
import pytest
from solver_testmodel import cloth_edge_pinned_sheet, cloth_sphere_drape, fabric

from couture.solvers import get_solver


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["membrane_textile", "bending_plate"])
def test_sc_fig6_random_initial_guess(kind):
    """SC Fig. 6: from a random initial guess, kinetic damping reaches residual <= 1e-4.

    Sheets pinned along one edge (y = size), 0.5 m square: a textile (~3k
    triangles, bend 1e-6 N·m) and a plate with 100x its bending (~2k triangles).
    Initial guess: the flat placement plus N(0, 5 cm) noise on every free vertex.
    """
    if kind == "membrane_textile":
        m = cloth_edge_pinned_sheet(35, 35, fab=fabric(stretch=500.0, bend=1e-6))
    else:
        m = cloth_edge_pinned_sheet(28, 28, fab=fabric(stretch=500.0, bend=1e-4))
    n_tri = len(m.mesh.tris)
    assert (2500 if kind == "membrane_textile" else 1700) < n_tri < (3500 if kind == "membrane_textile" else 2500)
    x0 = m.mesh.x0 + np.random.default_rng(7).normal(scale=0.05, size=m.mesh.x0.shape)
    res = get_solver("kinetic").solve(m, x0, tol=1e-4, max_seconds=120)
    assert res.converged, res.diagnosis
    assert res.residual <= 1e-4 and m.relative_residual(res.x) <= 1e-4 * 1.0001
    print(f"{kind}: {n_tri} triangles, {res.iterations} steps, {res.wall_time:.1f} s")


@pytest.mark.slow
def test_sc_fig5_sphere_drape_all_solvers_agree_with_newton():
    """0.6 m square pinned along an edge over a 0.2 m sphere, draped over it (no friction).

    Reference: Newton to residual 1e-9 warm-started from the kinetic drape (1e-6):
    max vertex distance / cloth size < 1e-4 (measured 6e-7).

    A frictionless cloth on a sphere has many equilibria (fold patterns; the
    hanging part can settle turned about the sphere), so solvers started cold
    may find another one, and which one the kinetic path picks depends on its
    step control: cold Newton is checked on its residual and on the centroid
    (within 2% of the size; measured 0.2% and 0.7% against references from
    two kinetic configurations, whose equilibria differed in energy by 0.7%
    and 11%, so energies are not compared). Verlet integrates the same model
    explicitly: checked like cold Newton, its residual recomputed here (measured:
    converged in 10.7k steps, 5.3 to 7 s, centroid 1.4 % off, cold Newton's
    1.2 %; Newton polished from its drape moves it 0.03 mm: an equilibrium).
    """
    m = cloth_sphere_drape(20)
    size = 0.6
    kin = get_solver("kinetic").solve(m, m.mesh.x0, tol=1e-6, max_seconds=120)
    assert kin.converged, kin.diagnosis
    ref = get_solver("newton").solve(m, kin.x, tol=1e-9, max_iters=500)
    assert ref.converged and ref.residual < 1e-8, ref.diagnosis
    newton_cold = get_solver("newton").solve(m, m.mesh.x0, tol=1e-8, max_iters=2000, max_seconds=60)
    ver = get_solver("verlet").solve(m, m.mesh.x0, tol=1e-4, max_seconds=60)
    assert ver.converged, ver.diagnosis
    assert m.relative_residual(ver.x) <= 1e-4
    d_kin = np.linalg.norm(kin.x - ref.x, axis=1).max() / size

    def centroid(x):
        return np.linalg.norm(x.mean(axis=0) - ref.x.mean(axis=0)) / size

    print(
        f"kinetic {d_kin:.2e}; verlet centroid {centroid(ver.x):.2e} ({ver.iterations} steps, {ver.wall_time:.1f} s); "
        f"cold newton {newton_cold.converged} {newton_cold.residual:.2e} centroid {centroid(newton_cold.x):.2e} "
        f"energy {m.energy(newton_cold.x) / m.energy(ref.x) - 1:+.2e}"
    )
    assert d_kin < 1e-4
    assert centroid(ver.x) < 0.02
    assert newton_cold.converged, newton_cold.diagnosis
    assert centroid(newton_cold.x) < 0.02
    # every drape touches the sphere and stays outside it (contact offset 1 cm, penalty)
    for x in (ref.x, newton_cold.x, ver.x):
        phi, _ = m.body.phi_grad(x)
        assert phi.min() > 0.0 and phi.min() < 0.02


@pytest.mark.slow
def test_default_skirt_drapes_from_placement():
    """The garment users drape: the default A-line skirt (Design()) at ~300
    vertices, from the initial placement around the mannequin.

    With friction on (the default scene) kinetic reaches relative residual
    1e-3, including the anchor forces. Agreement with the reference is
    checked without friction (quasi-static friction makes the drape depend on
    the path: measured, Newton from the kinetic drape with the anchors
    refreshed once moved it 13.5 mm): kinetic to 1e-4, Newton warm-started
    there to 5e-5, max vertex distance < 1 mm (the skirt is ~0.6 m long;
    measured 0.1-0.35 mm). Every drape keeps the cloth outside the body (phi > 0)
    and its seams closed to < 1 mm.
    """
    from couture.cloth import ClothModel
    from couture.remesh.service import RemeshService
    from couture.solvers.service import scene_from_design
    from schemas.design import Design, Resolution

    design = Design(resolution=Resolution(coarse_vertices=300, fine_vertices=1200))
    mesh = next(u.mesh for u in RemeshService().set_design(design, 1) if u.level == "coarse")
    scene = scene_from_design(design)
    model = ClothModel(mesh, design.fabric, scene)
    assert "friction" in model.terms and "seams" in model.terms and model.n < 500
    kin_f = get_solver("kinetic").solve(model, mesh.x0, tol=1e-3, max_seconds=60)
    assert kin_f.converged, kin_f.diagnosis
    assert model.relative_residual(kin_f.x) <= 1e-3 * 1.0001

    scene.friction = False
    free = ClothModel(mesh, design.fabric, scene)
    kin = get_solver("kinetic").solve(free, mesh.x0, tol=1e-4, max_seconds=60)
    assert kin.converged, kin.diagnosis
    # Newton stalls at 1.3e-5 (CHOLMOD) to 2.2e-5 (SuperLU, what a fresh install
    # uses): the frictionless skirt is nearly free to spin about the body's
    # axis and the line search crawls along that mode. The reference is asked
    # for 5e-5, still twice tighter than kinetic's 1e-4.
    ref = get_solver("newton").solve(free, kin.x, tol=5e-5, max_seconds=30)
    assert ref.converged, ref.diagnosis
    d = np.linalg.norm(kin.x - ref.x, axis=1).max()
    print(
        f"skirt n={model.n}: kinetic with friction {kin_f.iterations} steps {kin_f.wall_time:.1f} s; "
        f"frictionless kinetic {kin.iterations} steps {kin.wall_time:.1f} s, newton {ref.iterations} its "
        f"{ref.wall_time:.1f} s, max distance {d * 1e3:.2f} mm"
    )
    assert d < 1e-3
    for x in (kin_f.x, kin.x, ref.x):
        assert model.body.phi_grad(x)[0].min() > 0.0
        st, w = model.seam_stencils, model.seam_w
        gap = w[:, 0, None] * x[st[:, 0]] + w[:, 1, None] * x[st[:, 1]] + w[:, 2, None] * x[st[:, 2]]
        assert np.linalg.norm(gap, axis=1).max() < 1e-3

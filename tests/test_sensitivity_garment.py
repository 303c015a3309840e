"""Sensitivity on a garment: the default skirt sloper, meshed by the remesher,
on a frictionless smooth dress form. Ψ comes from the pattern's edit Jacobian
and the remesher's PMVC coordinates; the dress form is rotationally symmetric,
so the skirt's free spin is projected out on the way."""

from __future__ import annotations

import numpy as np
import pytest
from fdcheck import assert_close, central
from sens_testmodel import skirt_design, skirt_on_dress_form
from test_sensitivity_gmls import look_at, perspective, to_px

from couture.pattern.edit import edit_jacobian
from couture.remesh import build_coordinates
from couture.remesh import psi as remesh_psi
from couture.sensitivity import SensitivityFactor, drag_to_param


def solve_gauged(model, x, tol=1e-9, iters=60):
    """Newton with the free spin gauged out (the factor as a linear solver),
    where a plain Newton crawls on the singular stiffness. Far from
    equilibrium: the compression-projected Hessian with an Armijo search on
    the energy; below 1e-5: the exact Hessian, backtracking on the residual
    (energy differences drown in round-off there). Stops at ``tol`` or when
    round-off stalls it (~3e-10 here)."""
    x = np.array(x, dtype=np.float64)
    r = model.relative_residual(x)
    for _ in range(iters):
        if r < tol:
            break
        exact = r < 1e-5
        f = model.forces(x)
        dx = SensitivityFactor(model, x, bend_floor=False, check=False, exact_hessian=exact).solve(f)
        t = 1.0
        if exact:
            while t > 1e-3 and model.relative_residual(x + t * dx) >= r:
                t *= 0.5
        else:
            e0, slope = model.energy(x), float(f.ravel() @ dx.ravel())
            while t > 1e-6 and model.energy(x + t * dx) > e0 - 1e-4 * t * slope:
                t *= 0.5
        rn = model.relative_residual(x + t * dx)
        if exact and (rn >= r or (rn > 0.5 * r and r < 1e-8)):
            x, r = (x + t * dx, rn) if rn < r else (x, r)
            break
        x, r = x + t * dx, rn
    assert r < 1e-9, r
    return x


def equilibrium(model, x_start):
    """The project's Newton gets close (it stalls near 3e-6 on the singular
    spin); the gauged Newton finishes."""
    from couture.solvers import get_solver

    r = get_solver("newton").solve(model, x_start, tol=1e-5, max_seconds=60, max_iters=1000)
    assert r.residual < 1e-3, r.diagnosis
    return solve_gauged(model, r.x)


@pytest.fixture(scope="module")
def skirt():
    design = skirt_design()
    model, res = skirt_on_dress_form(design, vertices=400)
    x = equilibrium(model, res.mesh.x0)
    coords = build_coordinates(res, "pmvc")
    psi_len = remesh_psi(coords, edit_jacobian(design, "param:length"))
    return design, model, res, x, psi_len


def spin_mode(x, axis=(0.0, 0.04)):
    r = x - np.array([axis[0], 0.0, axis[1]])
    s = np.cross([0.0, 1.0, 0.0], r).ravel()
    return s / np.linalg.norm(s)


def test_skirt_length_sensitivity_matches_finite_differences(skirt):
    design, model, res, x, psi = skirt
    assert np.abs(psi[:, :, 1]).max() == 0.0  # a parameter edit: one column
    assert np.abs(psi[:, :, 0]).max() == pytest.approx(1.0, rel=0.05)  # the hem moves 1:1 with length
    f = SensitivityFactor(model, x, bend_floor=False)
    assert f.info.null_modes == 1 and abs(spin_mode(x) @ f.N[:, 0]) > 0.999
    s = f.param_column(psi[:, :, 0])
    assert np.all(np.isfinite(s)) and np.abs(s).max() > 0.5
    X = model.X.copy()
    # The FD step must stay inside the region where x(g) is linear. Every
    # contact vertex here rests inside the contact law's ramp (pen < 0.14 mm <
    # eps = 1 mm, stiffness k pen/eps), one of them only 0.12 um deep (stiffness
    # ~0.9 N/m, far above the softest mode, ~5e-3 N/m): it lifts off at
    # g + ~3e-5, and beyond that the slope of x(g) differs by ~4e-3 relative,
    # so steps of 2e-4..1e-3 measure the mean of two branches (rel. error
    # ~1.6e-3 whatever h). With h = 5e-6 the central difference is O(h²)-exact
    # (measured ~1e-6) and no vertex enters or leaves contact (checked).
    h = 5e-6
    in_contact = model.body.phi_grad(x)[0] < model.contact_offset

    def drape_at(Xp):
        model.set_rest_positions(Xp)
        xp = solve_gauged(model, x, tol=1e-11)  # stops at the round-off floor (~3e-10)
        assert np.array_equal(model.body.phi_grad(xp)[0] < model.contact_offset, in_contact)
        return xp

    fd = central(drape_at, X, psi[:, :, 0], h).ravel()
    model.set_rest_positions(X)
    sp_ = spin_mode(x)
    fd -= sp_ * (sp_ @ fd)
    assert_close(s.ravel(), fd, 1e-3, ord=2, what="skirt length column modulo the spin")


def tug(model, x, psi, drag_px=30.0):
    """Tug the front hem point down by drag_px in a camera at hem height.
    Returns (Δg, world distance of the drag at the hem, hem screen motion after
    applying Δg and re-solving, the DragResult at a waist point)."""
    f = SensitivityFactor(model, x)  # as the node runs it: exact linearisation, floor only if needed
    s = f.param_column(psi[:, :, 0])
    hem = np.nonzero(model.X[:, 1] < model.X[:, 1].min() + 1e-9)[0]
    i = hem[np.argmax(x[hem, 2])]  # the hem vertex facing the camera
    eye = np.array([x[i, 0], x[i, 1], 2.2])
    VP = perspective(0.7, 1.0, 0.1, 10.0) @ look_at(eye, x[i], [0, 1, 0])
    vp = (900, 900)
    drag = np.array([0.0, drag_px])  # down on screen
    r = drag_to_param(s[i], VP, vp, x[i], drag)
    assert not r.ignored
    px_per_m = np.linalg.norm((to_px(VP, vp, x[i] + [0, -1e-4, 0]) - to_px(VP, vp, x[i])) / 1e-4)
    X = model.X.copy()
    model.set_rest_positions(X + r.dg[0] * psi[:, :, 0])
    x_new = equilibrium(model, x + r.dg[0] * s)
    model.set_rest_positions(X)
    moved = to_px(VP, vp, x_new[i]) - to_px(VP, vp, x[i])
    waist = np.argmax(model.X[:, 1])
    # the UI's threshold: a drag that needs more than 1 cm of length per ~1.5 px is ignored
    r_waist = drag_to_param(s[waist], VP, vp, x[waist], drag, min_px_per_unit=150.0)
    return r.dg[0], drag_px / px_per_m, moved, r_waist


def test_3d_tug_of_the_hem_follows_the_pointer(skirt):
    """SC §4.1 / Fig. 1: tug the hem down in the 3D view; Δg = ŝ·Δd/|ŝ|² makes
    the re-solved hem land under the pointer (within 10 % of the drag). On this
    soft fabric (20 N/m) the hem drops ~1.15 m per metre of length (the longer
    skirt is heavier and stretches), so Δg is ~0.85 of the dragged distance."""
    design, model, res, x, psi = skirt
    dg, dragged, moved, r_waist = tug(model, x, psi)
    assert moved[1] == pytest.approx(30.0, rel=0.10) and abs(moved[0]) < 3.0
    assert 0.75 * dragged < dg < 1.0 * dragged
    # a waist point moves ~0.1 m per metre of length (~80 px/m here, the hem
    # ~740 px/m): below the threshold, its drag is ignored
    assert r_waist.ignored and r_waist.dg[0] == 0.0

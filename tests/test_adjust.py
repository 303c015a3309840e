"""Pattern adjustment (Bartle et al. 2016, couture.adjust): the fixed point's
pieces against closed forms, the edits' targets, and the whole adjustment
with its solves answered by solver node processes over the bus."""

from __future__ import annotations

import numpy as np
import pytest
from fdcheck import check_gradient, check_jacobian

from couture.adjust import fixed_point_update, hem_edit, waist_edit
from couture.adjust.geometry import (
    SurfaceDistance,
    edges2,
    flatten,
    frames3,
    hausdorff,
    lscm,
    stretch,
)
from couture.adjust.seams import equalize_seams, max_seam_mismatch
from couture.mesh import grid_sheet


def _sheet(nx=14, ny=10, w=0.6, h=0.4, jitter=0.004):
    return grid_sheet(w, h, nx, ny, jitter=jitter, seed=3)


def _grid(nx=14, ny=10):
    """A structured grid on [0, 1]²: columns are straight lines (generators)."""
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    U = np.column_stack([i.ravel() / (nx - 1), j.ravel() / (ny - 1)])
    v = lambda a, b: a * ny + b  # noqa: E731
    tris = []
    for a in range(nx - 1):
        for b in range(ny - 1):
            tris += [[v(a, b), v(a + 1, b), v(a + 1, b + 1)], [v(a, b), v(a + 1, b + 1), v(a, b + 1)]]
    return U, np.array(tris, np.int32)


def _cylinder(U, R=0.25):
    """Columns of the grid on generators of a cylinder: every quad is a planar
    rectangle, so the mesh is intrinsically flat (discretely developable)."""
    a = 1.2 * U[:, 0]
    return np.column_stack([R * np.sin(a), 0.4 * U[:, 1], R * np.cos(a)])


def _cone(U, k=0.5):
    """Columns on rays of a cone from its apex: every quad is a planar trapezoid."""
    phi = 2.0 * U[:, 0]
    r = 0.3 + 0.4 * U[:, 1]
    return np.column_stack([k * r * np.sin(phi), -r * np.sqrt(1 - k * k), k * r * np.cos(phi)])


@pytest.mark.parametrize("surface", [_cylinder, _cone])
def test_flattening_a_developable_surface_is_isometric(surface):
    U, tris = _grid()
    x = surface(U)
    t3 = frames3(x, tris)
    # the 3D surface is not the plane: its triangles are bent (non-trivial input)
    n = np.cross(x[tris[:, 1]] - x[tris[:, 0]], x[tris[:, 2]] - x[tris[:, 0]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    assert np.ptp(n, axis=0).max() > 0.5
    for X in (lscm(x, tris), flatten(x, tris)):
        S = stretch(t3, edges2(X, tris))
        assert np.abs(S - 1).max() < 1e-6
        assert (np.linalg.det(edges2(X, tris)) > 0).all()  # counter-clockwise, as GarmentMesh wants


def test_flattening_a_sphere_cap_stretches():
    """A doubly curved cap cannot flatten isometrically: the stretch says so."""
    m = _sheet(jitter=0.0)
    X = m.X - m.X.mean(axis=0)
    R = 0.5
    z = np.sqrt(R**2 - (X**2).sum(axis=1))
    x = np.column_stack([X, z])
    S = stretch(frames3(x, m.tris), edges2(flatten(x, m.tris), m.tris))
    assert S.mean() < 1 - 1e-4 and S.mean() > 0.9


def test_stretch_is_eq8_of_the_principal_stretches():
    rng = np.random.default_rng(0)
    T = rng.normal(size=(20, 2, 2))
    T[np.linalg.det(T) < 0] *= np.array([[-1.0, 1.0], [-1.0, 1.0]])
    F = np.array([[1.1, 0.0], [0.0, 0.95]])
    R = np.array([[0.6, -0.8], [0.8, 0.6]])
    S = stretch(R @ F @ T, T)  # target = a rotated, stretched copy
    assert np.allclose(S, 1 - np.hypot(0.1, 0.05), atol=1e-12)
    assert np.allclose(stretch(R @ T, T), 1.0, atol=1e-12)


def test_fixed_point_update_recovers_a_known_per_triangle_deformation():
    """If the simulation deforms every aligned triangle by a fixed A (upper
    triangular, as any map between aligned frames is), one update gives
    pattern triangles that simulate exactly to the target (Bartle eq. 5-7)."""
    rng = np.random.default_rng(1)
    m = 50

    def upper(lo, hi):
        U = np.zeros((m, 2, 2))
        U[:, 0, 0] = rng.uniform(lo, hi, m)
        U[:, 1, 1] = rng.uniform(lo, hi, m)
        U[:, 0, 1] = rng.uniform(-0.3, 0.3, m)
        return U

    def aligned(T):  # a 2D triangle's aligned-frame edge matrix
        x = np.zeros((m * 3, 3))
        x[0::3, :2], x[1::3, :2], x[2::3, :2] = 0.0, T[:, :, 0], T[:, :, 1]
        return frames3(x, np.arange(3 * m).reshape(m, 3))

    A = upper(1.0, 1.2)  # the simulation stretches
    theta = rng.uniform(0, 2 * np.pi, m)
    rot = np.stack([np.stack([np.cos(theta), -np.sin(theta)], -1), np.stack([np.sin(theta), np.cos(theta)], -1)], 1)
    T = rot @ upper(0.02, 0.05)  # pattern triangles, arbitrarily rotated in the plane
    t_target = upper(0.02, 0.05)
    t_k = A @ aligned(T)
    assert np.abs(stretch(t_target, t_k) - 1).max() > 0.05  # not there yet
    T_new = fixed_point_update(T, t_k, t_target)
    assert np.allclose(A @ aligned(T_new), t_target, atol=1e-13)


def test_hausdorff_against_closed_forms():
    m = _sheet(jitter=0.0)
    flat = np.column_stack([m.X, np.zeros(len(m.X))])
    lifted = flat + np.array([0.0, 0.0, 0.013])
    H = hausdorff(flat, lifted, m.tris)
    assert H["hausdorff"] == pytest.approx(0.013, abs=1e-12) and H["mean"] == pytest.approx(0.013, abs=1e-12)
    # a point's distance to the sheet, brute force over every triangle's exact closest point
    rng = np.random.default_rng(2)
    P = np.column_stack([rng.uniform(-0.2, 0.8, 200), rng.uniform(-0.2, 0.6, 200), rng.normal(0, 0.05, 200)])
    _, d, _ = SurfaceDistance(flat, m.tris).closest(P)
    cx = np.clip(P[:, 0], 0, 0.6)
    cy = np.clip(P[:, 1], 0, 0.4)
    ref = np.sqrt((P[:, 0] - cx) ** 2 + (P[:, 1] - cy) ** 2 + P[:, 2] ** 2)
    assert np.allclose(d, ref, atol=1e-9)


# ---------------------------------------------------------------- on a garment


@pytest.fixture(scope="module")
def skirt():
    """The default skirt at 200 coarse vertices, draped in-process (Newton)."""
    from couture.adjust.fixed_point import local_simulator
    from couture.adjust.pipeline import garment_mesh
    from couture.client import load_design

    design = load_design("couture/pattern/examples/default_skirt.json")
    mesh = garment_mesh(design, 200)
    src = local_simulator(mesh, design)(mesh.X, mesh.x0)
    assert src.converged
    return design, mesh, src.x


def test_hem_edit_cuts_the_drape_along_its_own_surface(skirt):
    _, mesh, x = skirt
    t = hem_edit(x, mesh.tris, -0.15)
    assert t.achieved == pytest.approx(-0.15, abs=0.01)  # the hem rose 15 cm: the garment is 15 cm shorter
    keep = x[:, 1] >= t.info["y_fix"]
    assert keep.sum() > 10 and np.array_equal(t.x[keep], x[keep])  # the top part stays
    _, d, _ = SurfaceDistance(x, mesh.tris).closest(t.x)
    assert d.max() < 1e-6  # the target lies on the source surface: fit and flare kept
    assert t.x[:, 1].min() == pytest.approx(x[:, 1].min() + 0.15, abs=0.01)
    with pytest.raises(ValueError, match="non-zero length change"):
        hem_edit(x, mesh.tris, 0.0)


def test_waist_edit_loosens_the_girth_and_fades_out(skirt):
    from couture.adjust.target import section_girth

    _, mesh, x = skirt
    y0 = 0.2
    t = waist_edit(x, mesh.tris, 0.04, y_loop=y0, band=0.1)
    assert section_girth(t.x, mesh.tris, y0) - section_girth(x, mesh.tris, y0) == pytest.approx(0.04, abs=1e-4)
    far = np.abs(x[:, 1] - y0) >= 0.1
    assert far.sum() > 10 and np.array_equal(t.x[far], x[far])


def test_equalized_seams_match(skirt):
    _, mesh, _ = skirt
    rng = np.random.default_rng(4)
    X = mesh.X + rng.normal(scale=0.002, size=mesh.X.shape)
    assert max_seam_mismatch(mesh, mesh.X) < 1e-4  # drafted seams match
    assert max_seam_mismatch(mesh, X) > 1e-3
    Xe = equalize_seams(mesh, X)
    assert max_seam_mismatch(mesh, Xe) < 1e-9
    assert stretch(edges2(Xe, mesh.tris), edges2(X, mesh.tris)).mean() > 0.98  # the rest barely moved


def test_equalized_seams_keep_the_drafted_ease():
    """The shirt's sleeve caps are drafted 43 mm longer than its armholes (the
    ease a set-in sleeve is sewn with): equalizing against the source pattern
    keeps each seam's ratio; equalizing without it would take the ease away."""
    from couture.adjust.pipeline import garment_mesh
    from couture.adjust.seams import seam_ease
    from couture.client import load_design

    mesh = garment_mesh(load_design("couture/pattern/examples/shirt.json"), 250)
    ease = seam_ease(mesh, mesh.X)
    assert max(ease.values()) > 1.1  # a cap 10 % or more longer than its armhole (drafted, not noise)
    rng = np.random.default_rng(5)
    X = mesh.X + rng.normal(scale=0.002, size=mesh.X.shape)
    assert max_seam_mismatch(mesh, X, mesh.X) > 1e-3
    Xe = equalize_seams(mesh, X, reference=mesh.X)
    assert max_seam_mismatch(mesh, Xe, mesh.X) < 1e-9
    for k, r in seam_ease(mesh, Xe).items():
        assert r == pytest.approx(ease[k], rel=1e-9), k
    assert max_seam_mismatch(mesh, equalize_seams(mesh, X)) < 1e-9  # without the reference: equal, ease gone


def test_the_source_start_gives_back_the_source_pattern_where_the_edit_kept_the_drape(skirt):
    """Iteration 0 from the source (start_from_source): the source pattern simulated to the
    source drape is an iterate of the fixed point, so with the source drape as the target
    the update gives the source pattern back (to round-off, from any triangle shapes the
    source drape has), while the flattening of the same drape is centimetres off it (the
    simulation's stretch not undone); for a waist edit, the cloth the edit did not move keeps
    its source pattern to within the embedding's spread of the band's change (< 1 mm here,
    against 20 mm for the flattening)."""
    from couture.adjust.fixed_point import align_panels, start_from_source
    from couture.adjust.geometry import flatten, frames3
    from couture.adjust.pipeline import make_target

    _, mesh, x = skirt
    X0 = start_from_source(mesh, x, frames3(x, mesh.tris))
    assert np.abs(X0 - mesh.X).max() < 1e-9
    Xf = align_panels(flatten(x, mesh.tris), mesh.X, mesh.tris, mesh.tri_panel)
    assert np.abs(Xf - mesh.X).max() > 0.01  # [m]
    t = make_target("waist", 0.04, x, mesh.tris, mesh)
    X1 = start_from_source(mesh, x, frames3(t.x, mesh.tris))
    kept = np.abs(x[:, 1] - t.info["y_loop"]) > 0.2
    assert np.abs(t.x - x)[kept].max() == 0.0
    assert np.abs(X1 - mesh.X)[kept].max() < 2e-3  # [m]
    assert np.abs(X1 - mesh.X)[~kept].max() > np.abs(X1 - mesh.X)[kept].max()  # the band's cloth changed most


@pytest.mark.timeout(120)
def test_adjustment_over_two_solver_processes_matches_one_and_beats_flattening(skirt):
    """Every solve of the adjustment is a `solve` request to solver node
    processes; fanned out over two of them the result is the one of one
    (within what the solver's tolerance allows), and the adjusted pattern's
    drape is closer to the target than the flattening-only one's."""
    from couture.adjust import adjust
    from couture.adjust.pipeline import make_target
    from couture.client import SolveFanout, solver_session

    design, mesh, x = skirt
    target = make_target("hem", -0.15, x, mesh.tris).x
    with solver_session(["newton", "newton"]) as (client, names):
        assert names == ["solver-newton0", "solver-newton1"]
        runs = []
        for use in ([names[0]], names):
            fan = SolveFanout(client, mesh, design, use, max_seconds=30)
            r = adjust(
                mesh, target, fan, x_source=x, max_iters=2, stop_stretch=1.1, stagnation=-1, log=None, start="flatten"
            )
            runs.append((r, dict(fan.counts)))
    (one, c1), (two, c2) = runs
    assert c1 == {names[0]: 3} and c2 == {names[0]: 2, names[1]: 1}
    assert all(h.converged and h.flipped_triangles == 0 for r in (one, two) for h in r.history)
    for a, b in zip(one.history, two.history, strict=True):
        assert abs(a.stretch_mean - b.stretch_mean) < 1e-3
        assert abs(a.hausdorff_m - b.hausdorff_m) < 1e-3
    assert np.abs(one.patterns[-1] - two.patterns[-1]).max() < 1e-3  # [m]
    for r in (one, two):
        flat, best = r.history[0], r.history[r.best]
        assert best.hausdorff_m < 0.7 * flat.hausdorff_m  # 200 vertices: 60 -> 32 mm
        assert best.stretch_mean > flat.stretch_mean + 0.01


@pytest.mark.timeout(120)
def test_couture_adjust_writes_a_cuttable_pattern(tmp_path):
    """The command end to end on a small skirt: its solver node started, the
    adjusted pattern written as DXF that reads back with the panels' outlines,
    seams of equal length, the numbers in adjust.json, and design.json (the
    sloper's options fitted, what the adjust node publishes)."""
    import json

    from couture.adjust.pipeline import garment_mesh
    from couture.adjust.seams import max_seam_mismatch
    from couture.cli import main
    from couture.client import load_design
    from couture.pattern.io import import_dxf

    src = "couture/pattern/examples/default_skirt.json"
    argv = [
        "adjust",
        src,
        "--hem",
        "-0.15",
        "--out",
        str(tmp_path),
        "--vertices",
        "200",
        "--iters",
        "1",
        "--start",
        "flatten",
    ]
    rc = main([*argv, "--gradient-steps", "0"])
    s = json.loads((tmp_path / "adjust.json").read_text())
    # exit 0 only when the goal is met, 3 (outputs written, reasons given) otherwise
    v = s["verdict"]
    assert rc == (0 if v["met"] else 3) and (v["met"] or v["reasons"])
    assert v["solves"] == s["solves"] == 2 and v["hausdorff_pct"] == pytest.approx(s["final"]["hausdorff_pct"])
    assert s["solvers"] == ["solver-newton"] and len(s["iterations"]) == 2
    assert s["start"]["pattern"] == "flatten"
    assert s["adjusted"]["hausdorff_pct"] < s["start"]["hausdorff_pct"]
    pieces = import_dxf(tmp_path / "pattern.dxf")
    z = np.load(tmp_path / "adjust_mesh.npz")
    mesh = garment_mesh(load_design(src), 200)
    assert sorted(pieces) == sorted(mesh.panel_names)
    # the DXF holds the adjusted outlines at true scale (mm in the file, read back in m)
    area = sum(abs(np.linalg.det(edges2(z["X_adjusted"], z["tris"]))) / 2)
    dxf_area = sum(
        0.5
        * abs(
            np.sum(
                p["outline"][:, 0] * np.roll(p["outline"][:, 1], -1)
                - np.roll(p["outline"][:, 0], -1) * p["outline"][:, 1]
            )
        )
        for p in pieces.values()
    )
    assert dxf_area == pytest.approx(area, rel=1e-4)
    assert max_seam_mismatch(mesh, z["X_adjusted"]) < 1e-6
    assert (tmp_path / "adjust.png").stat().st_size > 10_000
    # design.json: the design the UI's adjust node would publish, its options fitted to the adjusted pattern
    fitted = load_design(tmp_path / "design.json")
    fit = s["design_fit"]
    assert fitted.sloper.params["length"] == pytest.approx(fit["options"]["length"][1])
    assert fitted.sloper.params["length"] < fit["options"]["length"][0] - 0.05  # shorter, in its own option
    assert -0.2 < fit["achieved_m"] < -0.08 and fit["drapes"] >= 1


def test_gradient_steps_jacobian_matches_finite_differences():
    """∂x/∂X of the equilibrium (couture.adjust.gradient.jacobian) against
    central differences of Newton solves, on a sheet hanging from two corners."""
    from couture.adjust.gradient import jacobian

    m, design, drape = _hanging_sheet()
    x = drape(m.X, m.x0)
    J = jacobian(m, design, m.X, x)
    rng = np.random.default_rng(5)
    dX = rng.normal(size=m.X.shape)
    dX[m.pinned] = 0.0
    check_jacobian(lambda X: drape(X, x), J, m.X, h=1e-5, rtol=1e-3, dirs=[dX], nontrivial=1e-2, ord=2)


def _hanging_sheet():
    from couture.adjust import with_rest
    from couture.cloth.model import ClothModel
    from couture.solvers import get_solver
    from couture.solvers.service import scene_from_design
    from schemas.design import Design, SceneFlags
    from tests.solver_testmodel import horizontal

    m = horizontal(grid_sheet(0.3, 0.3, 7, 7), center=(0.15, 0.15))
    top = np.nonzero(np.isclose(m.X[:, 1], 0.3))[0]
    m.pinned = top[[np.argmin(m.X[top, 0]), np.argmax(m.X[top, 0])]].astype(np.int32)
    design = Design(scene=SceneFlags(body=False, friction=False, seams=False))
    newton = get_solver("newton")

    def drape(X, x0):
        model = ClothModel(with_rest(m, X), design.fabric, scene_from_design(design))
        r = newton.solve(model, x0, tol=1e-11, max_seconds=30)
        assert r.converged
        return r.x

    return m, design, drape


def test_gradient_step_objective_gradient_matches_finite_differences():
    """∇_X Φ (distance to the target plus the drape's edge-length stretch
    against it, couture.adjust.gradient.gauss_newton_system) against central
    differences of Φ over Newton solves; the stretch term alone too (so a
    wrong sign or scale of ∂ℓ/∂x cannot hide behind the distance term)."""
    from couture.adjust.gradient import edge_length_jacobian, edge_lengths, gauss_newton_system, jacobian, mesh_edges
    from couture.adjust.gradient import objective as phi

    m, design, drape = _hanging_sheet()
    x = drape(m.X, m.x0)
    edges = mesh_edges(m.tris)
    # ∂ℓ/∂x against central differences of the edge lengths
    rng = np.random.default_rng(7)
    v = rng.normal(size=x.shape)
    E = edge_length_jacobian(x, edges)
    check_jacobian(lambda y: edge_lengths(y, edges), E, x, h=1e-6, rtol=1e-6, dirs=[v], what="∂ℓ/∂x")
    # a target the drape does not reach: another rest shape's drape, moved off a little
    X_t = m.X * np.array([1.04, 0.97])
    x_t = drape(X_t, x) + 0.003 * rng.normal(size=x.shape)
    J = jacobian(m, design, m.X, x)
    dX = rng.normal(size=m.X.shape)
    dX[m.pinned] = 0.0
    drapes = {}

    def objective(X, w):
        """Φ of the drape at rest shape X (each drape solved once: Φ is asked for at two weights)."""
        key = X.tobytes()
        if key not in drapes:
            drapes[key] = drape(X, x)
        return phi(drapes[key], x_t, edges, w)

    g = {w: gauss_newton_system(J, x, x_t, edges, w)[1].reshape(m.X.shape) for w in (0.0, 10.0)}
    for w in (0.0, 10.0):
        check_gradient(
            lambda X, w=w: objective(X, w), g[w], m.X, h=1e-5, rtol=1e-4, dirs=[dX], nontrivial=1e-6, what=f"∇Φ w={w}"
        )
    # the stretch term alone: Φ(w=10) - Φ(w=0)
    check_gradient(
        lambda X: objective(X, 10.0) - objective(X, 0.0),
        g[10.0] - g[0.0],
        m.X,
        h=1e-5,
        rtol=1e-4,
        dirs=[dX],
        nontrivial=1e-6,
        what="∇ stretch term",
    )


def test_gradient_step_with_stretch_term_approaches_a_reachable_target_keeping_stretch():
    """A target that is the drape of a known rest shape: one Gauss-Newton step
    (with the stretch term) from the source pattern is kept, brings the drape
    closer (Hausdorff) and its stretch against the target nearer 1, and moves
    the pattern toward the known rest shape."""
    from couture.adjust.fixed_point import Simulated
    from couture.adjust.geometry import frames3, hausdorff, stretch
    from couture.adjust.gradient import gradient_polish

    m, design, drape = _hanging_sheet()
    x = drape(m.X, m.x0)
    X_t = m.X * np.array([1.03, 0.98])
    x_t = drape(X_t, x)

    def simulate(X, warm):
        return Simulated(drape(X, warm), 0.0, True, "newton")

    h0 = hausdorff(x_t, x, m.tris)["hausdorff"]
    s0 = stretch(frames3(x_t, m.tris), frames3(x, m.tris)).mean()
    X1, x1, steps = gradient_polish(m, design, m.X, x, x_t, simulate, steps=1, equalize=False, log=None)
    assert steps[0].accepted and steps[0].solves >= 1
    assert hausdorff(x_t, x1, m.tris)["hausdorff"] < 0.5 * h0
    assert stretch(frames3(x_t, m.tris), frames3(x1, m.tris)).mean() > s0
    # the pattern is only defined up to a rigid motion: compare edge lengths
    from couture.adjust.gradient import edge_lengths, mesh_edges

    e = mesh_edges(m.tris)
    assert (
        np.abs(edge_lengths(X1, e) - edge_lengths(X_t, e)).mean()
        < 0.5 * np.abs(edge_lengths(m.X, e) - edge_lengths(X_t, e)).mean()
    )


def test_verdicts_worst_point_is_where_the_hausdorff_distance_is():
    """couture.adjust.verdict names where the worst point is: on a flat sheet
    and the same sheet with one vertex lifted 5 cm, it is that vertex, 5 cm
    off, found on the lifted surface (the flat one is nowhere 5 cm from it)."""
    from couture.adjust.geometry import hausdorff
    from couture.adjust.verdict import worst_point

    g = np.linspace(0.0, 0.4, 9)
    X, Y = np.meshgrid(g, g)
    x = np.column_stack([X.ravel(), np.zeros(X.size), Y.ravel()])
    idx = np.arange(81).reshape(9, 9)
    tris = np.concatenate(
        [
            np.column_stack([idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()]),
            np.column_stack([idx[:-1, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()]),
        ]
    )
    lifted = x.copy()
    lifted[40, 1] += 0.05  # the middle vertex
    w = worst_point(x, lifted, tris)
    assert w["on"] == "drape" and w["distance"] == pytest.approx(0.05, rel=1e-9)
    assert np.allclose(w["drape_point"], lifted[40]) and w["target_point"][1] == pytest.approx(0.0)
    assert w["distance"] == pytest.approx(hausdorff(x, lifted, tris)["hausdorff"])


def test_a_failed_resimulation_ends_the_updates_and_keeps_the_iterates_before_it(skirt):
    """A solver node that answers a solve with an error (a factorization that
    failed at every shift: the 1.6k shirt, once) ends the fixed point there;
    the pattern returned is the best iterate whose solve gave a drape, and
    the failure is named, not raised (it had stopped `couture bench adjust`)."""
    from couture.adjust.fixed_point import adjust, local_simulator
    from couture.adjust.target import hem_edit

    design, mesh, x = skirt
    target = hem_edit(x, mesh.tris, -0.1)
    real = local_simulator(mesh, design)
    calls = []

    def fails_on_the_third(X, xw):
        calls.append(1)
        if len(calls) == 3:
            raise RuntimeError("solver solver-newton failed: factorization failed")
        return real(X, xw)

    r = adjust(mesh, target.x, fails_on_the_third, x_source=x, max_iters=4, stop_stretch=1.1, stagnation=-1, log=None)
    assert len(r.history) == 3 and "iteration 2" in r.stopped and "diverged" in r.stopped
    assert not r.history[2].converged and r.history[2].hausdorff_m == float("inf")
    assert r.best in (0, 1) and np.isfinite(r.history[r.best].hausdorff_m)
    assert r.X is r.patterns[r.best] and not np.allclose(r.x, target.x)  # a real drape, not the warm start


def test_an_unconverged_source_drape_is_adjusted_and_named_in_the_verdict():
    """An edit of a drape that did not settle is carried on by the command
    and the adjust node alike (at 1.6k vertices dress_waist's Newton source
    drapes stop just above tolerance and still meet the goal), and the
    verdict names the source drape's own diagnosis."""
    from couture.adjust.fixed_point import Simulated
    from couture.adjust.pipeline import run_case
    from couture.adjust.verdict import assess
    from couture.client import load_design

    design = load_design("couture/pattern/examples/default_skirt.json")
    calls = []

    def simulate_for(mesh):
        def unsettled(X, xw):
            calls.append(1)
            return Simulated(np.asarray(xw, float), 5e-3, False, "stub-newton", 1.0, "in body: a vertex 2 mm inside")

        return unsettled

    case = run_case(design, "hem", -0.1, simulate_for, vertices=150, log=None)
    assert len(calls) > 1 and not case.source_solve["converged"]
    verdict = assess(case)
    assert not verdict.met
    assert any("source drape did not converge (in body: a vertex 2 mm inside)" in r for r in verdict.reasons)


def test_the_verdict_tells_a_run_still_closing_in_from_a_stalled_one():
    """closing_in reads the Hausdorff distance over the run's re-simulations in order (start,
    updates, every gradient trial; a refused trial came no closer): falling by more than a
    tenth over the last two says the budget ended it, less says the method had stalled."""
    from types import SimpleNamespace as NS

    from couture.adjust.gradient import GradientStep
    from couture.adjust.verdict import closing_in

    def run(hs, steps=()):
        return NS(result=NS(history=[NS(hausdorff_pct=h) for h in hs]), gradient=list(steps))

    def step(accepted, h, solves):
        return GradientStep(1, accepted, 1.0 if accepted else 0.0, h, 0.99, 0.01, "n", 1.0, solves)

    falling = closing_in(run([3.0, 1.6, 1.4], [step(True, 1.1, 1), step(True, 1.05, 1)]))
    assert falling["falling"] and falling["best_before_pct"] == 1.4 and falling["best_last_pct"] == 1.05
    assert "still closing in when the 5 re-simulations were spent" in falling["text"]
    stalled = closing_in(run([2.0, 1.63, 1.7], [step(False, 1.63, 2)]))
    assert not stalled["falling"] and stalled["best_last_pct"] == float("inf")
    assert stalled["text"] == "stalled: none of the last 2 of 5 re-simulations came closer than 1.63 %"
    slow = closing_in(run([2.0, 1.7, 1.6, 1.55]))  # 1.55 is within a tenth of 1.7
    assert not slow["falling"] and slow["text"].startswith(
        "stalled: the best of the last 2 of 4 re-simulations (1.55 %)"
    )
    assert closing_in(run([2.0, 1.5])) is None

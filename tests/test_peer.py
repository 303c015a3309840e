"""The peer solver (NVIDIA newton's SolverStyle3D, ``get_solver("style3d")``): its drape of
the small strip over the sphere lies close to our Newton drape, reported in our residual
measure; the bench's time-to-same-error ratio picks the fastest of our answers at least as
accurate. newton is in the test extra, so these always run."""

import numpy as np
import pytest

from bench.sensitivity import strip_over_sphere
from bench.tradeoff import LINEAR_FRICTIONLESS, PEER, peer_ratios
from couture.solvers import get_solver


@pytest.fixture(scope="module")
def drapes():
    model = strip_over_sphere(16, 6)
    ours = get_solver("newton").solve(model, model.mesh.x0.copy(), tol=1e-6, max_seconds=60)
    assert ours.converged
    peer = get_solver(PEER).solve(model, model.mesh.x0.copy(), tol=1e-2, max_seconds=120)
    return model, ours, peer


def test_peer_drape_close_to_ours(drapes):
    model, ours, peer = drapes
    assert peer.method == PEER and peer.converged, peer.diagnosis
    assert peer.stats["own_residual"] <= 1e-2
    assert peer.stats["contact"] == "sphere"
    # pins held where we hold them
    pinned = ~model.free
    np.testing.assert_allclose(peer.x[pinned], model.mesh.x0[pinned], atol=1e-6)
    dist = np.linalg.norm(peer.x - ours.x, axis=1)
    start = np.linalg.norm(model.mesh.x0 - ours.x, axis=1)
    rms, rms_start = np.sqrt(np.mean(dist**2)), np.sqrt(np.mean(start**2))
    # its own model (Baraff-Witkin stretch without Poisson coupling, its contact law):
    # within 3 cm RMS of ours, and far closer than the flat start was
    assert rms < 0.03, rms
    assert rms < 0.25 * rms_start, (rms, rms_start)
    # it drapes over the sphere: nothing inside it, hanging below its top
    phi, _ = model.body.phi_grad(peer.x)
    assert phi.min() > 0.0
    assert peer.x[:, 1].min() < 0.0
    # reported in OUR measure, finite, and it is model.relative_residual at its answer
    assert np.isfinite(peer.residual)
    assert peer.residual == pytest.approx(model.relative_residual(peer.x))


def _row(method, label, latency, rms):
    return {"method": method, "label": label, "latency_s": latency, "rms_mm": rms}


def test_peer_ratios_fastest_of_ours_at_least_as_accurate():
    rows = [
        _row("none", "none fine", 0.0, 0.5),  # never ours: the unchanged old drape
        _row(LINEAR_FRICTIONLESS, "nofric fine", 0.001, 0.01),  # diagnostic, not ours
        _row("linear", "linear fine", 0.01, 3.0),
        _row("newton", "newton 1e-02 fine", 0.5, 0.2),
        _row("kinetic", "kinetic 1e-02 fine", 0.2, 0.9),
        _row(PEER, "style3d 1e-01 fine", 4.0, 1.0),
        _row(PEER, "style3d 1e-02 fine", 8.0, 0.1),
    ]
    rows[-2]["build_s"] = 2.0
    a, b = peer_ratios(rows)
    assert a["ours"] == "kinetic 1e-02 fine" and a["ours_over_peer"] == pytest.approx(0.2 / 4.0)
    assert a["ours_over_peer_steps"] == pytest.approx(0.2 / 2.0)
    assert a["solver_ours"] == "kinetic 1e-02 fine"
    assert b["ours"] is None and b["ours_over_peer"] is None and b["solver_ours"] is None
    rows[2]["rms_mm"] = 0.5  # the linear prediction becomes accurate enough: the fastest of ours
    a, _ = peer_ratios(rows)
    assert a["ours"] == "linear fine" and a["solver_ours"] == "kinetic 1e-02 fine"


def test_seams_welded_as_style3d_sews_them():
    from couture.cloth.model import ClothModel
    from couture.pattern.io import EXAMPLES, load_design
    from couture.pattern.validate import validate
    from couture.remesh import mesh_pattern
    from couture.solvers.peer import weld_seams
    from couture.solvers.service import scene_from_design

    design = load_design(EXAMPLES / "default_skirt.json")
    mesh = mesh_pattern(validate(design), 150, level="coarse").mesh
    model = ClothModel(mesh, design.fabric, scene_from_design(design))
    weld, unwelded = weld_seams(model)
    assert weld.shape == (model.n,) and weld.max() + 1 < model.n
    # no triangle loses a corner to a weld
    t = weld[mesh.tris]
    assert np.all((t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2]))
    # each sewn emitter shares its particle with the nearer end of its edge
    a, b = mesh.seam_edges[:, 0], mesh.seam_edges[:, 1]
    near = np.where(mesh.seam_weights <= 0.5, a, b)
    sewn = weld[mesh.seam_emitters] == weld[near]
    assert np.count_nonzero(~sewn) == unwelded
    assert unwelded <= 0.1 * len(mesh.seam_emitters)
    # only seam vertices are welded: the others keep a particle of their own
    seam_vertices = np.unique(np.r_[mesh.seam_emitters, near])
    others = np.setdiff1d(np.arange(model.n), seam_vertices)
    assert len(np.unique(weld[others])) == len(others)


def test_without_newton_clear_error_and_bench_skips(monkeypatch):
    import sys

    from bench import tradeoff
    from couture.solvers import peer

    # newton made unimportable in this process (None in sys.modules: import raises ImportError)
    monkeypatch.setitem(sys.modules, "newton", None)
    assert not peer.available()
    with pytest.raises(ImportError, match=r"couture\[peer\]"):
        get_solver(PEER)
    lines: list[str] = []
    res = tradeoff.run([], "small", (1e-2,), repeats=1, seconds=2.0, log=lines.append, peer_tols=(1e-1,))
    assert any("skipped" in line and "couture[peer]" in line for line in lines), lines
    assert res["peer"]["tols"] == [] and "skipped" in res["peer"]["note"]
    assert PEER not in res["compile_s"]


def _hanging_sheet(grain: float, fabric):
    from couture.cloth.model import ClothModel, Scene
    from couture.mesh import grid_sheet

    mesh = grid_sheet(0.2, 0.3, 7, 9)
    mesh.panel_grain = np.array([grain])
    mesh.x0 = np.column_stack([mesh.X, np.zeros(len(mesh.X))])
    mesh.pinned = np.nonzero(np.isclose(mesh.X[:, 1], 0.3))[0].astype(np.int32)
    return ClothModel(mesh, fabric, Scene())


def test_an_orthotropic_sheet_hangs_along_its_grain_in_the_peer_as_in_ours():
    """A sheet hung from its top edge, its soft warp (10 N/m) or its stiff weft
    (100 N/m) vertical: the peer drops as far as our Newton drape in each (its
    Baraff-Witkin stretch against our StVK: within 10 % at 8 % strain, 2 % at
    1 %), so it reads the grain and the per-triangle stiffness. Before, it
    drapes both as one isotropic 30 N/m membrane (4.4 mm each)."""
    from schemas.design import Fabric

    fabric = Fabric(
        stretch_stiffness=30.0,
        poisson_ratio=0.0,
        bend_stiffness=1e-6,
        area_density=0.3,
        warp_stiffness=10.0,
        weft_stiffness=100.0,
        shear_stiffness=5.0,
    )
    drops = {}
    for name, grain in (("warp", 0.0), ("weft", np.pi / 2)):
        model = _hanging_sheet(grain, fabric)
        assert "membrane_orthotropic" in model.terms
        ours = get_solver("newton").solve(model, model.mesh.x0.copy(), tol=1e-8, max_seconds=60)
        peer = get_solver(PEER).solve(model, model.mesh.x0.copy(), tol=1e-4, max_seconds=120)
        assert ours.converged and peer.converged, peer.diagnosis
        drops[name] = (-ours.x[:, 1].min(), -peer.x[:, 1].min())
    (ours_w, peer_w), (ours_f, peer_f) = drops["warp"], drops["weft"]
    assert peer_w == pytest.approx(ours_w, rel=0.10), drops
    assert peer_f == pytest.approx(ours_f, rel=0.02), drops
    assert 7.0 < peer_w / peer_f < 12.0, drops  # the stiffness ratio is 10


def test_the_peers_bending_edges_take_our_hinges_directional_stiffness():
    """With directional bending every interior edge of the peer gets our
    hinge's stiffness on the same two vertices; boundary edges (one
    triangle: no hinge of ours) keep bend_stiffness."""
    from couture.solvers.peer import peer_edge_stiffness
    from schemas.design import Fabric

    denim = Fabric(
        stretch_stiffness=2000.0,
        poisson_ratio=0.3,
        bend_stiffness=2e-5,
        area_density=0.4,
        bend_warp=3e-5,
        bend_weft=1.5e-5,
        bend_bias=1e-5,
    )
    model = _hanging_sheet(0.4, denim)
    assert model.bend_directional
    st = model.bend_stencils
    # newton's order: opposite 0, opposite 1, then the edge's two vertices; boundary edges have one triangle
    tris = model.mesh.tris
    all_edges = np.sort(np.vstack([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(all_edges, axis=0, return_counts=True)
    rim = uniq[count == 1]
    assert len(rim) > 10
    edges = np.vstack([st[:, [2, 3, 0, 1]], np.column_stack([-np.ones((len(rim), 2), int), rim[:, ::-1]])])
    k = peer_edge_stiffness(model, edges, None)
    np.testing.assert_allclose(k[: len(st)], model.hinge_stiffness(), rtol=0, atol=0)
    assert len(np.unique(np.round(k[: len(st)] / 1e-5, 6))) > 3  # directional: not one value
    assert np.all(k[len(st) :] == model.bend_stiffness)

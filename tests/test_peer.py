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

"""``couture bench fabric``: its references (the heavy elastica, the drape
coefficient and node counter, the support's distance field) against closed
forms, and a quick run of the whole bench on one fabric."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from bench import fabric as fb


def test_elastica_small_deflection_is_the_beam_tip_deflection():
    """lam = q L³/EI small: tip deflection w L⁴ / (8 EI) = lam / 8 in units of L."""
    for lam in (0.01, 0.05):
        _, x, y = fb.elastica(lam)
        assert y[-1] == pytest.approx(lam / 8, rel=2e-3 * max(1.0, lam / 0.01))
        assert x[-1] == pytest.approx(1.0, abs=1e-4)


def test_elastica_at_41_5_degrees_reads_as_peirce_l_equals_2c():
    """ASTM D1388's angle makes the overhang twice the bending length: the
    elastica's lam* = (l/c)³ is 8 (l = 2c) within 0.1 %; Peirce's own
    approximate formula c = l (cos(θ/2) / (8 tan θ))^(1/3) reads 1.96 c there."""
    lam = fb.elastica_lambda()
    assert fb.elastica_tip_angle(lam) == pytest.approx(fb.ASTM_ANGLE, abs=1e-8)
    assert lam ** (1 / 3) == pytest.approx(2.0, rel=1e-3)
    assert fb.peirce_overhang_ratio() == pytest.approx(1.9634, rel=1e-3)
    # a larger angle needs a longer overhang
    assert fb.elastica_lambda(math.radians(50)) > lam


def test_bias_stiffness_of_an_isotropic_sheet_is_its_modulus():
    e, nu = 1000.0, 0.3
    assert fb.bias_stiffness(e, e, e / (2 * (1 + nu)), nu) == pytest.approx(e, rel=1e-12)
    # a woven: soft on the bias, governed by the shear stiffness
    assert fb.bias_stiffness(1500, 900, 40, 0.3) == pytest.approx(151.64, rel=1e-3)


@pytest.mark.parametrize("n", [4, 6, 9])
def test_node_counter_and_drape_coefficient_on_synthetic_drapes(n):
    """A rim r(θ) = R0 + a cos(nθ) has n nodes; its shadow, ½∮r² dθ =
    π R0² + π a²/2, gives the drape coefficient in closed form."""
    R0, a = 0.125, 0.012
    t = np.linspace(0, 2 * np.pi, 240, endpoint=False)
    r = R0 + a * np.cos(n * t + 0.4)
    assert fb.count_nodes(r) == n
    # noise well under the prominence does not add nodes
    rng = np.random.default_rng(1)
    assert fb.count_nodes(r + 0.0005 * rng.standard_normal(len(r))) == n
    area = math.pi * R0**2 + math.pi * a**2 / 2
    a_s, a_d = math.pi * fb.SUPPORT_RADIUS**2, math.pi * fb.DISC_RADIUS**2
    rim = np.column_stack([r * np.cos(t), r * np.sin(t)])
    assert fb.polygon_area(rim) == pytest.approx(area, rel=2e-3)
    assert fb.drape_coefficient(fb.polygon_area(rim)) == pytest.approx((area - a_s) / (a_d - a_s), rel=5e-3)
    theta, rb = fb.rim_profile(np.column_stack([rim[:, 0], np.zeros(len(t)), rim[:, 1]]), np.zeros(3), bins=240)
    assert fb.shadow_area(theta, rb) == pytest.approx(area, rel=0.01)


def test_drape_coefficient_ends():
    """A disc that does not drape has DC 1; one hanging straight down, 0."""
    assert fb.drape_coefficient(math.pi * fb.DISC_RADIUS**2) == pytest.approx(1.0)
    assert fb.drape_coefficient(math.pi * fb.SUPPORT_RADIUS**2) == pytest.approx(0.0)
    assert fb.count_nodes(np.full(100, 0.15)) == 0


def test_support_disc_distance_and_gradient():
    """The rounded support: distance above its flat top and beside its wall
    exact; the gradient against central differences outside the body."""
    s = fb.SupportDisc(top=np.zeros(3), radius=0.09)
    phi, g = s.phi_grad(np.array([[0.02, 0.01, 0.03], [0.0, -0.02, 0.12], [0.0, 0.0, 0.0]]))
    assert phi[0] == pytest.approx(0.01) and np.allclose(g[0], [0, 1, 0])
    assert phi[1] == pytest.approx(0.03) and np.allclose(g[1], [0, 0, 1])
    assert phi[2] == pytest.approx(0.0, abs=1e-12)
    rng = np.random.default_rng(0)
    p = rng.uniform([-0.12, -0.06, -0.12], [0.12, 0.03, 0.12], size=(200, 3))
    phi, g = s.phi_grad(p)
    out = phi > 1e-3
    eps = 1e-6
    for k in range(3):
        d = np.zeros(3)
        d[k] = eps
        fd = (s.phi_grad(p + d)[0] - s.phi_grad(p - d)[0]) / (2 * eps)
        assert np.allclose(fd[out], g[out, k], atol=1e-5)
    assert np.any(out) and np.all(np.abs(np.linalg.norm(g[out], axis=1) - 1) < 1e-9)


def test_quick_bench_run_on_one_fabric(tmp_path):
    """The whole bench, --quick (one fabric, coarse meshes), in under 60 s of CPU:
    the tensile test reproduces the model's stiffness within 1 %, the
    cantilever search lands on 41.5 degrees, the Cusick disc drapes
    (0 < DC < 1, folds counted) and the picture is written."""
    # CPU time of this process: the machine's other jobs do not count
    t = time.process_time()
    assert fb.main(["--quick", "--out", str(tmp_path)]) == 0
    assert time.process_time() - t < 60
    d = json.loads((tmp_path / "fabric.json").read_text())
    assert d["compile_s"] > 0 and d["total_s"] > 0
    assert d["elastica_overhang_per_c"] == pytest.approx(2.0, rel=1e-3)
    for r in d["tensile"]:
        assert r["converged"] and abs(r["error"]) < 0.01, r
    for r in d["cantilever"]:
        assert r["all_converged"]
        assert (
            abs(r["tries"][-1]["angle_deg"] - 41.5) < 0.2
            or abs(r["overhang_m"] / r["tries"][-1]["overhang"] - 1) < 0.01
        )
        # docs/fabrics.md: -1.5 % here at 4 mm (-3.5 % with the imposed-bend BEND_CONSTANT 0.29, -7 % before the clamp fix)
        assert abs(r["error_vs_elastica"]) < 0.03, r
    (c,) = d["cusick"]
    assert c["fabric"] == "cotton_shirting" and 0.0 < c["drape_coefficient"] < 1.0 and c["nodes"] >= 2
    assert (tmp_path / "cusick.png").stat().st_size > 10_000


def test_a_published_drape_coefficient_is_set_beside_the_benchs(tmp_path):
    """Compared on the bench's own 30 cm specimen only (ISO 9073-9's 24 and
    36 cm discs give other coefficients); nothing for a fabric without one."""
    from couture import fabrics
    from tests.test_fabrics import MEASURED_DRAPE, _write

    entry = fabrics.load(_write(tmp_path, MEASURED_DRAPE))["x"]
    out = fb.against_measured({"drape_coefficient": 0.65}, entry)
    assert out["measured_dc"] == 0.62 and out["dc_minus_measured"] == pytest.approx(0.03)
    assert out["measured_dc_source"].startswith("measured:")
    other = fabrics.load(_write(tmp_path, MEASURED_DRAPE.replace("diameter = 0.30", "diameter = 0.24")))["x"]
    assert "dc_minus_measured" not in fb.against_measured({"drape_coefficient": 0.65}, other)
    for name in fabrics.names():
        e = fabrics.entry(name)
        if e.measured_dc is None:
            assert fb.against_measured({"drape_coefficient": 0.65}, e) == {}


def test_the_bench_runs_another_library_and_saves_the_comparison(tmp_path):
    """``--library``: a trial file's fabric on a coarse Cusick disc; its
    published DC and the difference land in the JSON row."""
    from tests.test_fabrics import MEASURED_DRAPE, _write

    lib = _write(tmp_path, MEASURED_DRAPE)
    out = tmp_path / "out"
    assert fb.main(["--quick", "--tests", "cusick", "--library", str(lib), "--fabrics", "x", "--out", str(out)]) == 0
    d = json.loads((out / "fabric.json").read_text())
    (c,) = d["cusick"]
    assert c["fabric"] == "x" and d["library"] == str(lib)
    assert c["measured_dc"] == 0.62 and c["dc_minus_measured"] == pytest.approx(c["drape_coefficient"] - 0.62)
    with pytest.raises(SystemExit, match="unknown fabric 'denim'.*'x'"):
        fb.main(["--quick", "--tests", "cusick", "--library", str(lib), "--fabrics", "denim", "--out", str(out)])

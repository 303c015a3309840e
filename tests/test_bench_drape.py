"""`couture bench drape` on a small skirt: the JSON has every figure the
benchmark promises, finite, and the plots are written (no timing goals here).

The case is draped by kinetic (its stats fill every linear-algebra figure:
factorizations and their time, solves, CG iterations); the sweep by Newton,
the sweep's default solver, about twice as fast here (a 300/900 skirt in 4 s
against 9 s, and each size's process drapes two, its warm-up and its size)."""

from __future__ import annotations

import json
import math

import pytest

from bench import drape as bench

pytestmark = pytest.mark.timeout(300)

SMALL = {
    "schema": "couture/design/v1",
    "design": {"sloper": {"kind": "skirt", "params": {}}, "resolution": {"coarse_vertices": 300, "fine_vertices": 900}},
}


def finite(v) -> bool:
    return isinstance(v, (int, float)) and math.isfinite(v)


def test_bench_drape_writes_finite_figures_and_plots(tmp_path):
    design = tmp_path / "small_skirt.json"
    design.write_text(json.dumps(SMALL))
    out = tmp_path / "results"
    assert (
        bench.main(
            [
                "--designs",
                str(design),
                "--solvers",
                "kinetic",
                "--sizes",
                "600,900",
                "--sweep-design",
                str(design),
                "--sweep-solver",
                "newton",
                "--max-seconds",
                "60",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    rep = json.loads((out / "drape.json").read_text())
    assert rep["bench"] == "drape" and finite(rep["warmup_s"]["kinetic"])
    (case,) = rep["cases"]
    assert (case["design"], case["solver"], case["friction"]) == ("small_skirt", "kinetic", True)
    assert set(case["levels"]) == {"coarse", "fine"}
    for lv in case["levels"].values():
        for key in ("residual", "wall_time_s", "steps_per_s", "starts_at_s"):
            assert finite(lv[key]), (key, lv[key])
        assert lv["vertices"] > 0 and lv["iterations"] > 0 and isinstance(lv["converged"], bool)
        assert lv["solves"] >= lv["iterations"]
        assert lv["history"] and all(finite(t) and finite(r) for t, r in lv["history"])
        la = lv["linear_algebra"]
        assert all(finite(v) for k, v in la.items() if not k.endswith("_from")), la
        assert la["factorizations"] > 0 and la["s_per_factorization"] > 0 and la["s_per_solve"] > 0, la
    assert set(case["time_to_tol_s"]) == {"coarse", "fine", "total"}
    assert all(v is None or finite(v) for v in case["time_to_tol_s"].values())
    assert set(case["goals"]) == {
        "fine_total_s",
        "fine_steps_per_s",
        "coarse_steps_per_s",
        "coarse_iterations",
        "fine_iterations",
    }
    sw = rep["sweep"]
    assert sw["solver"] == "newton" and [r["target"] for r in sw["rows"]] == [600, 900]
    for r in sw["rows"]:
        assert "error" not in r, r
        assert r["vertices"] > 0 and finite(r["peak_rss_mib"]) and r["peak_rss_mib"] > 10
    if sw["fit"] is not None:  # both sizes reached 1e-4
        assert finite(sw["fit"]["exponent"])
    assert (out / "drape_small_skirt.png").stat().st_size > 0
    assert (out / "drape_sweep.png").stat().st_size > 0


def test_convergence_tail_reads_the_order_of_a_residual_sequence():
    """Quadratic (r_{k+1} = r_k^2 / 10) gives order 2, linear (halving) order 1."""
    from bench.drape import convergence_tail

    quad = [1e-1]
    for _ in range(5):
        quad.append(quad[-1] ** 2 / 10)
    tail = convergence_tail([(float(i), r) for i, r in enumerate(quad)])
    assert tail["order"] == pytest.approx(2.0, rel=0.05) and len(tail["ratios"]) == 4
    assert tail["ratios"][-1] == pytest.approx(quad[-1] / quad[-2])
    # the final state recorded twice counts once
    assert convergence_tail([(0.0, r) for r in quad] + [(9.0, quad[-1])])["ratios"] == tail["ratios"]
    lin = convergence_tail([(float(i), 0.5**i) for i in range(8)])
    assert lin["order"] == pytest.approx(1.0) and all(q == pytest.approx(0.5) for q in lin["ratios"])


def test_fabric_variants_are_the_ends_of_the_allowed_ranges():
    """--fabrics stiff / soft set the fabric the solver goals must hold at, within
    the limits every node checks, and leave the rest of the design as it was."""
    from bench.drape import FABRICS, load, with_options
    from couture.pattern.limits import check_simulation_values

    _, design = load("default_skirt")
    stiff = with_options(design, fabric="stiff")
    soft = with_options(design, fabric="soft", friction=False)
    assert stiff.fabric.stretch_stiffness == 2000.0 and stiff.fabric.bend_stiffness == design.fabric.bend_stiffness
    assert (soft.fabric.stretch_stiffness, soft.fabric.bend_stiffness) == (10.0, 1e-8) and not soft.scene.friction
    assert with_options(design, fabric="design") == design and set(FABRICS) == {"design", "stiff", "soft"}
    for d in (stiff, soft):
        check_simulation_values(d)  # raises for a fabric outside its physical range
        assert d.sloper == design.sloper and d.resolution == design.resolution


def test_library_fabric_names_replace_the_design_fabric(monkeypatch, capsys):
    """--fabrics takes a library name besides the variants: the library's fabric
    replaces the design's whole; an unknown name is refused naming the choices,
    a missing library naming the module. (The library is passed as a mapping
    here, so the test holds with or without couture.fabrics on the branch.)"""
    import sys

    from bench.drape import check_fabrics, load, with_options
    from couture.pattern.limits import check_simulation_values
    from schemas.design import Fabric

    denim = Fabric(
        name="denim",
        stretch_stiffness=3160.0,
        warp_stiffness=4000.0,
        weft_stiffness=2500.0,
        shear_stiffness=122.5,
        bend_warp=3e-5,
        bend_weft=1.5e-5,
        bend_bias=2.25e-5,
        area_density=0.4,
    )
    library = {"denim": denim, "chiffon": Fabric(name="chiffon", stretch_stiffness=346.0, area_density=0.04)}
    _, design = load("default_skirt")
    d = with_options(design, fabric="denim", library=library, friction=False)
    assert d.fabric == denim and not d.scene.friction and d.sloper == design.sloper
    check_simulation_values(d)
    assert check_fabrics(["design", "stiff"]) == {}  # variants alone never import the library
    assert check_fabrics(["soft", "chiffon"], library) is library
    with pytest.raises(ValueError, match=r"unknown silk, tweed; choose from design, stiff, soft, chiffon, denim"):
        check_fabrics(["denim", "silk", "tweed"], library)
    monkeypatch.setitem(sys.modules, "couture.fabrics", None)  # as on a checkout without the library
    with pytest.raises(ValueError, match=r"--fabrics denim: not a variant .* couture.fabrics is not importable"):
        check_fabrics(["design", "denim"])
    with pytest.raises(SystemExit) as e:
        bench.main(["--designs", "default_skirt", "--fabrics", "design,denim", "--no-sweep"])
    assert e.value.code == 2 and "couture.fabrics is not importable" in capsys.readouterr().err


def test_an_iteration_is_a_linear_solve_retries_and_continuation_included():
    """Newton's accepted steps undercount its work: a failed factorization, a
    shift retried and every step of a dynamics phase are each a solve."""
    newton = {"factorizations": 14, "factorization_failures": 3, "dynamics_steps": 200}
    assert bench.linear_solves(12, newton) == 14 + 3 + 200
    assert bench.linear_solves(12, {"factorizations": 12}) == 12
    assert bench.linear_solves(500, {"velocity_resets": 7}) == 500  # kinetic: one solve a step

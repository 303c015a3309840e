"""``couture bench extremes`` on a tiny subset: the case list, the outcome
rules, and real worker processes, including a worker that hangs (killed at
its deadline and replaced) and one that dies (a blow-up), so the bench can
tell every outcome apart."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from bench import extremes as ex

GRID = (11, 4)
"""a tiny strip: the worker's cases take a fraction of a second"""


def test_case_list_covers_every_knob_placement_and_edit():
    from couture.pattern.slopers import SKIRT_OPTIONS

    specs = ex.case_list(("skirt", "strip"), ("newton",))
    skirt = [s for s in specs if s["scene"] == "skirt"]
    strip = [s for s in specs if s["scene"] == "strip"]
    for knob, values in ex.SWEEPS.items():
        assert sorted(s["value"] for s in skirt if s.get("knob") == knob) == sorted(values), knob
    assert not [s for s in strip if s.get("knob") == "seam_stiffness_scale"], "the strip has no seams"
    edits = {(s["knob"], s["end"]) for s in skirt if s["kind"] == "edit"}
    assert edits == {(o.name, end) for o in SKIRT_OPTIONS for end in ("min", "max")}
    assert len([s for s in strip if s["kind"] == "placement"]) == len(ex.SEEDS)
    assert len({(s["scene"], s["label"]) for s in specs}) == len(specs), "labels name the cases"
    assert min(ex.SWEEPS["stretch_stiffness"]) == 10 and max(ex.SWEEPS["stretch_stiffness"]) == 1e4
    assert max(ex.SWEEPS["poisson_ratio"]) == 0.49 and min(ex.SWEEPS["seam_stiffness_scale"]) == 1e-2


def _checks(**ok):
    return {k: {"ok": v} for k, v in ok.items()}


def test_outcome_rules():
    good = _checks(residual=True, friction_cone=True, penetration=True, seams=None)
    kw = dict(diagnosis="", finite=True, max_edge_stretch=1.1)
    assert ex.classify(converged=True, checks=good, **kw) == "converged"
    bad_seams = _checks(residual=True, friction_cone=None, penetration=True, seams=False)
    assert ex.classify(converged=True, checks=bad_seams, **kw) == "failed_checks"
    assert ex.classify(converged=False, checks=good, **dict(kw, diagnosis="stalled: ...")) == "diagnosed"
    assert ex.classify(converged=False, checks=good, **kw) == "undiagnosed"
    assert ex.classify(converged=False, checks=None, **dict(kw, finite=False, diagnosis="x")) == "blew_up"
    assert ex.classify(converged=True, checks=good, **dict(kw, max_edge_stretch=50.0)) == "blew_up"
    assert (
        ex.classify(converged=False, checks=None, **dict(kw, max_edge_stretch=float("inf"), diagnosis="x")) == "blew_up"
    )
    assert ex.classify(converged=False, checks=None, error="ValueError", **kw) == "blew_up"
    assert ex.stop_kind("max_seconds 30 reached after 4 steps") == "max_seconds"
    assert ex.stop_kind("stalled: residual best 0.1") == "stalled"


def test_independent_checks_see_an_open_seam_and_a_vertex_inside_the_body():
    """The checks are computed from positions, not taken from the solver: a
    closed drape passes, the same drape with one seam emitter pulled 5 mm
    away or one vertex pushed into the sphere fails that check."""
    spec = {"scene": "strip", "kind": "baseline", "solver": "newton"}
    model, x0, _ = ex.strip_case(spec, GRID)
    from couture.solvers import get_solver

    r = get_solver("newton").solve(model, x0, tol=1e-6, max_seconds=30)
    assert r.converged, r.diagnosis
    c = ex.checks(model, r.x, 1e-6)
    assert c["residual"]["ok"] and c["penetration"]["ok"] and c["friction_cone"]["ok"] is not None
    assert c["seams"]["ok"] is None  # no seams on the strip
    x = r.x.copy()
    free = np.nonzero(model.free)[0]
    x[free[-1]] = [0.0, 0.1, 0.0]  # 0.1 m inside the 0.2 m sphere
    c = ex.checks(model, x, 1e-6)
    assert c["penetration"]["ok"] is False and c["penetration"]["deepest_m"] == pytest.approx(0.11)
    assert c["residual"]["ok"] is False
    assert ex.max_edge_stretch(model, r.x) < 1.5  # whole
    assert ex.max_edge_stretch(model, 20 * r.x) > ex.BLOWUP_STRETCH  # torn apart


def test_skirt_seam_check_measures_the_gap():
    from couture.cloth.model import ClothModel
    from couture.mesh import GarmentMesh
    from couture.solvers.service import scene_from_design
    from schemas.design import Design, SceneFlags

    # two triangles sewn along one edge: emitter 3 sews to the edge (1, 2) at its middle
    mesh = GarmentMesh(
        X=np.array([[0, 0], [1, 0], [0, 1], [1, 1.0]]) * 0.1,
        tris=np.array([[0, 1, 2], [1, 3, 2]], np.int32),
        x0=np.zeros((4, 3)),
        tri_panel=np.zeros(2, np.int32),
        panel_names=["a"],
        seam_emitters=np.array([3], np.int32),
        seam_edges=np.array([[1, 2]], np.int32),
        seam_weights=np.array([0.5]),
        pinned=np.zeros(0, np.int32),
    )
    d = Design(scene=SceneFlags(body=False, friction=False))
    model = ClothModel(mesh, d.fabric, scene_from_design(d))
    x = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0.05, 0.05, 0.004]])
    c = ex.checks(model, x, 1e-4)
    assert c["seams"]["max_gap_m"] == pytest.approx(0.004) and c["seams"]["ok"] is False
    assert c["seams"]["worst_emitter"] == 3 and c["penetration"]["ok"] is None


def test_real_workers_converge_stop_and_refuse(tmp_path):
    """One real worker process runs three strip cases: the default converges
    and passes its checks; an unreachable tolerance stops at a cap with a
    diagnosis; a NaN placement is refused with a diagnosis."""
    base = {"scene": "strip", "kind": "baseline", "limit_s": 10.0, "tol": 1e-4, "label": "baseline"}
    specs = [
        dict(base, solver="newton"),
        dict(base, solver="kinetic", tol=1e-30, limit_s=1.0, label="unreachable tol"),
        dict(base, solver="kinetic", kind="placement", seed="nan", label="placement NaN"),
    ]
    seen = []
    rows = ex.run_cases(specs, jobs=1, strip_grid=GRID, on_row=lambda k, n, r: seen.append((k, n)))
    assert seen == [(1, 3), (2, 3), (3, 3)], "progress per case"
    ok, capped, nan = rows
    assert ok["outcome"] == "converged", ok
    assert ok["checks"]["residual"]["value"] <= 1e-4 and not ok["failed_checks"]
    assert capped["outcome"] == "diagnosed" and capped["stop"] in ("max_seconds", "max_iters", "stalled"), capped
    assert nan["outcome"] == "diagnosed" and "non-finite" in nan["diagnosis"], nan
    summ = ex.summary(rows)
    assert summ["by_solver"]["newton"]["converged"] == 1 and summ["by_solver"]["kinetic"]["diagnosed"] == 2
    assert not summ["by_solver"]["kinetic"]["goals_met"]["converged_fraction"]
    json.dumps(rows)  # rows are plain JSON


FAKE_WORKER = r"""
import json, os, sys, time
for line in sys.stdin:
    spec = json.loads(line)
    print(json.dumps({"event": "solving"}), flush=True)
    if spec["label"] == "hang":
        time.sleep(120)
    if spec["label"] == "die":
        os._exit(3)
    row = dict(spec, outcome="converged", diagnosis="")
    print(json.dumps({"event": "done", "row": row}), flush=True)
"""


def test_a_hung_worker_is_killed_and_replaced_and_a_dead_one_is_a_blow_up():
    """Worker processes that never answer or die: the parent's deadline and its
    EOF check, with a stand-in worker (the real one cannot be made to hang)."""
    base = {"scene": "strip", "solver": "newton", "kind": "baseline", "limit_s": 0.2, "tol": 1e-4}
    specs = [dict(base, label=lb) for lb in ("hang", "after", "die", "last")]
    rows = ex.run_cases(specs, jobs=1, command=[sys.executable, "-c", FAKE_WORKER], hang_margin_s=1.0)
    assert [r["outcome"] for r in rows] == ["hung", "converged", "blew_up", "converged"], rows
    assert "killed" in rows[0]["diagnosis"] and "into its solve" in rows[0]["diagnosis"]
    assert "exit code 3" in rows[2]["diagnosis"]


def test_main_writes_json_and_heat_map(tmp_path, capsys):
    code = ex.main(
        [
            "--scenes",
            "strip",
            "--solvers",
            "newton",
            "--strip-grid",
            "11x4",
            "--quick",
            "--jobs",
            "1",
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 0
    rep = json.loads((tmp_path / "extremes.json").read_text())
    assert (tmp_path / "extremes.png").stat().st_size > 1000
    n = len(rep["cases"])
    assert n == len(ex.case_list(("strip",), ("newton",), quick=True))
    c = rep["summary"]["by_solver"]["newton"]
    assert sum(c[o] for o in ex.OUTCOMES) == n == c["cases"]
    assert {"settings", "goals", "summary", "worst", "cases"} <= set(rep)
    for row in rep["cases"]:
        assert row["outcome"] in ex.OUTCOMES and row["label"]
    out = capsys.readouterr().out
    assert "converged" in out and "goals per solver" in out

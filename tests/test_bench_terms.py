"""``couture bench terms``: only what the scene requires is built, and the rest is inert."""

from __future__ import annotations

import json

from bench import terms


def test_a_sheet_without_a_body_builds_no_contact_and_the_extra_terms_change_nothing(tmp_path):
    """The hanging sheet: its model has no contact and no friction; the same
    scene with the mannequin and friction built reaches an answer that
    balances the required model (the extra terms are inert there), and both
    report what they built."""
    r = terms.sheet_scene()
    assert r["required"]["terms"] == ["membrane", "bending", "gravity"]
    assert r["everything"]["terms"] == ["membrane", "bending", "gravity", "contact", "friction"]
    assert r["required"]["converged"] and r["everything"]["converged"]
    assert r["same_answer"] and r["cross_residual"] <= 10 * terms.TOL
    assert r["required"]["build_s"] > 0 and r["everything"]["total_s"] > 0


def test_bench_terms_cli_writes_json(tmp_path):
    assert terms.main(["--scenes", "sheet", "--out", str(tmp_path)]) == 0
    d = json.loads((tmp_path / "terms.json").read_text())
    assert [s["scene"] for s in d["scenes"]] == ["sheet"] and d["tolerance"] == terms.TOL

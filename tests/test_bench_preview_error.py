"""``couture bench preview_error`` runs on one edit and writes its table."""

from __future__ import annotations

import json
import math

from bench import preview_error


def test_preview_error_bench_writes_estimates_and_true_errors(tmp_path):
    args = ["--garments", "skirt", "--params", "flare", "--steps", "0.002", "--out", str(tmp_path)]
    assert preview_error.main(args) == 0
    out = json.loads((tmp_path / "preview_error.json").read_text())
    rows = out["rows"]
    assert len(rows) == 2 and {r["dg_mm"] for r in rows} == {2.0, -2.0}
    for r in rows:
        assert r["truth_converged"] and r["regularization"] == "none" and r["friction_sticking"] > 0
        assert r["estimate_mm"] > 0 and r["true_error_mm"] > 0
        assert math.isclose(r["ratio"], r["estimate_mm"] / r["true_error_mm"], rel_tol=1e-9)
    assert out["summary"]["edits"] == 2 and 0.0 <= out["summary"]["within_2x_fraction"] <= 1.0

"""`couture bench remesh` runs headless and writes its JSON."""

import json

from bench.remesh import main


def test_bench_remesh_quick(tmp_path):
    assert main(["--fixtures", "--vertices", "1500", "--repeats", "1", "--out", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "remesh.json").read_text())
    assert set(res["patterns"]) == {"tube4", "L+U"}
    for row in res["patterns"].values():
        assert abs(row["vertices"] - 1500) <= 0.15 * 1500
        assert row["remesh_ms"] > 0 and row["psi_global_ms"] > 0 and row["pmvc_precompute_ms"] > 0

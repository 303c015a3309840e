"""Every benchmark takes the same ``--out DIR`` (default bench/results/) and
writes NAME.json there (couture.bench)."""

from __future__ import annotations

import contextlib
import importlib
import io
import json

import pytest

from couture.bench import RESULTS_DIR, write_results
from couture.cli import BENCHES


@pytest.mark.parametrize("name", BENCHES)
def test_every_bench_takes_an_out_folder(name):
    mod = importlib.import_module(f"couture.bench.{name}")
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        mod.main(["--help"])
    assert "--out DIR" in out.getvalue() and str(RESULTS_DIR) in out.getvalue()


def test_write_results_names_the_file_after_the_bench(tmp_path):
    path = write_results(tmp_path / "new", "demo", {"p50_ms": 1.5})
    assert path == tmp_path / "new" / "demo.json" and json.loads(path.read_text()) == {"p50_ms": 1.5}

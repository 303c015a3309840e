"""Every benchmark takes the same ``--out DIR`` (default bench/results/) and
writes NAME.json there; they live in the top-level package ``bench`` beside
the library, and ``couture bench NAME`` finds them from a checkout whatever
the working directory."""

from __future__ import annotations

import contextlib
import importlib
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import bench
from bench import RESULTS_DIR, write_results
from couture.cli import BENCH_DIR, benches, main

ROOT = Path(__file__).resolve().parents[1]


def test_the_benchmarks_sit_beside_the_library():
    assert BENCH_DIR == ROOT / "bench" and Path(bench.__file__).parent == BENCH_DIR
    assert RESULTS_DIR == BENCH_DIR / "results" and RESULTS_DIR.is_dir()
    assert not (ROOT / "couture" / "bench").exists()
    names = benches()
    assert {"adjust", "cloth", "drape", "edit", "tradeoff"} <= set(names) and "__init__" not in names


@pytest.mark.parametrize("name", benches())
def test_every_bench_takes_an_out_folder(name):
    mod = importlib.import_module(f"bench.{name}")
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        mod.main(["--help"])
    assert "--out DIR" in out.getvalue() and str(RESULTS_DIR) in out.getvalue()


def test_write_results_names_the_file_after_the_bench(tmp_path):
    path = write_results(tmp_path / "new", "demo", {"p50_ms": 1.5})
    assert path == tmp_path / "new" / "demo.json" and json.loads(path.read_text()) == {"p50_ms": 1.5}


def test_an_unknown_bench_is_named():
    with pytest.raises(SystemExit), contextlib.redirect_stderr(io.StringIO()) as err:
        main(["bench", "nope"])
    assert "nope" in err.getvalue() and "cloth" in err.getvalue()


EDITABLE_FINDER = """\
# what `pip install -e .` installs: a finder that maps exactly these top-level names to the checkout
import sys
from importlib.machinery import PathFinder


class _Checkout:
    @classmethod
    def find_spec(cls, fullname, path=None, target=None):
        if fullname in ("couture", "nodes", "schemas"):
            return PathFinder.find_spec(fullname, [{root!r}])
        return None


sys.meta_path.insert(0, _Checkout)
"""


def test_couture_bench_runs_from_a_fresh_checkout(tmp_path):
    """As after ``pip install -e .`` in a clone: couture, nodes and schemas
    importable (here through a finder like the editable install's, which maps
    exactly those three, put in by a sitecustomize on PYTHONPATH), bench not,
    the working directory elsewhere; the launcher still finds bench/ and the
    benchmark writes its JSON. The modules keep their paths in this checkout,
    as the editable install leaves them, so numba's cache (keyed by a kernel's
    source path) serves the benchmark: through links to the packages it
    recompiled every kernel, 16 s of CPU a run and a new cache folder each time."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(EDITABLE_FINDER.format(root=str(ROOT)))
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"} | {"PYTHONPATH": str(site)}
    probe = subprocess.run(
        [
            sys.executable,
            "-P",
            "-c",
            "import couture, schemas; print(couture.__file__, schemas.__file__); import bench",
        ],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )
    assert probe.stdout.split() == [str(ROOT / "couture" / "__init__.py"), str(ROOT / "schemas" / "__init__.py")]
    assert probe.returncode != 0 and "No module named 'bench'" in probe.stderr, probe.stderr
    out = tmp_path / "results"
    cmd = [sys.executable, "-P", "-m", "couture", "bench", "cloth", "--vertices", "100", "--repeat", "1"]
    p = subprocess.run(cmd + ["--out", str(out)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=240)
    assert p.returncode == 0, p.stdout + p.stderr
    res = json.loads((out / "cloth.json").read_text())
    assert res["timings"]["vertices"] > 50 and res["timings"]["forces_ms"][0] > 0

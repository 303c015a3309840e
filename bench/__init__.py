"""Benchmarks, run as ``couture bench NAME [--out DIR]`` (or ``python -m bench.NAME``
from the repository root).

They live beside the library, not in it: this package is not installed with
couture and nothing in couture/ imports it (tests/test_layers.py); the
``couture bench`` launcher finds it in the checkout couture was imported from.

One convention for all of them: ``--out`` names a results folder (default
``bench/results/``) and benchmark NAME writes ``NAME.json`` there, with its
plots beside it. The figures live in those files, not in docstrings.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from couture.jsonout import dumps
from couture.solvers import SOLVERS

ROOT = Path(__file__).resolve().parents[1]
"""the repository checkout this package sits in"""

RESULTS_DIR = ROOT / "bench" / "results"
"""default results folder: bench/results/ beside this package, whatever the working directory"""

PEER = "style3d"
"""the peer solver (NVIDIA newton's Style3D): an optional extra (couture[peer]) with its own cloth model"""

OWN_SOLVERS = tuple(name for name in SOLVERS if name != PEER)
"""the registry's solvers on couture's own cloth model: what a benchmark runs by default"""


def add_out_arg(parser: argparse.ArgumentParser) -> None:
    """The shared ``--out DIR`` flag."""
    parser.add_argument(
        "--out",
        type=Path,
        default=RESULTS_DIR,
        metavar="DIR",
        help="results folder: writes NAME.json and its plots there (default: %(default)s)",
    )


def write_results(out_dir: Path | str, name: str, results: Any, **json_kw: Any) -> Path:
    """Write ``results`` as ``<out_dir>/<name>.json`` (the folder is created;
    standard JSON: NaN and infinities as null); returns the path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.json"
    path.write_text(dumps(results, indent=2, **json_kw))
    return path


def source_commit() -> str | None:
    """The source tree's git commit ('+dirty' with local changes), None outside a checkout."""
    try:
        head = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "")


def module_command(name: str, *args: str) -> list[str]:
    """The command that runs benchmark module ``bench.<name>`` in a child process
    (with :func:`child_env`: the child finds this package from any working directory)."""
    return [sys.executable, "-m", f"bench.{name}", *args]


def child_env(env: dict[str, str] | None = None) -> dict[str, str]:
    """``env`` (default: this process's environment) with the checkout first on
    PYTHONPATH, so that ``python -m bench.<name>`` imports this package."""
    out = dict(os.environ if env is None else env)
    out["PYTHONPATH"] = str(ROOT) + (os.pathsep + out["PYTHONPATH"] if out.get("PYTHONPATH") else "")
    return out

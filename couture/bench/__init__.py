"""Benchmarks, run as ``couture bench NAME [--out DIR]``.

One convention for all of them: ``--out`` names a results folder (default
``bench/results/``) and benchmark NAME writes ``NAME.json`` there, with its
plots beside it. The figures live in those files, not in docstrings.
"""

from __future__ import annotations

import argparse
import subprocess
from pathlib import Path
from typing import Any

from couture.jsonout import dumps

RESULTS_DIR = Path("bench/results")
"""default results folder, relative to the working directory"""


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
    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "")

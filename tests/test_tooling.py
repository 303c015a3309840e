"""The project's linters run as tests, so the test command runs them:
``ruff check`` and ``mypy`` (configured in pyproject.toml) must be clean, and
the tree must be as ``ruff format`` writes it. The tools come with the
``test`` extra (``scripts/setup.sh --test``); a missing one fails here."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(*args: str) -> subprocess.CompletedProcess:
    """Run a tool of this interpreter's environment from the repository root."""
    return subprocess.run([sys.executable, "-m", *args], cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_ruff_check_clean():
    r = _run("ruff", "check", "--no-cache", ".")
    assert r.returncode == 0, f"ruff check found problems:\n{r.stdout}{r.stderr}"


def test_ruff_format_clean():
    r = _run("ruff", "format", "--check", "--no-cache", ".")
    assert r.returncode == 0, f"files ruff format would change (run `ruff format`):\n{r.stdout}{r.stderr}"


def test_mypy_clean():
    r = _run("mypy")  # files and strictness from [tool.mypy] in pyproject.toml
    assert r.returncode == 0, f"mypy found type errors:\n{r.stdout}{r.stderr}"

#!/usr/bin/env bash
# Sets up (scripts/setup.sh --test) and runs the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --test
export NUMBA_CACHE_DIR="${NUMBA_CACHE_DIR:-$PWD/.numba_cache}"
# pytest exits 5 when it collected no test: that is a failure here, like any non-zero exit.
# --durations=30: every CI log lists the slowest tests (the whole run should stay well under 30 minutes)
exec .venv/bin/python -m pytest -q -p no:cacheprovider --durations=30 "$@"

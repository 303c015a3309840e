#!/usr/bin/env bash
# Creates .venv and installs couture into it. Idempotent.
#   scripts/setup.sh          runtime only (the demo)
#   scripts/setup.sh --test   plus test tools and Debian's chromium for the browser tests
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "[setup] creating .venv with $($PY --version)"
  "$PY" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
if [ "${1:-}" = "--test" ]; then
  echo "[setup] installing couture with test extras"
  .venv/bin/python -m pip install -q -e '.[test]'
  if [ ! -x /usr/bin/chromium ]; then
    echo "[setup] installing Debian chromium for the browser tests"
    SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null
  fi
else
  echo "[setup] installing couture"
  .venv/bin/python -m pip install -q -e .
fi
# the fast direct solver (MKL PARDISO, ~700 MB): optional, the solvers fall back to SciPy's SuperLU
echo "[setup] installing the PARDISO extra (couture[fast])"
.venv/bin/python -m pip install -q -e '.[fast]' || echo "[setup] couture[fast] unavailable here: direct solves use SciPy SuperLU"
echo "[setup] done: $(.venv/bin/couture --version 2>/dev/null || echo couture installed)"

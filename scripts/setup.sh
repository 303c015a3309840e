#!/usr/bin/env bash
# Creates .venv and installs couture into it. Idempotent.
#   scripts/setup.sh          runtime only (the demo)
#   scripts/setup.sh --test   plus test tools, Debian's chromium for the browser tests and valentina
#                             for the imported-pattern fixtures
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
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  apt_updated=""
  apt_install() {  # Debian packages for the tests, each only where missing
    [ -n "$apt_updated" ] || { $SUDO apt-get update -qq; apt_updated=1; }
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "$@" >/dev/null
  }
  if [ ! -x /usr/bin/chromium ]; then
    echo "[setup] installing Debian chromium for the browser tests"
    apt_install chromium
  fi
  if ! command -v valentina >/dev/null; then
    # tests/test_import_redraft.py exports Valentina's examples to DXF (tests/data/imported/make/make.sh):
    # the program and its Qt 5 libraries, ~25 MB to download beside chromium's (2.5 s here), ~4 s to unpack
    echo "[setup] installing Debian valentina for the imported-pattern fixtures"
    apt_install --no-install-recommends valentina ||
      echo "[setup] apt could not install valentina: make.sh tries again, and its tests say why they skip"
  fi
else
  echo "[setup] installing couture"
  .venv/bin/python -m pip install -q -e .
fi
# the fast direct solver (MKL PARDISO, ~700 MB): optional, the solvers fall back to SciPy's SuperLU
echo "[setup] installing the PARDISO extra (couture[fast])"
.venv/bin/python -m pip install -q -e '.[fast]' || echo "[setup] couture[fast] unavailable here: direct solves use SciPy SuperLU"
echo "[setup] done: $(.venv/bin/couture --version 2>/dev/null || echo couture installed)"

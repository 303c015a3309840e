#!/usr/bin/env bash
# Sets up (scripts/setup.sh) and starts every node plus the web UI on the default mannequin and garment.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/couture up "$@"

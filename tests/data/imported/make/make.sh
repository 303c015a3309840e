#!/usr/bin/env bash
# Drafts the imported-pattern fixtures (tests/data/imported/) with the real tools.
# One script for both uses: the test set-up (tests/test_import_redraft.py) drafts
# into a cache and compares with the committed files; a remake overwrites them.
#   FreeSewing 4.10.2 (npm ci of package.json + package-lock.json beside this
#   script): penelope (skirt), titan (trousers), teagan (a top with sleeves),
#   aaron (a sleeveless top with a neck binding and arm bindings),
#   each drafted for two @freesewing/models measurement sets, rendered to SVG
#   with seam allowances (the importer must tell them apart), and the sets as JSON;
#   Valentina (Debian's package, installed with apt where missing): two examples
#   of its collection exported headless to ASTM (-f 25) and AAMA (-f 16) DXF, and
#   Keiko's measurements as a FreeSewing-named set.
# Usage:
#   make.sh                      remake the committed fixtures (both tools)
#   make.sh PART OUT [WORK]      PART freesewing, valentina or all: the files go to
#                                OUT/freesewing, OUT/valentina; WORK (default: a
#                                fresh temporary folder) holds the npm tree and the
#                                raw exports
#   make.sh lock                 re-pin package-lock.json after editing package.json
# Exit status 75: the package manager refused (the npm registry unreachable or
# refusing a pinned package; apt unable to install valentina); the reason is the
# last line on stderr. Any other failure exits 1.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
PART="${1:-all}"
if [ "$PART" = lock ]; then
  cd "$HERE"
  exec npm install --package-lock-only --no-audit --no-fund
fi
case "$PART" in
  freesewing | valentina | all) ;;
  *)
    echo "make.sh: unknown part '$PART' (freesewing, valentina, all or lock)" >&2
    exit 1
    ;;
esac
if [ "$#" -eq 0 ]; then
  OUT="$(dirname "$HERE")"
else
  OUT="${2:?usage: make.sh [freesewing|valentina|all|lock] OUT [WORK]}"
fi
WORK="${3:-$(mktemp -d)}"
[ -n "${3:-}" ] || trap 'rm -rf "$WORK"' EXIT
mkdir -p "$OUT" "$WORK"
OUT="$(cd "$OUT" && pwd)"
WORK="$(cd "$WORK" && pwd)"

refused() {
  echo "package manager refused: $*" >&2
  exit 75
}

draft_freesewing() {
  mkdir -p "$WORK/fs" "$OUT/freesewing"
  cp "$HERE/package.json" "$HERE/package-lock.json" "$HERE/freesewing.mjs" "$WORK/fs/"
  cd "$WORK/fs"
  # npm ci: exactly the lock file's versions (the registry lacks @freesewing/snapseries@4.10.2:
  # package.json overrides it with 4.10.0)
  if ! npm ci --no-audit --no-fund --loglevel=error >npm.log 2>&1; then
    cat npm.log >&2
    # unreachable (DNS, connection, TLS, proxy) or an HTTP error from the registry: it refused
    if grep -qE 'E(NOTFOUND|AI_AGAIN|CONNREFUSED|CONNRESET|TIMEDOUT|NETUNREACH|HOSTUNREACH|PROXY)|code E[0-9]{3}|network|certificate' npm.log; then
      refused "npm ci from $(npm config get registry): $(grep -m1 -E 'npm (ERR!|error) (code|network|[0-9]{3})' npm.log || tail -1 npm.log)"
    fi
    echo "npm ci failed (see above)" >&2
    exit 1
  fi
  node freesewing.mjs out
  cp out/penelope_*.svg out/titan_*.svg out/teagan_*.svg out/aaron_*.svg out/cis*.json "$OUT/freesewing/"
}

install_valentina() {
  if command -v valentina >/dev/null; then return; fi
  local SUDO=""
  if [ "$(id -u)" != 0 ]; then
    sudo -n true 2>/dev/null || refused "apt: valentina is not installed, and installing it needs root (sudo asks for a password)"
    SUDO="sudo -n"
  fi
  echo "[make] installing Debian's valentina" >&2
  # scripts/setup.sh --test does the same: the library dependencies only (~25 MB)
  if ! { $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends valentina >"$WORK/apt.log" 2>&1; }; then
    cat "$WORK/apt.log" >&2 2>/dev/null || true
    refused "apt-get install valentina: $(tail -1 "$WORK/apt.log" 2>/dev/null || echo 'apt-get update failed')"
  fi
}

draft_valentina() {
  install_valentina
  local C
  C=$(dpkg -L valentina | grep '/collection$' | head -1)
  mkdir -p "$WORK/val" "$OUT/valentina"
  for f in Keiko_skirt TShirt_test; do
    for fmt in 25:astm 16:aama; do
      # it logs every step (DEBUG:...): kept in WORK, shown where it fails
      if ! QT_QPA_PLATFORM=offscreen valentina -b "${f}_${fmt%%:*}" -d "$WORK/val" -f "${fmt%%:*}" \
        --exportOnlyDetails "$C/$f.val" >"$WORK/val/valentina.log" 2>&1; then
        cat "$WORK/val/valentina.log" >&2
        echo "valentina could not export $f.val (-f ${fmt%%:*})" >&2
        exit 1
      fi
      cp "$WORK/val/${f}_${fmt%%:*}_1.dxf" "$OUT/valentina/${f}_${fmt##*:}.dxf"
    done
  done
  # Keiko's measurements (keiko.vit, cm) as a FreeSewing-named set (mm) for `couture import --body`
  python3 - "$C/keiko.vit" "$OUT/valentina/keiko.json" <<'PY'
import json, sys, xml.etree.ElementTree as ET
m = {e.get("name"): float(e.get("value")) for e in ET.parse(sys.argv[1]).iter("m")}
names = {"chest": "bust_circ", "waist": "waist_circ", "seat": "hip_circ"}
out = {k: round(10 * m[v]) for k, v in names.items()}
open(sys.argv[2], "w").write(json.dumps(out) + "\n")
PY
}

case "$PART" in
  freesewing) draft_freesewing ;;
  valentina) draft_valentina ;;
  all)
    (draft_freesewing)
    draft_valentina
    ;;
esac
echo "fixtures written under $OUT"

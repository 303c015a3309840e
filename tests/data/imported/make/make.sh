#!/usr/bin/env bash
# Re-makes the imported-pattern fixtures under tests/data/imported/ from the
# real tools (not run in CI; the files it made are committed):
#   FreeSewing 4.10.2 (npm): penelope (skirt), titan (trousers), aaron (a sleeveless
#   top with a neck binding and arm bindings), teagan (a top
#   with sleeves), each drafted for two @freesewing/models measurement sets,
#   rendered to SVG with seam allowances (the importer must tell them apart);
#   Valentina (Debian's package): two examples of its collection exported headless
#   to ASTM (-f 25) and AAMA (-f 16) DXF.
# Usage: bash tests/data/imported/make/make.sh [SCRATCH_DIR]   (needs node/npm, apt for valentina)
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
DATA="$(dirname "$HERE")"
SCRATCH="${1:-$(mktemp -d)}"
V=4.10.2

mkdir -p "$SCRATCH/fs" && cd "$SCRATCH/fs"
[ -f package.json ] || npm init -y >/dev/null
# the registry mirror used here lacked @freesewing/snapseries@4.10.2: pin the 4.10.0 that exists
node -e 'const f="package.json";const p=require("./"+f);p.overrides={"@freesewing/snapseries":"4.10.0"};require("fs").writeFileSync(f,JSON.stringify(p,null,2))'
npm install --no-audit --no-fund "@freesewing/core@$V" "@freesewing/models@$V" "@freesewing/config@$V" \
  "@freesewing/plugin-transform" "@freesewing/penelope@$V" "@freesewing/titan@$V" "@freesewing/teagan@$V" \
  "@freesewing/aaron@$V"
cp "$HERE/freesewing.mjs" .
node freesewing.mjs out
mkdir -p "$DATA/freesewing"
cp out/penelope_*.svg out/titan_*.svg out/teagan_*.svg out/aaron_*.svg out/cis*.json "$DATA/freesewing/"

if ! command -v valentina >/dev/null; then
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq valentina
fi
C=$(dpkg -L valentina | grep '/collection$' | head -1)
mkdir -p "$SCRATCH/val" "$DATA/valentina"
for f in Keiko_skirt TShirt_test; do
  for fmt in 25:astm 16:aama; do
    QT_QPA_PLATFORM=offscreen valentina -b "${f}_${fmt%%:*}" -d "$SCRATCH/val" -f "${fmt%%:*}" --exportOnlyDetails "$C/$f.val"
    cp "$SCRATCH/val/${f}_${fmt%%:*}_1.dxf" "$DATA/valentina/${f}_${fmt##*:}.dxf"
  done
done
# Keiko's measurements (keiko.vit, cm) as a FreeSewing-named set (mm) for `couture import --body`
python3 - "$C/keiko.vit" "$DATA/valentina/keiko.json" <<'PY'
import json, sys, xml.etree.ElementTree as ET
m = {e.get("name"): float(e.get("value")) for e in ET.parse(sys.argv[1]).iter("m")}
names = {"chest": "bust_circ", "waist": "waist_circ", "seat": "hip_circ"}
out = {k: round(10 * m[v]) for k, v in names.items()}
open(sys.argv[2], "w").write(json.dumps(out) + "\n")
PY
echo "fixtures written under $DATA"

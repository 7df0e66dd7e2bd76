#!/usr/bin/env bash
# Builds dist/m3c2kit_processing.zip, the QGIS plugin as QGIS's plugin manager installs it
# ("Install from ZIP"): the folder m3c2kit_processing at the zip's root, no caches, and its help
# (docs/qgis.md as m3c2kit_processing/help/qgis.md: the algorithms' help link and the "m3c2 not
# found" message point there, so the installed plugin carries what it refers to).
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p dist
out="$PWD/dist/m3c2kit_processing.zip"
stage="$(mktemp -d)"
trap 'rm -rf "$stage"' EXIT
( cd qgis && find m3c2kit_processing -type f ! -path '*/__pycache__/*' ! -name '*.pyc' | LC_ALL=C sort ) > "$stage/files"
( cd qgis && python3 - "$stage/files" "$out.part" <<'PY'
import sys, zipfile
names = [line.strip() for line in open(sys.argv[1]) if line.strip()]
with zipfile.ZipFile(sys.argv[2], "w", zipfile.ZIP_DEFLATED) as z:
    for name in names:
        z.write(name, name)
    z.write("../docs/qgis.md", "m3c2kit_processing/help/qgis.md")
PY
)
mv "$out.part" "$out"
echo "wrote $out"

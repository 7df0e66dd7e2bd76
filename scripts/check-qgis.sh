#!/usr/bin/env bash
# The QGIS Processing provider (qgis/m3c2kit_processing, docs/qgis.md) headless with Debian's QGIS:
# installs qgis, python3-qgis and xvfb when missing (CI runs as root on Debian 12), then runs
# tests/qgis with Debian's python3: qgis_process (enable, list, help, run: the command line's bytes,
# PDAL's names, a missing input, the model), the layer's style and fields, Cancel, the plugin zip.
# m3c2 under test: M3C2_BIN (a folder holding m3c2), default .venv/bin.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! [ -x /usr/bin/qgis_process.bin ] || ! /usr/bin/python3 -c 'import qgis.core' 2>/dev/null; then
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq qgis python3-qgis xvfb xauth >/dev/null
fi
export M3C2_BIN="${M3C2_BIN:-$PWD/.venv/bin}"
[ -x "$M3C2_BIN/m3c2" ] || { echo "check-qgis: no m3c2 in $M3C2_BIN (bash scripts/install.sh first)" >&2; exit 1; }
status=0
for test in tests/qgis/test_plugin_zip.py tests/qgis/test_qgis_process.py tests/qgis/test_in_qgis.py; do
  echo "== $test"
  /usr/bin/python3 "$test" || status=1
done
exit $status

#!/usr/bin/env bash
# README command (1): install m3c2kit (scripts/install.sh: into a virtual environment), then
# measure the change between the 2015 and 2023 airborne lidar surveys of Tommy Thompson Park
# (Toronto) bundled in data/toronto-ttp, with the parameters `m3c2 suggest` proposes for this
# rough urban scene (multi-scale normals, d with >= 30 points).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh
source scripts/python-env.sh
m3c2_activate
mkdir -p out
python -m m3c2kit compare data/toronto-ttp/TTP_15.laz data/toronto-ttp/TTP_23.laz -o out/toronto-m3c2.laz \
  --core-spacing 5 --normal-scale 8:40:8 --projection-scale 10 --max-depth 30 "$@"

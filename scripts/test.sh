#!/usr/bin/env bash
# README command (2): install m3c2 with its test dependencies, then run every test: the C++
# GoogleTest suite (ctest) and the Python suite (pytest).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh --test

cmake -S . -B build/tests -DCMAKE_BUILD_TYPE=Release -DM3C2_BUILD_TESTS=ON >/dev/null
cmake --build build/tests -j"$(nproc)"
ctest --test-dir build/tests --output-on-failure

# Run from outside the source tree so that the installed package, not python/, is tested.
repo=$(pwd)
cd /tmp && python3 -m pytest -q -p no:cacheprovider "$repo/tests/python"

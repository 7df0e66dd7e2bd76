#!/usr/bin/env bash
# The engine as another C++ project uses it: `cmake --install` of a configured build (default
# build/tests, the test build, reused) into build/prefix, then tests/consumer/ (find_package(m3c2))
# configured, built and run against that prefix alone.
# Usage: scripts/check-consumer.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/tests}
prefix=$PWD/build/prefix
rm -rf "$prefix" build/consumer
cmake --install "$build" --prefix "$prefix" >/dev/null
echo "installed into $prefix: $(cd "$prefix" && find . -type f | sort | tr '\n' ' ')"
cmake -S tests/consumer -B build/consumer -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build/consumer -j"$(nproc)" >/dev/null
ctest --test-dir build/consumer --output-on-failure

#!/usr/bin/env bash
# Same bits whatever the build: every result bit of tests/cpp/tools/m3c2_dump (a fixed scene, all
# run modes) from the test build (GCC, OpenMP on 2 threads, compiler builtins, the system's Eigen
# and Boost: build/tests) against a build that changes all of those it can at once: serial
# (M3C2_USE_OPENMP=OFF), the portable fallbacks (M3C2_PORTABLE_FALLBACKS), and, when a Python
# with PyPI's cmeel-eigen and boost-headers is given, those headers (M3C2_HEADERS=PYPI).
# Usage: scripts/check-serial.sh [PYTHON_WITH_PYPI_HEADERS]
set -euo pipefail
cd "$(dirname "$0")/.."
reference=build/tests/tests/cpp/m3c2_dump
[[ -x $reference ]] || { echo "error: build the test build first (scripts/test.sh): no $reference" >&2; exit 1; }
args=(-DCMAKE_BUILD_TYPE=Release -DM3C2_BUILD_TESTS=ON -DM3C2_USE_OPENMP=OFF -DM3C2_PORTABLE_FALLBACKS=ON)
what="serial, portable fallbacks"
if [[ -n "${1:-}" ]]; then
  args+=(-DM3C2_HEADERS=PYPI -DPython3_EXECUTABLE="$1")
  what+=", PyPI's Eigen and Boost"
fi
rm -rf build/serial  # no cached Eigen3_DIR of an earlier configuration
cmake -S . -B build/serial "${args[@]}" | grep -E "^-- m3c2:" | sed 's/^-- /   /'
cmake --build build/serial -j"$(nproc)" --target m3c2_dump >/dev/null
if grep -q -- "-fopenmp" build/serial/compile_commands.json; then echo "error: build/serial uses OpenMP" >&2; exit 1; fi
out=$(mktemp -d)
"$reference" 2 >"$out/openmp-2-threads.txt"
"$reference" 1 >"$out/openmp-1-thread.txt"
build/serial/tests/cpp/m3c2_dump >"$out/serial.txt"
fields=$(wc -l <"$out/serial.txt")
values=$(wc -w <"$out/serial.txt")
status=0
for other in openmp-1-thread serial; do
  if ! cmp -s "$out/openmp-2-threads.txt" "$out/$other.txt"; then
    echo "FAILED: $other differs from the OpenMP build on 2 threads:" >&2
    diff <(tr ' ' '\n' <"$out/openmp-2-threads.txt") <(tr ' ' '\n' <"$out/$other.txt") | head -20 >&2
    status=1
  fi
done
((status == 0)) && echo "same bits: OpenMP build on 2 threads, on 1 thread, and the $what build ($fields result fields, $values values)"
rm -rf "$out"
exit $status

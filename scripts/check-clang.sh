#!/usr/bin/env bash
# The engine and its GoogleTest suite built with clang (and its OpenMP, libomp) instead of GCC,
# then run; its m3c2_dump must give the GCC test build's bits (build/tests), as the strict
# floating-point flags promise (cmake/m3c2_compiler_options.cmake).
set -euo pipefail
cd "$(dirname "$0")/.."
clangxx=$(command -v clang++) || { echo "error: no clang++ (Debian: apt-get install clang libomp-dev)" >&2; exit 1; }
cmake -S . -B build/clang -DCMAKE_CXX_COMPILER="$clangxx" -DCMAKE_BUILD_TYPE=Release -DM3C2_BUILD_TESTS=ON |
  grep -E "^-- (m3c2:|The CXX compiler)" | sed 's/^-- /   /'
if ! cmake --build build/clang -j"$(nproc)" >build/clang.log 2>&1; then
  tail -40 build/clang.log >&2
  exit 1
fi
grep -E "warning:" build/clang.log || true  # shown, not fatal: GCC's -Wall set is the reference
ctest --test-dir build/clang --output-on-failure -j"$(nproc)"
if [[ -x build/tests/tests/cpp/m3c2_dump ]]; then
  if cmp -s <(build/tests/tests/cpp/m3c2_dump 2) <(build/clang/tests/cpp/m3c2_dump 2); then
    echo "same bits: clang and GCC builds (m3c2_dump)"
  else
    echo "FAILED: the clang build's results differ from GCC's (m3c2_dump)" >&2
    exit 1
  fi
fi

#!/usr/bin/env bash
# README command (2): install m3c2 with its test dependencies, then run every test: the C++
# GoogleTest suite (ctest) and the Python suite (pytest).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh --test

cmake -S . -B build/tests -DCMAKE_BUILD_TYPE=Release -DM3C2_BUILD_TESTS=ON >/dev/null
cmake --build build/tests -j"$(nproc)"
ctest --test-dir build/tests --output-on-failure

# The same C++ suite under AddressSanitizer + UndefinedBehaviorSanitizer (docs/errors.md).
cmake -S . -B build/asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DM3C2_BUILD_TESTS=ON -DM3C2_SANITIZE=ON >/dev/null
cmake --build build/asan -j"$(nproc)"
ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
  ctest --test-dir build/asan --output-on-failure -j"$(nproc)"

# Run from outside the source tree so that the installed package, not python/, is tested.
repo=$(pwd)
cd /tmp && python3 -m pytest -q -p no:cacheprovider "$repo/tests/python"

# Bounded fuzzing of the parsers of untrusted input (tests/fuzz/, docs/errors.md): 25 s per
# target with atheris (libFuzzer), or the seeded mutation fuzzer when no atheris wheel installs.
fuzz_dir=$(mktemp -d)
if python3 -c "import atheris" 2>/dev/null || python3 -m pip install --quiet --disable-pip-version-check atheris; then
  for target in ascii_reader ply_reader cc_params cli_args crs_text las_header; do
    (cd "$fuzz_dir" && python3 "$repo/tests/fuzz/fuzz.py" "$target" -max_total_time=25 -print_final_stats=0 \
      >"$fuzz_dir/$target.log" 2>&1) || { tail -50 "$fuzz_dir/$target.log"; exit 1; }
    echo "fuzz $target: $(grep -Eo 'Done [0-9]+ runs' "$fuzz_dir/$target.log" || echo done)"
  done
else
  echo "atheris unavailable: running the seeded mutation fuzzer instead"
  (cd "$fuzz_dir" && python3 "$repo/tests/fuzz/random_fuzz.py" --runs 20000 --seconds 25 --seed 1)
fi
rm -rf "$fuzz_dir"

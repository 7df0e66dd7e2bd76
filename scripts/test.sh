#!/usr/bin/env bash
# README command (2): install m3c2kit with its test dependencies (scripts/install.sh --test: into
# a virtual environment), then run every test: the C++ GoogleTest suite (ctest) with GCC, with
# clang and under AddressSanitizer + UndefinedBehaviorSanitizer; the installed C++ package used
# by another project; the same bits from a serial build; a wheel built from PyPI alone and run in
# a clean venv; the Python suite (pytest); the QGIS provider headless; bounded fuzzing of the parsers.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh --test
source scripts/python-env.sh
m3c2_activate
jobs=$(nproc)
step() { echo; echo "==== $* ($(date -u +%H:%M:%S))"; }

step "C++ tests, GCC, Release"
cmake -S . -B build/tests -DCMAKE_BUILD_TYPE=Release -DM3C2_BUILD_TESTS=ON >/dev/null
cmake --build build/tests -j"$jobs"
ctest --test-dir build/tests --output-on-failure -j"$jobs"

step "C++ sources formatted as the committed .clang-format says"
bash scripts/format.sh --check

step "the installed C++ package from another project (tests/consumer)"
bash scripts/check-consumer.sh build/tests

step "a wheel from PyPI alone, repaired, in a clean venv"
bash scripts/check-wheel.sh "$M3C2_PYTHON"

step "same bits from a serial build with the portable fallbacks and PyPI's headers"
bash scripts/check-serial.sh "$PWD/build/wheel/build-venv/bin/python"

step "C++ tests, clang"
bash scripts/check-clang.sh

# The same C++ suite under AddressSanitizer + UndefinedBehaviorSanitizer (docs/errors.md), with
# the engine's internal invariants checked (M3C2_ASSERT).
step "C++ tests, ASan + UBSan, assertions on"
cmake -S . -B build/asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DM3C2_BUILD_TESTS=ON -DM3C2_SANITIZE=ON -DM3C2_ASSERTS=ON >/dev/null
cmake --build build/asan -j"$jobs"
ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
  ctest --test-dir build/asan --output-on-failure -j"$jobs"

# Run from outside the source tree so that the installed package, not python/, is tested.
step "Python tests"
repo=$(pwd)
(cd /tmp && python -m pytest -q -p no:cacheprovider "$repo/tests/python")

# Windows' and macOS's fallbacks on Linux (python/m3c2kit/base/portable.py, docs/architecture.md
# "Portability"): the layers that use a POSIX path, with every POSIX path off; their fast tests
# only (with their slow ones, a subprocess per case, this pass took 6 minutes in a clean-clone run).
step "Python tests with the POSIX paths off (M3C2_PORTABLE_FALLBACKS=1)"
(cd /tmp && M3C2_PORTABLE_FALLBACKS=1 python -m pytest -q -p no:cacheprovider -m "not slow" \
  "$repo/tests/python/base" "$repo/tests/python/io" "$repo/tests/python/series" "$repo/tests/python/cli" \
  "$repo/tests/python/qgis_runner")

# The QGIS Processing provider headless with Debian's QGIS (docs/qgis.md): installs qgis and
# python3-qgis when missing, then runs tests/qgis against the m3c2 just installed.
step "QGIS provider, headless"
M3C2_BIN="$(dirname "$(command -v m3c2)")" bash scripts/check-qgis.sh

# Bounded fuzzing of the parsers of untrusted input (tests/fuzz/, docs/errors.md): 25 s per
# target with atheris (libFuzzer), or the seeded mutation fuzzer when no atheris wheel installs.
step "fuzzing"
fuzz_dir=$(mktemp -d)
if python -c "import atheris" 2>/dev/null || python -m pip install --quiet --disable-pip-version-check atheris; then
  for target in ascii_reader ply_reader cc_params cli_args crs_text las_header; do
    (cd "$fuzz_dir" && python "$repo/tests/fuzz/fuzz.py" "$target" -max_total_time=25 -print_final_stats=0 \
      >"$fuzz_dir/$target.log" 2>&1) || { tail -50 "$fuzz_dir/$target.log"; exit 1; }
    echo "fuzz $target: $(grep -Eo 'Done [0-9]+ runs' "$fuzz_dir/$target.log" || echo done)"
  done
else
  echo "atheris unavailable: running the seeded mutation fuzzer instead"
  (cd "$fuzz_dir" && python "$repo/tests/fuzz/random_fuzz.py" --runs 20000 --seconds 25 --seed 1)
fi
rm -rf "$fuzz_dir"

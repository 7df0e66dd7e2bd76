#!/usr/bin/env bash
# Installs m3c2kit into a virtual environment (an activated one, else the repository's .venv):
# the C++ compiler, CMake and Python headers from Debian where missing (as root, or through
# sudo), then `pip install .`, which takes Eigen and Boost's headers from PyPI. The build takes
# a minute or two; its progress is shown as it compiles (the full log: build/install.log).
# Usage: scripts/install.sh [--test]   (--test also installs what the test suite needs)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/python-env.sh

test_mode=0
[[ "${1:-}" == "--test" ]] && test_mode=1

packages=(build-essential cmake)
# The C++ test suite (scripts/test.sh) builds the engine with CMake directly, against Debian's
# Eigen, Boost.Math and GoogleTest, also with clang; the report test opens a headless browser.
((test_mode)) && packages+=(libeigen3-dev libboost-math-dev libgtest-dev clang clang-format libomp-dev chromium git)
mapfile -t missing < <(m3c2_missing_debs "${packages[@]}")
m3c2_apt_install "${missing[@]}"

m3c2_activate
# The extension needs the interpreter's own headers (Python.h): Debian keeps them in python3-dev.
if ! python -c 'import os, sys, sysconfig; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))'; then
  v=$(python -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')
  m3c2_apt_install "python$v-dev"
fi

extra=""
((test_mode)) && extra="[test]"
mkdir -p build
log=build/install.log
echo "building and installing m3c2kit$extra into $(python -c 'import sys; print(sys.prefix)') (log: $log)"
# pip -v shows CMake's output; only its progress lines are echoed, shortened.
set +e
python -m pip install -v --disable-pip-version-check ".$extra" 2>&1 | tee "$log" |
  sed -nuE 's#^ *\[ *([0-9]+)%\] Building CXX object .*/([^/]+)\.o$#  [\1%] compiling \2#p;
            s#^ *\[ *([0-9]+)%\] Linking CXX .* ([^ ]+)$#  [\1%] linking \2#p;
            s#^ *Collecting ([^ ]+).*#  collecting \1#p;
            s#^Successfully installed (.*)#  installed \1#p'
status=${PIPESTATUS[0]}
set -e
if ((status != 0)); then
  echo "error: pip install failed (exit $status); the end of $log:" >&2
  tail -40 "$log" >&2
  exit "$status"
fi
echo "m3c2kit installed: $(command -v m3c2)"

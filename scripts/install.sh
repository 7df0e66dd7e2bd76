#!/usr/bin/env bash
# Installs what m3c2 needs on Debian 12 (as root): the C++ toolchain and libraries from Debian,
# then the Python package itself with `pip install .` into the current Python environment.
# Usage: scripts/install.sh [--test]   (--test also installs the test dependencies)
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(build-essential cmake libeigen3-dev libboost-math-dev libgtest-dev)
# The tests also open the HTML report in a headless browser.
[[ "${1:-}" == "--test" ]] && packages+=(chromium)
missing=()
for p in "${packages[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if ((${#missing[@]})); then
  echo "installing Debian packages: ${missing[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

extra=""
[[ "${1:-}" == "--test" ]] && extra="[test]"
python3 -m pip install --quiet --disable-pip-version-check ".${extra}"

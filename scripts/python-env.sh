# Sourced by scripts/install.sh, demo.sh and test.sh: chooses the Python environment they use.
# - An activated virtual environment ($VIRTUAL_ENV) is used as it is.
# - Otherwise the repository's own .venv, created on first use. Debian's python3 refuses pip
#   installs outside a venv (PEP 668, "externally-managed-environment"), and a venv needs no
#   root. It is isolated from the interpreter's own site-packages: with them, on a machine where
#   QGIS is installed, pip kept Debian's python3-matplotlib (built for numpy 1.x) beside a numpy
#   2.x from PyPI, and the report and the test collection failed to import (issue 44). Every
#   package comes from PyPI, built for the numpy pip installs. A .venv made by an earlier version
#   with the system's site-packages is switched to isolated (its pyvenv.cfg) before use.
# After sourcing, `python` is the environment's interpreter and `$M3C2_PYTHON` its path.

m3c2_repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

# Runs apt-get as root, through sudo when needed; says what to run when neither is possible.
m3c2_apt_install() {
  ((${#@})) || return 0
  local run=()
  if ((EUID != 0)); then
    if command -v sudo >/dev/null; then run=(sudo); else
      echo "error: these Debian packages are missing: $*; install them as root: apt-get install $*" >&2
      return 1
    fi
  fi
  if ! command -v apt-get >/dev/null; then
    echo "error: missing $* and no apt-get here: install the equivalent packages of your system" >&2
    return 1
  fi
  echo "installing Debian packages: $*"
  "${run[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${run[@]}" apt-get install -y -qq --no-install-recommends "$@" >/dev/null
}

# Debian packages among "$@" that are not installed (nothing when dpkg is absent).
m3c2_missing_debs() {
  command -v dpkg >/dev/null || return 0
  local p
  for p in "$@"; do dpkg -s "$p" >/dev/null 2>&1 || echo "$p"; done
}

m3c2_activate() {
  if [[ -n "${VIRTUAL_ENV:-}" && -x "$VIRTUAL_ENV/bin/python" ]]; then
    M3C2_PYTHON="$VIRTUAL_ENV/bin/python"
  else
    local venv="$m3c2_repo/.venv"
    if [[ ! -x "$venv/bin/python" ]]; then
      local base
      base=$(command -v python3) || { echo "error: no python3 on PATH (Debian: apt-get install python3)" >&2; return 1; }
      # Debian splits venv's pip bootstrap (ensurepip) into python3-venv.
      if ! "$base" -c "import ensurepip, venv" 2>/dev/null; then
        local v
        v=$("$base" -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')
        m3c2_apt_install "python$v-venv" || return 1
      fi
      echo "creating the virtual environment $venv"
      "$base" -m venv "$venv"
    fi
    if grep -qiE '^include-system-site-packages *= *true' "$venv/pyvenv.cfg" 2>/dev/null; then
      echo "isolating the virtual environment $venv from the system's site-packages (pip installs what it lacks)"
      sed -i -E 's/^(include-system-site-packages *= *)true/\1false/I' "$venv/pyvenv.cfg"
    fi
    # shellcheck disable=SC1091
    source "$venv/bin/activate"
    M3C2_PYTHON="$venv/bin/python"
  fi
  export M3C2_PYTHON
  hash -r
}

#!/usr/bin/env bash
# Checks the README's quick start where it is hardest: a minimal stock Debian 12 (debootstrap)
# with nothing but Debian's own python3. A clean clone of this repository's HEAD is copied into
# a fresh copy of that root and both README commands run there in a chroot, as root:
#   bash scripts/demo.sh      bash scripts/test.sh
# Each one's exit status and the end of its output are printed; the exit status is non-zero
# when either fails. Needs root, debootstrap (apt-get install debootstrap) and the network
# (Debian's mirror, PyPI). Not part of CI: it takes 15-30 minutes. The pristine root is kept in
# $M3C2_DEBIAN_ROOT (default /var/tmp/m3c2-debian12) for later runs; each run uses a new copy.
# Usage: scripts/check-debian12.sh [demo|test ...]   (default: demo test)
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
base=${M3C2_DEBIAN_ROOT:-/var/tmp/m3c2-debian12}
mirror=${M3C2_DEBIAN_MIRROR:-http://deb.debian.org/debian}
commands=("$@")
((${#commands[@]})) || commands=(demo test)

((EUID == 0)) || { echo "error: run as root (debootstrap and chroot need it)" >&2; exit 1; }
command -v debootstrap >/dev/null || DEBIAN_FRONTEND=noninteractive apt-get install -y -qq debootstrap >/dev/null

if [[ ! -e "$base/.complete" ]]; then
  echo "== debootstrap bookworm into $base (once)"
  rm -rf "$base"
  debootstrap --variant=minbase bookworm "$base" "$mirror" >"$base.log" 2>&1 || { tail -20 "$base.log"; exit 1; }
  # "Only its own python3": Debian's interpreter, without pip, venv or headers.
  chroot "$base" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin DEBIAN_FRONTEND=noninteractive \
    apt-get install -y -qq --no-install-recommends python3 >>"$base.log" 2>&1
  chroot "$base" apt-get clean
  touch "$base/.complete"
fi

run=$(mktemp -d /var/tmp/m3c2-debian12-run.XXXXXX)
mounts=()
cleanup() {
  local m
  for ((i = ${#mounts[@]} - 1; i >= 0; i--)); do umount -l "${mounts[i]}" 2>/dev/null || true; done
  rm -rf --one-file-system "$run"
}
trap cleanup EXIT
echo "== fresh copy of the root: $run"
cp -a "$base/." "$run/"
rm -f "$run/.complete"
cp /etc/resolv.conf "$run/etc/resolv.conf"
# A network behind a TLS-intercepting proxy needs its CA for PyPI: the host's bundle is handed to
# pip (PIP_CERT), and that is all of the host that enters the root.
pip_cert=()
if [[ -n "${PIP_CERT:-}" && -f "$PIP_CERT" ]] || [[ -n "$(ls /usr/local/share/ca-certificates/*.crt 2>/dev/null)" ]]; then
  cp "${PIP_CERT:-/etc/ssl/certs/ca-certificates.crt}" "$run/etc/host-network-ca.crt"
  pip_cert=(PIP_CERT=/etc/host-network-ca.crt)
fi
for m in proc sys dev dev/pts dev/shm; do
  mount --bind "/$m" "$run/$m"
  mounts+=("$run/$m")
done
git clone -q --no-local "$repo" "$run/root/m3c2kit"
echo "== clone of $(git -C "$repo" rev-parse --short HEAD) in /root/m3c2kit; python3 there: $(chroot "$run" python3 --version)"
chroot "$run" python3 -m pip --version >/dev/null 2>&1 && echo "   (pip is present)" || echo "   (no pip, no venv: stock)"

failed=0
for c in "${commands[@]}"; do
  log="$run.$c.log"
  echo "== bash scripts/$c.sh"
  start=$(date +%s)
  set +e
  chroot "$run" /usr/bin/env -i HOME=/root TERM=dumb LANG=C.UTF-8 "${pip_cert[@]}" \
    PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin bash -c "cd /root/m3c2kit && bash scripts/$c.sh" >"$log" 2>&1
  status=$?
  set -e
  echo "   exit status $status after $(($(date +%s) - start)) s; last lines (full log: $log):"
  tail -15 "$log" | sed 's/^/   | /'
  ((status == 0)) || failed=1
done
exit $failed

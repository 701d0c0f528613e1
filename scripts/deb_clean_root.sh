#!/usr/bin/env bash
# The package on a machine that never built anything: makes a clean Debian 12 root with
# debootstrap (minbase, from Debian's mirror), installs build/pmlsm_*.deb there with apt (which
# fetches the runtime libraries it depends on, no compiler), and runs the main job's first run
# inside it (launch/sim.yaml on the pulse scenario, the installed launcher finding the installed
# nodes and configs), comparing its trace with the source tree's run of the same launch.
#   ./scripts/deb_clean_root.sh [ROOT_DIR]    (as root; default /var/tmp/pmlsm_clean_root)
# Make the package first: (cd build && cpack). A root kept from an earlier run is reused
# (delete the folder for a fresh one). Prints each phase's time and the package's sizes.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PROGRESS_NAME=deb_clean_root
. "$root/scripts/progress.sh"
target="${1:-/var/tmp/pmlsm_clean_root}"
mirror="${PMLSM_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
domain="${PMLSM_DOMAIN:-89}"
deb=$(ls -t "$root"/build/pmlsm_*.deb 2>/dev/null | head -n 1 || true)
[ -n "$deb" ] || { echo "deb_clean_root: no build/pmlsm_*.deb: run (cd build && cpack) first" >&2; exit 2; }
[ "$(id -u)" -eq 0 ] || { echo "deb_clean_root: needs root (debootstrap, chroot)" >&2; exit 2; }
command -v debootstrap >/dev/null || { echo "deb_clean_root: debootstrap missing (scripts/install_deps.sh)" >&2; exit 2; }
echo "deb_clean_root: $(basename "$deb"): $(du -k "$deb" | cut -f1) KiB, installed size $(dpkg-deb -f "$deb" Installed-Size) KiB" >&2
echo "deb_clean_root: depends on: $(dpkg-deb -f "$deb" Depends)" >&2

if [ ! -x "$target/usr/bin/apt-get" ]; then
  phase_start "debootstrap" "a minimal Debian 12 root in $target from $mirror (about 2 minutes)"
  rm -rf "$target"
  debootstrap --variant=minbase bookworm "$target" "$mirror" >"$target.debootstrap.log" 2>&1 ||
    { tail -n 20 "$target.debootstrap.log" >&2; echo "deb_clean_root: debootstrap failed" >&2; exit 1; }
  phase_end
fi
mounted=()
cleanup() { for m in "${mounted[@]}"; do umount -l "$m" 2>/dev/null || true; done; }
trap cleanup EXIT
for m in proc dev dev/shm; do
  mountpoint -q "$target/$m" || { mount --bind "/$m" "$target/$m"; mounted=("$target/$m" "${mounted[@]}"); }
done
cp /etc/resolv.conf "$target/etc/resolv.conf"
cp "$deb" "$target/tmp/"
in_root() { chroot "$target" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root "$@"; }

phase_start "install" "apt install ./$(basename "$deb") in the clean root"
in_root apt-get update -qq
in_root apt-get install -y -q --no-install-recommends "/tmp/$(basename "$deb")" >"$target.install.log" 2>&1 ||
  { tail -n 30 "$target.install.log" >&2; echo "deb_clean_root: apt install failed" >&2; exit 1; }
phase_end
if in_root sh -c 'command -v c++ || command -v g++ || command -v cmake'; then
  echo "deb_clean_root: a compiler or cmake is in the clean root: the package pulled it in" >&2
  exit 1
fi

phase_start "run" "launcher launch/sim.yaml (pulse, lockstep) with the installed programs, domain $domain"
in_root sh -c "rm -rf /var/tmp/run && mkdir -p /var/tmp/run && cd /var/tmp/run &&
  ln -s /usr/share/pmlsm/configs configs && ln -s /usr/share/pmlsm/launch launch &&
  launcher launch/sim.yaml --arg out=out --arg domain=$domain" >"$target.run.log" 2>&1 ||
  { cat "$target.run.log" >&2; echo "deb_clean_root: the run in the clean root failed" >&2; exit 1; }
phase_end
sed -n 's/^\[evaluator\] //p' "$target.run.log"
# The same launch from the source tree: the traces must be byte-identical.
cd "$root"
ref=$(mktemp -d)
"$root/build/bin/launcher" "$root/launch/sim.yaml" --arg out="$ref" --arg domain="$domain" >/dev/null 2>&1
if cmp -s "$ref/pulse_pi.csv" "$target/var/tmp/run/out/pulse_pi.csv"; then
  echo "deb_clean_root: ok: the installed package's trace equals the source tree's (cmp of pulse_pi.csv)"
else
  echo "deb_clean_root: the traces differ ($ref/pulse_pi.csv, $target/var/tmp/run/out/pulse_pi.csv)" >&2
  exit 1
fi
rm -rf "$ref"

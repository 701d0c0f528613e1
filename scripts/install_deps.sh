#!/usr/bin/env bash
# Installs the Debian 12 packages the project builds and runs with (as root,
# or with sudo when it is there). Safe to run again: apt-get skips what is there.
set -euo pipefail

packages=(
  build-essential cmake           # compiler, make, cpp (fastddsgen preprocesses IDL with it)
  libfastrtps-dev libfastcdr-dev  # Fast DDS 2.9 and its CDR serialisation
  fastddsgen                      # IDL -> C++ type support, run at build time
  libeigen3-dev                   # matrices, matrix exponential (exact discretisation)
  libyaml-cpp-dev                 # configs/*.yaml
  libcli11-dev                    # command lines
  libboost-context-dev            # fibers: a container's components on one chain thread
  libgtest-dev                    # unit tests
  libpagmo-dev                    # jDE and CMA-ES, compared with the paper's DE/rand/1/bin
  libbenchmark-dev                # speed benchmark
  gnuplot-nox                     # PNG plots of the traces
  iproute2                        # network namespaces for the two-host test
  nftables                        # bench/rig_split_bench.sh: packets dropped at random and a partition between namespaces
  fastdds-tools                   # `fastdds discovery`: the Discovery Server for networks without multicast
  cyclonedds-tools                # ddsperf: the DDS latency floor the distributed benchmark compares with
  rt-tests                        # cyclictest: the machine's timer wake-up floor, in the same benchmark
  cyclonedds-dev                  # a Cyclone DDS subscriber built from our IDL: interoperation on the wire
  libzstd-dev liblz4-dev          # MCAP chunk compression (zstd default, lz4 for speed)
  zlib1g-dev                      # crc32 of MCAP chunks and summary (pmlsm_mcap)
  libwebsocketpp-dev libasio-dev  # the Foxglove WebSocket bridge (the server library the official bridge uses)
  nlohmann-json3-dev              # the Foxglove protocol's JSON control messages
  libmsgpack-cxx-dev              # CAN frames on the UDP-multicast virtual bus (python-can's udp_multicast format)
  python3-can                     # python-can 4.1: an independent peer on that bus in the tests
  libssl-dev openssl              # DDS Security keystores: keys, certificates, S/MIME signatures (pmlsm security)
  clang-14 libclang-rt-14-dev     # libFuzzer and the sanitizer runtimes for clang (bench/fuzz.sh)
  clang-format-14                 # the code style (.clang-format; the test code_format)
  clang-tidy-14                   # function size and naming (.clang-tidy; scripts/tidy.sh, run by CI)
  debootstrap                     # a clean Debian root for the package test (scripts/deb_clean_root.sh)
  tshark                          # Wireshark's EtherCAT dissectors judge our frames in the tests
)
# Node.js and npm run the third-party readers in the tests (@mcap/core, @foxglove/* from npm).
# Debian's packages only where none is installed: a machine may carry its own Node.js with npm.
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  packages+=(nodejs npm)
fi

sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install_deps: run as root or install sudo" >&2; exit 1; }
  sudo_cmd=(sudo)
fi

export DEBIAN_FRONTEND=noninteractive
PROGRESS_NAME=install_deps
. "$(dirname "${BASH_SOURCE[0]}")/progress.sh"

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#packages[@]} Debian packages present" >&2
else
  log=/tmp/pmlsm_install_deps.$$.log
  phase_start "apt-get update" "${#missing[@]} of ${#packages[@]} packages missing: ${missing[*]}"
  "${sudo_cmd[@]}" apt-get update -qq
  phase_end
  # The packages with their dependencies: what apt will fetch and set up (a fresh Debian 12: about
  # 680 packages, 5 minutes in a fresh root here).
  count=$("${sudo_cmd[@]}" apt-get install -s --no-install-recommends "${missing[@]}" | grep -c '^Inst ' || true)
  phase_start "packages" "installing ${#missing[@]}, $count with their dependencies (apt-get; log $log)"
  # APT::Status-Fd: apt's machine-readable progress ("dlstatus:i:PERCENT:text" while downloading,
  # "pmstatus:pkg:PERCENT:text" while unpacking and configuring), turned into percent lines.
  if ! "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends -o APT::Status-Fd=3 "${missing[@]}" \
       3>&1 1>"$log" 2>&1 |
       line_awk -F: '/^dlstatus:/ { print int($3) "\tdownloading: " $4; fflush() }
                /^pmstatus:/ { print int($3) "\tinstalling: " $4; fflush() }' | percent_filter "packages"; then
    tail -n 30 "$log" >&2
    echo "install_deps: apt-get install failed (log above, all of it in $log)" >&2
    exit 1
  fi
  phase_end
  rm -f "$log"
fi

# The npm packages of the third-party reader tests, at the versions in tests/node/package-lock.json.
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
phase_start "npm packages" "tests/node (npm ci, versions of tests/node/package-lock.json)"
# --ignore-scripts: none of them needs one, and soem-node (SOEM, the independent EtherCAT master of
# the tests: GPL, run as a separate program, never linked) ships its built addon.
(cd "$root/tests/node" && npm ci --ignore-scripts --no-audit --no-fund --loglevel=error >/dev/null)
phase_end

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
  libgtest-dev                    # unit tests
  libpagmo-dev                    # jDE and CMA-ES, compared with the paper's DE/rand/1/bin
  libbenchmark-dev                # speed benchmark
  gnuplot-nox                     # PNG plots of the traces
  iproute2                        # network namespaces for the two-host test
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
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${packages[@]}" >/dev/null
echo "install_deps: ${#packages[@]} packages present"

# The npm packages of the third-party reader tests, at the versions in tests/node/package-lock.json.
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
(cd "$root/tests/node" && npm ci --no-audit --no-fund --loglevel=error >/dev/null)
echo "install_deps: npm packages of tests/node present"

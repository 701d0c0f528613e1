#!/usr/bin/env bash
# The main job: installs what is missing, builds, runs the simulated system on
# the paper's two scenarios, prints the results table and plots the traces.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/install_deps.sh"
"$root/scripts/build.sh" >/dev/null
cd "$root"
./build/bin/closed_loop \
  -c configs/system.yaml \
  -s configs/scenarios/pulse.yaml -s configs/scenarios/free_vibration.yaml \
  -o out "$@"
gnuplot -e "outdir='out'" scripts/plot_traces.gp
echo "plots: out/pulse.png out/free_vibration.png"

#!/usr/bin/env bash
# The virtual rig (drive_bridge + virtual_drive on the UDP multicast CAN bus) next to the
# simulated drive (plant_sim), in one run, so the machine's mood is shared:
#   - lockstep, PI, pulse: real-time factor of plant_sim (launch/sim.yaml) and of the rig
#     (launch/virtual_rig.yaml), and their ratio;
#   - realtime, drive + controller only, alternating plant_sim and the rig RUNS times each:
#     chain latency feedback -> command p50 / p99 (what the drive node measures), the rig's SYNC
#     intervals at the drive (mean, std, p99, max), deadline misses;
#   - the bus load per 1 ms cycle at the configured bit rate (drive_bridge prints it).
#   bench/virtual_rig_bench.sh [realtime_seconds] [runs]   (default 20 s, 2 runs)
# Prints figures and ratios only.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bin=build/bin
realtime_s="${1:-20}"
runs="${2:-2}"
domain="${PMLSM_DOMAIN:-44}"
port="${PMLSM_CAN_PORT:-43120}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

source bench/bench_lib.sh
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { if (a > 0) printf "%.2f", b / a; else print "n/a" }'; }

echo "[1/3] lockstep, PI, pulse: plant_sim, then the virtual rig"
"$bin/launcher" launch/sim.yaml --arg domain="$domain" --arg out="$work" >"$work/lock_sim.log" 2>&1
"$bin/launcher" launch/virtual_rig.yaml --arg domain="$domain" --arg out="$work" --arg can_port="$port" \
  >"$work/lock_rig.log" 2>&1
sim_rtf=$(rtf_of "$work/lock_sim.log")
rig_rtf=$(rtf_of "$work/lock_rig.log")
load_line=$(sed -n 's/.*drive_bridge: \(bus load per .*\)/\1/p' "$work/lock_rig.log" | head -n 1)

sed "s/^duration_s: .*/duration_s: {value: ${realtime_s}.0, source: \"chosen: bench length\"}/" \
  configs/scenarios/pulse.yaml >"$work/long.yaml"
common=(--domain "$domain" -s "$work/long.yaml" --clock realtime)
realtime_sim() {
  "$bin/controller" "${common[@]}" --plant-lost-ms 5000 >"$work/$1_controller.log" 2>&1 &
  local c=$!
  "$bin/plant_sim" "${common[@]}" --peers 1 --watchdog-ms 1000 --controller-lost-ms 5000 >"$work/$1.log" 2>&1 || true
  wait "$c" || true
}
realtime_rig() {
  local can=(--can-port "$port" --canopen-set drive.sync_timeout_ms=1000 --canopen-set master.realtime.max_missed_answers=1000)
  "$bin/virtual_drive" "${common[@]}" "${can[@]}" >"$work/$1_drive.log" 2>&1 &
  local d=$!
  "$bin/controller" "${common[@]}" --plant-lost-ms 5000 >"$work/$1_controller.log" 2>&1 &
  local c=$!
  "$bin/drive_bridge" "${common[@]}" "${can[@]}" --peers 1 --watchdog-ms 1000 --controller-lost-ms 5000 \
    >"$work/$1.log" 2>&1 || true
  wait "$c" || true
  kill -INT "$d" 2>/dev/null || true
  wait "$d" || true
}
echo "[2/3] realtime, ${realtime_s} s each, ${runs} x (plant_sim, virtual rig) alternating"
for i in $(seq 1 "$runs"); do
  echo "  run $i: plant_sim"
  realtime_sim "rt_sim_$i"
  echo "  run $i: virtual rig"
  realtime_rig "rt_rig_$i"
done

echo "[3/3] figures"
echo
echo "lockstep, PI, pulse (2000 ticks)"
printf '  %-28s %10s\n' "" "x real time"
printf '  %-28s %10s\n' "plant_sim (sim.yaml)" "$sim_rtf"
printf '  %-28s %10s\n' "virtual rig (virtual_rig.yaml)" "$rig_rtf"
echo "  rig / plant_sim: $(ratio "$sim_rtf" "$rig_rtf") (target: at least 0.5)"
echo
echo "realtime 1 kHz, drive + controller, chain latency feedback -> command (us)"
printf '  %-6s %-12s %9s %9s %9s   %s\n' run drive p50 p99 misses "SYNC intervals at the drive"
for i in $(seq 1 "$runs"); do
  for kind in sim rig; do
    log="$work/rt_${kind}_$i.log"
    sync="-"
    [ "$kind" = rig ] && sync=$(sed -n 's/.*SYNC intervals at the drive over [0-9]* SYNCs: \(.*\)/\1/p' "$work/rt_rig_${i}_drive.log")
    printf '  %-6s %-12s %9s %9s %9s   %s\n' "$i" "$([ "$kind" = sim ] && echo plant_sim || echo virtual_rig)" \
      "$(p50_of "$log")" "$(p99_of "$log")" "$(miss_of "$log")" "$sync"
  done
  echo "  run $i: rig / plant_sim p50 $(ratio "$(p50_of "$work/rt_sim_$i.log")" "$(p50_of "$work/rt_rig_$i.log")") (target: at most 1.5)"
done
echo
echo "CAN $load_line"

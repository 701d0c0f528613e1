#!/usr/bin/env bash
# Figures of the distributed system on this machine, in one run, next to their
# baselines: the in-process loop (same computations, no DDS) and Cyclone DDS's
# ddsperf ping-pong (the floor of DDS messaging here). Prints figures only.
#   bench/distributed_bench.sh [realtime_seconds]   (default 60)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bin=build/bin
realtime_s="${1:-60}"
domain="${PMLSM_DOMAIN:-43}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

# The plant prints its own figures at the end of a run; pick them out.
field() { sed -n "$1" "$2" | head -n 1; }
rtf_of() { field 's/.*ticks in [0-9.]* s (\([0-9.]*\)x real time).*/\1/p' "$1"; }
p50_of() { field 's/.*p50 \([0-9.]*\) us.*/\1/p' "$1"; }
p99_of() { field 's/.*p99 \([0-9.]*\) us.*/\1/p' "$1"; }
max_of() { field 's/.*max \([0-9.]*\) us.*/\1/p' "$1"; }
late_of() { field 's/.*late \([0-9]*\),.*/\1/p' "$1"; }
miss_of() { field 's/.*deadline misses \([0-9]*\).*/\1/p' "$1"; }
ppm_of() { field 's/.*nominal [0-9.]* us, \([-+0-9.]*\) ppm.*/\1/p' "$1"; }

echo "[1/5] in-process loop (baseline)"
in_process=$("$bin/pmlsm_bench" --benchmark_filter='BM_ClosedLoopTick/integrator:2' 2>/dev/null |
             sed -n 's/.*x_realtime=\([0-9.]*\)\/s.*/\1/p' | head -n 1)

echo "[2/5] lockstep, force level, 4 nodes"
"$bin/launcher" launch/sim.yaml --arg domain="$domain" --arg out="$work" >"$work/force.log" 2>&1
echo "[3/5] lockstep, voltage level, 4 nodes"
"$bin/launcher" launch/sim.yaml --arg domain="$domain" --arg out="$work" --arg command_level=voltage \
  >"$work/voltage.log" 2>&1

echo "[4/5] realtime, plant_sim + controller, ${realtime_s} s"
sed "s/^duration_s: .*/duration_s: ${realtime_s}.0/" configs/scenarios/pulse.yaml >"$work/long.yaml"
"$bin/controller" --domain "$domain" -s "$work/long.yaml" --clock realtime >"$work/rt_controller.log" 2>&1 &
controller_pid=$!
"$bin/plant_sim" --domain "$domain" -s "$work/long.yaml" --clock realtime --peers 1 \
  --watchdog-ms 1000 >"$work/realtime.log" 2>&1 || true
wait "$controller_pid" || true

echo "[5/5] ddsperf ping-pong, 10 s"
ddsperf_p50="n/a"; ddsperf_p99="n/a"
if command -v ddsperf >/dev/null; then
  ddsperf -D 12 pong >/dev/null 2>&1 &
  pong_pid=$!
  ddsperf -D 10 ping >"$work/ddsperf.log" 2>&1 || true
  kill "$pong_pid" 2>/dev/null || true
  wait "$pong_pid" 2>/dev/null || true
  ddsperf_p50=$(grep ' 50% ' "$work/ddsperf.log" | tail -n 1 | sed -n 's/.* 50% \([0-9.]*\)us.*/\1/p')
  ddsperf_p99=$(grep ' 99% ' "$work/ddsperf.log" | tail -n 1 | sed -n 's/.* 99% \([0-9.]*\)us.*/\1/p')
fi

ratio() { awk -v a="$1" -v b="$2" 'BEGIN { if (a == "" || b == "" || b == "n/a" || b + 0 == 0) print "n/a"; else printf "%.3g", a / b }'; }
force_rtf=$(rtf_of "$work/force.log"); voltage_rtf=$(rtf_of "$work/voltage.log")
rt_p50=$(p50_of "$work/realtime.log")
echo
printf '%-58s %s\n' "figure" "value"
printf '%-58s %sx\n' "in-process closed loop (ab2), real-time factor" "$in_process"
printf '%-58s %sx (ratio to in-process %s)\n' "lockstep force level, 4 nodes, real-time factor" "$force_rtf" "$(ratio "$force_rtf" "$in_process")"
printf '%-58s p50 %s us, p99 %s us, max %s us\n' "  chain latency MotorFeedback -> ForceCommand" "$(p50_of "$work/force.log")" "$(p99_of "$work/force.log")" "$(max_of "$work/force.log")"
printf '%-58s %sx (ratio to in-process %s)\n' "lockstep voltage level (32 exchanges/tick), real-time factor" "$voltage_rtf" "$(ratio "$voltage_rtf" "$in_process")"
printf '%-58s p50 %s us, p99 %s us, max %s us\n' "realtime ${realtime_s} s chain latency" "$rt_p50" "$(p99_of "$work/realtime.log")" "$(max_of "$work/realtime.log")"
printf '%-58s late %s, deadline misses %s of %s ticks\n' "realtime ticks" "$(late_of "$work/realtime.log")" "$(miss_of "$work/realtime.log")" "$((realtime_s * 1000))"
printf '%-58s %s ppm\n' "realtime tick period drift" "$(ppm_of "$work/realtime.log")"
printf '%-58s p50 %s us, p99 %s us\n' "ddsperf ping-pong round trip (Cyclone DDS)" "$ddsperf_p50" "$ddsperf_p99"
printf '%-58s %s\n' "realtime chain p50 / ddsperf p50" "$(ratio "$rt_p50" "$ddsperf_p50")"

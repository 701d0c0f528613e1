#!/usr/bin/env bash
# Figures of the distributed system on this machine, in one run, next to their
# baselines: the in-process loop (same computations, no DDS), Cyclone DDS's
# ddsperf ping-pong (the floor of DDS messaging here) and cyclictest (the floor
# of waking a thread on time here). The realtime pair runs twice: with normal
# scheduling, and tuned as a lab rig would be (SCHED_FIFO 80 with memory
# locked, cores kept out of idle states through /dev/cpu_dma_latency, the
# plant polling the clock for the last 100 us before each tick; needs root).
# Prints figures only.
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
source bench/bench_lib.sh

echo "[1/7] in-process loop (baseline)"
in_process=$("$bin/pmlsm_bench" --benchmark_filter='BM_ClosedLoopTick/integrator:2' 2>/dev/null |
             sed -n 's/.*x_realtime=\([0-9.]*\)\/s.*/\1/p' | head -n 1)

echo "[2/7] lockstep, force level, 4 nodes"
"$bin/launcher" launch/sim.yaml --arg domain="$domain" --arg out="$work" >"$work/force.log" 2>&1
echo "[3/7] lockstep, voltage level, 4 nodes"
"$bin/launcher" launch/sim.yaml --arg domain="$domain" --arg out="$work" --arg command_level=voltage \
  >"$work/voltage.log" 2>&1

sed "s/^duration_s: .*/duration_s: ${realtime_s}.0/" configs/scenarios/pulse.yaml >"$work/long.yaml"
tuned=(--rt-priority 80 --cpu-dma-latency-us 0)
# realtime_pair NAME [options for both] -- [options for the plant only]
realtime_pair() {
  local name="$1"; shift
  local both=() plant_only=()
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do both+=("$1"); shift; done
  [ $# -gt 0 ] && shift
  plant_only=("$@")
  "$bin/controller" --domain "$domain" -s "$work/long.yaml" --clock realtime --plant-lost-ms 5000 "${both[@]}" \
    >"$work/${name}_controller.log" 2>&1 &
  controller_pid=$!
  "$bin/plant_sim" --domain "$domain" -s "$work/long.yaml" --clock realtime --peers 1 \
    --watchdog-ms 1000 --controller-lost-ms 5000 "${both[@]}" "${plant_only[@]}" >"$work/${name}.log" 2>&1 || true
  wait "$controller_pid" || true
}
echo "[4/7] realtime, plant_sim + controller, normal scheduling, ${realtime_s} s"
realtime_pair realtime
echo "[5/7] realtime, plant_sim + controller, tuned (${tuned[*]}, plant --wake-early-us 100), ${realtime_s} s"
realtime_pair tuned "${tuned[@]}" -- --wake-early-us 100

echo "[6/7] ddsperf ping-pong, 10 s"
ddsperf_p50="n/a"; ddsperf_p99="n/a"
if command -v ddsperf >/dev/null; then
  ddsperf -D 12 pong >/dev/null 2>&1 &
  pong_pid=$!
  ddsperf -D 10 ping >"$work/ddsperf.log" 2>&1 || true
  kill "$pong_pid" 2>/dev/null || true
  wait "$pong_pid" 2>/dev/null || true
  ddsperf_p50=$( (grep ' 50% ' "$work/ddsperf.log" || true) | tail -n 1 | sed -n 's/.* 50% \([0-9.]*\)us.*/\1/p')
  ddsperf_p99=$( (grep ' 99% ' "$work/ddsperf.log" || true) | tail -n 1 | sed -n 's/.* 99% \([0-9.]*\)us.*/\1/p')
fi

echo "[7/7] cyclictest, one SCHED_FIFO 80 thread waking every 1 ms, 10 s"
cyc_p50="n/a"; cyc_p99="n/a"; cyc_max="n/a"
if command -v cyclictest >/dev/null; then
  # Histogram in 1 us buckets up to 10 ms; what lies beyond counts as over.
  cyclictest -q -m -p 80 -i 1000 -D 10 -h 10000 >"$work/cyclictest.log" 2>&1 || true
  read -r cyc_p50 cyc_p99 < <(awk '
    /^[0-9]+ [0-9]+$/ { bucket[n] = $1 + 0; count[n] = $2 + 0; total += $2; n++ }
    /^# Histogram Overflows:/ { over = $4 + 0 }
    END {
      total += over; p50 = "n/a"; p99 = "n/a"; sum = 0
      for (i = 0; i < n; i++) {
        sum += count[i]
        if (p50 == "n/a" && sum >= 0.5 * total) p50 = bucket[i]
        if (p99 == "n/a" && sum >= 0.99 * total) p99 = bucket[i]
      }
      if (p99 == "n/a" && total > 0) p99 = ">10000"
      print p50, p99
    }' "$work/cyclictest.log")
  cyc_max=$(sed -n 's/^# Max Latencies: 0*\([0-9]\)/\1/p' "$work/cyclictest.log" | head -n 1)
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
for run in realtime tuned; do
  label="realtime ${realtime_s} s"; [ "$run" = tuned ] && label="realtime ${realtime_s} s, tuned"
  printf '%-58s p50 %s us, p99 %s us, max %s us\n' "$label chain latency" "$(p50_of "$work/$run.log")" \
    "$(p99_of "$work/$run.log")" "$(max_of "$work/$run.log")"
  printf '%-58s late %s, deadline misses %s of %s ticks\n' "  ticks" "$(late_of "$work/$run.log")" \
    "$(miss_of "$work/$run.log")" "$((realtime_s * 1000))"
  printf '%-58s %s ppm\n' "  tick period drift" "$(ppm_of "$work/$run.log")"
  if grep -q "refused" "$work/$run.log"; then
    printf '%-58s %s\n' "  (not run)" "$(grep -m1 refused "$work/$run.log")"
  fi
done
printf '%-58s p50 %s us, p99 %s us\n' "ddsperf ping-pong round trip (Cyclone DDS)" "$ddsperf_p50" "$ddsperf_p99"
printf '%-58s p50 %s us, p99 %s us, max %s us\n' "cyclictest timer wake-up lateness (SCHED_FIFO 80)" "$cyc_p50" "$cyc_p99" "$cyc_max"
printf '%-58s %s (tuned %s)\n' "realtime chain p50 / ddsperf p50" "$(ratio "$rt_p50" "$ddsperf_p50")" \
  "$(ratio "$(p50_of "$work/tuned.log")" "$ddsperf_p50")"

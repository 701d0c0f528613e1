#!/usr/bin/env bash
# Components in one container process against one process per node, side by side in one run
# on this machine (launch/sim_rnn.yaml: plant_sim, controller, kalman_estimator,
# rnn_compensator, evaluator):
#   - lockstep, composed and separate, each run `repeats` times: real-time factor (median and
#     range) and their ratio, and the composed chain's against the in-process closed loop's in
#     the same runs (pmlsm_bench BM_ClosedLoopTick, ab2: the same loop in one function); the
#     voltage level (32 exchanges a tick) composed;
#   - realtime, composed, untuned, `runs` runs of `seconds` s: the container's CPU (cores),
#     chain latency, watchdog trips, deadline misses; the same with one recorder outside
#     (`pmlsm record`), and one separate-process run for comparison;
#   - realtime, composed, tuned (SCHED_FIFO 80, memory locked, cpu_dma_latency 0, the plant
#     polling the clock for the last 100 us; needs root): deadline misses;
#   - realtime, composed, secured (a keystore made by `pmlsm security create`), untuned: chain
#     latency against the open runs', watchdog trips;
#   - the virtual rig (launch/virtual_rig.yaml, PI) in realtime, composed, `runs` / 2 runs:
#     watchdog trips, chain latency, the SYNC intervals at the virtual drive.
# Prints figures only; exits 1 when a run did not end with exit 0.
#   bench/compose_bench.sh [repeats] [runs] [seconds] [only]   (default 5 3 10; only=virtual_rig: that part alone)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bin=build/bin
repeats="${1:-5}"
runs="${2:-3}"
seconds="${3:-10}"
only="${4:-}"
domain="${PMLSM_DOMAIN:-47}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
source bench/bench_lib.sh
cores_of() { field 's/.*process CPU over the loop: [0-9.]* us a tick, \([0-9.]*\) cores.*/\1/p' "$1"; }
cpu_tick_of() { field 's/.*process CPU over the loop: \([0-9.]*\) us a tick.*/\1/p' "$1"; }
trips_of() { grep -c "watchdog: tick" "$1" || true; }
# median and range of the numbers on stdin: "median (min-max)"
summary() { sort -g | awk '{ v[NR] = $1 } END { if (NR == 0) { print "n/a"; exit }
  m = (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2; printf "%.4g (%.4g-%.4g, %d runs)", m, v[1], v[NR], NR }'; }
median() { sort -g | awk '{ v[NR] = $1 } END { if (NR == 0) print ""; else print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
failed=0
run() {  # run LOG launcher-args...: the launcher, its exit code noted
  local log="$1"; shift
  local code=0
  "$bin/launcher" launch/sim_rnn.yaml --arg domain="$domain" --arg out="$work" "$@" >"$log" 2>&1 || code=$?
  if [ "$code" -ne 0 ]; then
    echo "  run failed (exit $code): $(basename "$log")"; { grep -E "watchdog|fault|lost|first failure" "$log" || true; } | head -n 5; failed=1
  fi
}

sed "s/^duration_s: .*/duration_s: ${seconds}.0/" configs/scenarios/pulse.yaml >"$work/long.yaml"
if [ -z "$only" ]; then
echo "[1/7] lockstep, sim_rnn, composed and separate, ${repeats} runs each (alternating)"
for i in $(seq "$repeats"); do
  run "$work/lock_comp_$i.log" --arg compose=true
  run "$work/lock_sep_$i.log" --arg compose=false
  "$bin/pmlsm_bench" --benchmark_filter='BM_ClosedLoopTick/integrator:2$' --benchmark_format=json \
    >"$work/inproc_$i.json" 2>/dev/null || { echo "  pmlsm_bench failed"; failed=1; }
done
echo "[2/7] lockstep, voltage level (32 exchanges a tick), composed and separate"
"$bin/launcher" launch/sim.yaml --arg domain="$domain" --arg out="$work" --arg compose=true \
  --arg command_level=voltage >"$work/volt_comp.log" 2>&1 || { echo "  voltage composed failed"; failed=1; }
"$bin/launcher" launch/sim.yaml --arg domain="$domain" --arg out="$work" --arg compose=false \
  --arg command_level=voltage >"$work/volt_sep.log" 2>&1 || { echo "  voltage separate failed"; failed=1; }

echo "[3/7] realtime, composed, untuned, ${runs} runs of ${seconds} s"
for i in $(seq "$runs"); do
  run "$work/rt_comp_$i.log" --arg compose=true --arg clock=realtime --arg scenario="$work/long.yaml"
done
echo "[4/7] realtime, composed with a recorder outside; and separate processes, ${seconds} s each"
"$bin/pmlsm" --domain "$domain" record --no-progress -o "$work/rec.mcap" >"$work/recorder.log" 2>&1 &
recorder=$!
sleep 2  # the recorder's readers match before the run starts (a lockstep run would wait for them)
run "$work/rt_rec.log" --arg compose=true --arg clock=realtime --arg scenario="$work/long.yaml"
kill -INT "$recorder" 2>/dev/null || true
wait "$recorder" || true
run "$work/rt_sep.log" --arg compose=false --arg clock=realtime --arg scenario="$work/long.yaml"
echo "[5/7] realtime, composed, tuned (rt_priority=80 cpu_dma_latency_us=0 wake_early_us=100), ${runs} runs"
for i in $(seq "$runs"); do
  run "$work/rt_tuned_$i.log" --arg compose=true --arg clock=realtime --arg scenario="$work/long.yaml" \
    --arg rt_priority=80 --arg cpu_dma_latency_us=0 --arg wake_early_us=100
done
echo "[6/7] realtime, composed, secured, untuned, ${runs} runs"
"$bin/pmlsm" security create "$work/keystore" >"$work/keystore.log" 2>&1
for i in $(seq "$runs"); do
  run "$work/rt_sec_$i.log" --arg compose=true --arg clock=realtime --arg scenario="$work/long.yaml" \
    --arg keystore="$work/keystore"
done

fi
rig_runs=$(( runs / 2 > 0 ? runs / 2 : 1 ))
echo "[7/7] the virtual rig in realtime, composed, ${rig_runs} runs of ${seconds} s"
for i in $(seq "$rig_runs"); do
  code=0
  "$bin/launcher" launch/virtual_rig.yaml --arg domain="$domain" --arg out="$work" --arg compose=true \
    --arg clock=realtime --arg scenario="$work/long.yaml" --arg can_port="${PMLSM_CAN_PORT:-43130}" \
    >"$work/rig_$i.log" 2>&1 || code=$?
  if [ "$code" -ne 0 ]; then
    echo "  run failed (exit $code): rig_$i.log"; { grep -E "watchdog|FAULT|lost|first failure" "$work/rig_$i.log" || true; } | head -n 5
    failed=1
  fi
done

ratio() { awk -v a="$1" -v b="$2" 'BEGIN { if (a == "" || b == "" || b + 0 == 0) print "n/a"; else printf "%.3g", a / b }'; }
each() { for f in "$work"/$1; do "$2" "$f"; done; }
inproc_rtf_of() { field 's/.*"x_realtime": \([0-9.e+]*\).*/\1/p' "$1"; }
echo
printf '%-56s %s\n' "figure" "value"
if [ -z "$only" ]; then
comp_rtf=$(each 'lock_comp_*.log' rtf_of | median); sep_rtf=$(each 'lock_sep_*.log' rtf_of | median)
printf '%-56s %sx\n' "lockstep, composed, real-time factor" "$(each 'lock_comp_*.log' rtf_of | summary)"
printf '%-56s %sx\n' "lockstep, separate processes, real-time factor" "$(each 'lock_sep_*.log' rtf_of | summary)"
printf '%-56s %s\n' "  composed / separate (medians)" "$(ratio "$comp_rtf" "$sep_rtf")"
inproc_rtf=$(each 'inproc_*.json' inproc_rtf_of | median)
printf '%-56s %sx\n' "in-process closed loop (ab2), real-time factor" "$(each 'inproc_*.json' inproc_rtf_of | summary)"
printf '%-56s %s\n' "  composed / in-process (medians)" "$(ratio "$comp_rtf" "$inproc_rtf")"
printf '%-56s %s us composed, %s us separate (plant process only)\n' "  process CPU a tick (medians)" \
  "$(each 'lock_comp_*.log' cpu_tick_of | median)" "$(each 'lock_sep_*.log' cpu_tick_of | median)"
printf '%-56s %sx composed, %sx separate\n' "lockstep voltage level, real-time factor" \
  "$(rtf_of "$work/volt_comp.log")" "$(rtf_of "$work/volt_sep.log")"
printf '%-56s %s\n' "realtime composed untuned: container CPU, cores" "$(each 'rt_comp_*.log' cores_of | summary)"
printf '%-56s %s\n' "  chain latency p50, us" "$(each 'rt_comp_*.log' p50_of | summary)"
printf '%-56s %s\n' "  chain latency p99, us" "$(each 'rt_comp_*.log' p99_of | summary)"
printf '%-56s %s of %s runs; deadline misses %s\n' "  watchdog trips" \
  "$(for f in "$work"/rt_comp_*.log; do [ "$(trips_of "$f")" -gt 0 ] && echo x; done | wc -l)" "$runs" \
  "$(each 'rt_comp_*.log' miss_of | awk '{ s += $1 } END { print s + 0 }')"
printf '%-56s %s cores (%s without), p50 %s us\n' "  with one recorder outside" "$(cores_of "$work/rt_rec.log")" \
  "$(each 'rt_comp_*.log' cores_of | median)" "$(p50_of "$work/rt_rec.log")"
printf '%-56s %s cores (plant process only), p50 %s us, trips %s\n' "realtime separate processes" \
  "$(cores_of "$work/rt_sep.log")" "$(p50_of "$work/rt_sep.log")" "$(trips_of "$work/rt_sep.log")"
trip_runs() { for f in "$work"/$1; do [ "$(trips_of "$f")" -gt 0 ] && echo x; done | wc -l; }
printf '%-56s %s\n' "realtime composed secured: chain latency p50, us" "$(each 'rt_sec_*.log' p50_of | summary)"
printf '%-56s %s (secured / open medians)\n' "  p50 ratio" \
  "$(ratio "$(each 'rt_sec_*.log' p50_of | median)" "$(each 'rt_comp_*.log' p50_of | median)")"
printf '%-56s %s of %s runs; container CPU %s cores (median)\n' "  watchdog trips" "$(trip_runs 'rt_sec_*.log')" "$runs" \
  "$(each 'rt_sec_*.log' cores_of | median)"
printf '%-56s %s of %s ticks; p50 %s us, p99 %s us\n' "realtime composed tuned: deadline misses" \
  "$(each 'rt_tuned_*.log' miss_of | awk '{ s += $1 } END { print s + 0 }')" "$((runs * seconds * 1000))" \
  "$(each 'rt_tuned_*.log' p50_of | median)" "$(each 'rt_tuned_*.log' p99_of | median)"
fi
sync_std_of() { field 's/.*SYNC intervals at the drive over [0-9]* SYNCs: mean [0-9.]* us, std \([0-9.]*\) us.*/\1/p' "$1"; }
sync_max_of() { field 's/.*SYNC intervals at the drive over [0-9]* SYNCs: .*max \([0-9.]*\) us.*/\1/p' "$1"; }
printf '%-56s %s of %s runs\n' "virtual rig realtime composed: watchdog trips" \
  "$(for f in "$work"/rig_*.log; do [ "$(trips_of "$f")" -gt 0 ] && echo x; done | wc -l)" "$rig_runs"
printf '%-56s %s\n' "  chain latency p50, us" "$(each 'rig_*.log' p50_of | summary)"
printf '%-56s %s\n' "  chain latency p99, us" "$(each 'rig_*.log' p99_of | summary)"
printf '%-56s std %s us, max %s us (medians)\n' "  SYNC intervals at the virtual drive" \
  "$(each 'rig_*.log' sync_std_of | median)" "$(each 'rig_*.log' sync_max_of | median)"
exit "$failed"

#!/usr/bin/env bash
# The composed realtime chain (launch/sim_rnn.yaml, clock=realtime: one container) while the world
# outside the process listens: `pmlsm record` of every topic, `pmlsm topic echo` of motor_feedback,
# the Foxglove bridge with a client (tests/node/ws_client.mjs) on every topic and an independent
# ROS 2 node (@foxglove/ros2, tests/node/ros2_listener.mjs) on motor_feedback, all at once.
# Two ways, alternating run by run so that both see the machine's same mood:
#   thread: what leaves the process goes out from the container's publisher thread (the default);
#   inline: the chain thread writes it to DDS itself (--arg publish_period_us=0, as before).
# Per way: chain latency p50 / max (median and range over the runs), watchdog trips, runs that did
# not end 0, the recording's count of lost samples and the container's count of samples the
# publisher thread dropped. Prints figures only; exits 1 when a run did not end with exit 0.
# `rt_priority` (root): the container's chain thread at that SCHED_FIFO priority, memory locked.
#   bench/outside_readers_bench.sh [runs] [seconds] [rt_priority]   (default 5 10 0)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bin="${PMLSM_BIN_DIR:-build/bin}"
runs="${1:-5}"
seconds="${2:-10}"
rt_priority="${3:-0}"
domain="${PMLSM_DOMAIN:-48}"
for v in "$runs" "$seconds"; do
  [[ "$v" =~ ^[1-9][0-9]*$ ]] || { echo "outside_readers_bench: runs and seconds must be positive integers, got '$v'" >&2; exit 2; }
done
[[ "$rt_priority" =~ ^[0-9]+$ ]] && [ "$rt_priority" -le 99 ] ||
  { echo "outside_readers_bench: rt_priority must be 0..99, got '$rt_priority'" >&2; exit 2; }
for program in launcher container pmlsm foxglove_bridge; do
  [ -x "$bin/$program" ] || { echo "outside_readers_bench: no $bin/$program (build it, or set PMLSM_BIN_DIR)" >&2; exit 2; }
done
command -v node >/dev/null || { echo "outside_readers_bench: node not found (scripts/install_deps.sh installs it)" >&2; exit 2; }
work="$(mktemp -d)"
pids=()
# Every path out stops what this script started, by PID.
cleanup() {
  for pid in ${pids[@]+"${pids[@]}"}; do kill "$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT
source bench/bench_lib.sh
summary() { sort -g | awk '{ v[NR] = $1 } END { if (NR == 0) { print "n/a"; exit }
  m = (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2; printf "%.4g (%.4g-%.4g)", m, v[1], v[NR] }'; }

sed "s/^duration_s: .*/duration_s: ${seconds}.0/" configs/scenarios/pulse.yaml >"$work/long.yaml"
dds=(--domain "$domain" --profiles configs/dds/profiles.xml)

echo "[1/3] the outside readers: foxglove_bridge with a client on every topic, pmlsm topic echo, a ROS 2 node"
"$bin/foxglove_bridge" "${dds[@]}" --address 127.0.0.1 --port 0 >"$work/bridge.log" 2>&1 &
pids+=($!)
wait_for_line "$work/bridge.log" "listening on ws://"
url=$(sed -n 's/.*listening on \(ws:\/\/[0-9.]*:[0-9]*\).*/\1/p' "$work/bridge.log" | head -n 1)
nice -n 10 node tests/node/ws_client.mjs --url "$url" --topics all --min-messages 0 \
  --duration-s 36000 --timeout-s 72000 >"$work/client.log" 2>&1 &
pids+=($!)
wait_for_line "$work/client.log" "ws_client: subscribed"
"$bin/pmlsm" "${dds[@]}" topic echo /pmlsm/motor_feedback >"$work/echo.log" 2>&1 &
pids+=($!)
nice -n 10 node tests/node/ros2_listener.mjs --package "${PMLSM_ROS2_PACKAGE_DIR:-build/ros2/pmlsm_msgs}" \
  --domain "$domain" --listen-s 36000 --timeout-s 72000 >"$work/ros2.log" 2>&1 &
pids+=($!)
wait_for_line "$work/ros2.log" "ros2_listener: started"

failed=0
echo "[2/3] ${runs} runs of ${seconds} s each way, alternating, each with its own pmlsm record (rt_priority ${rt_priority})"
for i in $(seq "$runs"); do
  for way in thread inline; do
    period=250
    [ "$way" = inline ] && period=0
    mkdir -p "$work/$way"
    log="$work/$way/run_$i.log"
    "$bin/pmlsm" "${dds[@]}" record -o "$work/$way/rec_$i.mcap" >"$work/$way/rec_$i.log" 2>&1 &
    rec=$!
    sleep 1  # the recorder's readers discovered before the run starts
    code=0
    "$bin/launcher" launch/sim_rnn.yaml --arg domain="$domain" --arg out="$work" --arg clock=realtime \
      --arg scenario="$work/long.yaml" --arg publish_period_us="$period" --arg rt_priority="$rt_priority" \
      >"$log" 2>&1 || code=$?
    kill -INT "$rec"; wait "$rec" || true
    echo "$code" >"$work/$way/code_$i"
    if [ "$code" -ne 0 ]; then failed=1; echo "  ${way} run $i: exit $code"; fi
    printf '  %-6s run %d: p50 %s us, max %s us, exit %s\n' "$way" "$i" "$(p50_of "$log")" "$(max_of "$log")" "$code"
  done
done

echo "[3/3] figures"
printf '%-8s %-26s %-28s %-8s %-10s %-14s %s\n' way "p50 us median (range)" "max us median (range)" trips "not exit 0" "rec. lost" "outbox lost"
for way in thread inline; do
  p50=$(for f in "$work/$way"/run_*.log; do p50_of "$f"; done | summary)
  mx=$(for f in "$work/$way"/run_*.log; do max_of "$f"; done | summary)
  trips=$(cat "$work/$way"/run_*.log | grep -c "watchdog: tick" || true)
  bad=$(cat "$work/$way"/code_* | grep -vc '^0$' || true)
  lost=$(cat "$work/$way"/rec_*.log | sed -n 's/.* \([0-9]*\) lost;.*/\1/p' | awk '{ s += $1 } END { print s + 0 }')
  outbox=$(cat "$work/$way"/run_*.log | sed -n 's/.*to readers outside (publisher thread): .*, \([0-9]*\) lost$/\1/p' |
    awk '{ s += $1 } END { print s + 0 }')
  printf '%-8s %-26s %-28s %-8s %-10s %-14s %s\n' "$way" "$p50" "$mx" "$trips" "$bad" "$lost" "$outbox"
done
echo "(rec. lost: samples the recordings miss, summed over the runs; outbox lost: samples the publisher thread dropped)"
exit "$failed"

#!/usr/bin/env bash
# What a live Foxglove view costs the control loop: the realtime chain latency (plant_sim's
# MotorFeedback written -> its ForceCommand taken, the figure bench/distributed_bench.sh
# reports) of plant_sim + controller, run three times: without the bridge, with the bridge
# running but no client, and with a Foxglove client (tests/node/ws_client.mjs) subscribed to
# every topic (or those given). Prints figures only. On a shared machine the idle run is the
# yardstick: it costs the loop nothing, so its ratio's distance from 1 is noise.
#   bench/bridge_bench.sh [seconds_per_run [topics]]   (default 20, all)
# The client runs at niceness 10: it stands in for Foxglove, which runs on the operator's
# machine, not on the control machine's cores.
#   PMLSM_BIN_DIR: the programs (default build/bin); PMLSM_DOMAIN: DDS domain (default 44);
#   PMLSM_CHAIN_OPTS: more options for plant_sim and controller, e.g. the tuned setup of
#   bench/distributed_bench.sh: "--rt-priority 80 --cpu-dma-latency-us 0".
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bin="${PMLSM_BIN_DIR:-build/bin}"
seconds="${1:-20}"
topics="${2:-all}"
domain="${PMLSM_DOMAIN:-44}"
if ! [[ "$seconds" =~ ^[1-9][0-9]*$ ]]; then
  echo "bridge_bench: seconds per run must be a positive integer, got '$seconds'" >&2
  exit 2
fi
for program in plant_sim controller foxglove_bridge; do
  [ -x "$bin/$program" ] || { echo "bridge_bench: no $bin/$program (build it, or set PMLSM_BIN_DIR)" >&2; exit 2; }
done
command -v node >/dev/null || { echo "bridge_bench: node not found (scripts/install_deps.sh installs it)" >&2; exit 2; }

work="$(mktemp -d)"
bridge_pid=""
client_pid=""
controller_pid=""
# Every path out stops what this script started, by PID.
cleanup() {
  for pid in "$client_pid" "$bridge_pid" "$controller_pid"; do
    [ -n "$pid" ] && kill "$pid" 2>/dev/null || true
  done
  wait 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT

# Polls a log for a line (the programs print when they are ready); fails after 15 s.
wait_for_line() {
  local file="$1" text="$2" deadline=$((SECONDS + 15))
  until grep -q -- "$text" "$file" 2>/dev/null; do
    if ((SECONDS >= deadline)); then
      echo "bridge_bench: '$text' not in $file within 15 s:" >&2
      cat "$file" >&2
      exit 1
    fi
    sleep 0.05
  done
}

field() { sed -n "$1" "$2" | head -n 1; }
p50_of() { field 's/.*p50 \([0-9.]*\) us.*/\1/p' "$1"; }
p99_of() { field 's/.*p99 \([0-9.]*\) us.*/\1/p' "$1"; }
max_of() { field 's/.*max \([0-9.]*\) us.*/\1/p' "$1"; }
late_of() { field 's/.*late \([0-9]*\),.*/\1/p' "$1"; }
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { if (a == "" || b == "" || b + 0 == 0) print "n/a"; else printf "%.3f", a / b }'; }

sed "s/^duration_s: .*/duration_s: ${seconds}.0/" configs/scenarios/pulse.yaml >"$work/long.yaml"
dds=(--domain "$domain" --profiles configs/dds/profiles.xml)
read -r -a chain_opts <<<"${PMLSM_CHAIN_OPTS:-}"

# plant_sim + controller in realtime, as bench/distributed_bench.sh runs them.
run_loop() {
  local name="$1"
  "$bin/controller" "${dds[@]}" ${chain_opts[@]+"${chain_opts[@]}"} -s "$work/long.yaml" --clock realtime >"$work/${name}_controller.log" 2>&1 &
  controller_pid=$!
  "$bin/plant_sim" "${dds[@]}" ${chain_opts[@]+"${chain_opts[@]}"} -s "$work/long.yaml" --clock realtime --peers 1 --watchdog-ms 1000 \
    >"$work/${name}.log" 2>&1 || true
  wait "$controller_pid" || true
  controller_pid=""
}

echo "[1/3] no bridge, ${seconds} s"
run_loop base

echo "[2/3] bridge running, no client, ${seconds} s"
"$bin/foxglove_bridge" "${dds[@]}" --address 127.0.0.1 --port 0 >"$work/bridge.log" 2>&1 &
bridge_pid=$!
wait_for_line "$work/bridge.log" "listening on ws://"
url=$(sed -n 's/.*listening on \(ws:\/\/[0-9.]*:[0-9]*\).*/\1/p' "$work/bridge.log" | head -n 1)
run_loop idle

echo "[3/3] bridge + Foxglove client on topics '$topics', ${seconds} s"
# The client stays until it is stopped below; it checks every message it decodes.
nice -n 10 node tests/node/ws_client.mjs --url "$url" --topics "$topics" --min-messages 0 \
  --duration-s $((seconds + 3600)) --timeout-s $((seconds + 7200)) >"$work/client.log" 2>&1 &
client_pid=$!
wait_for_line "$work/client.log" "ws_client: subscribed"
if [ "$topics" = all ]; then topic_count=17; else topic_count=$(tr ',' '\n' <<<"$topics" | grep -c .); fi
wait_for_line "$work/bridge.log" "reading $topic_count of 17 topics"
run_loop attached
kill "$client_pid" 2>/dev/null || true
wait "$client_pid" 2>/dev/null || true
client_pid=""
kill -INT "$bridge_pid"
wait "$bridge_pid" || true
bridge_pid=""
grep "samples read" "$work/bridge.log" >"$work/bridge_exit.log" || true  # the bridge's exit line
sent=$(field 's/.* \([0-9]*\) frames sent.*/\1/p' "$work/bridge_exit.log")
dropped=$(field 's/.* \([0-9]*\) dropped, .*/\1/p' "$work/bridge_exit.log")

echo
printf '%-48s %s\n' "realtime chain latency, ${seconds} s each" "p50 / p99 / max [us], late ticks"
for run in base idle attached; do
  case "$run" in
    base) label="no bridge" ;;
    idle) label="bridge running, no client" ;;
    attached) label="bridge + client on ${topic_count} topics" ;;
  esac
  printf '%-48s %s / %s / %s, late %s\n' "  $label" "$(p50_of "$work/$run.log")" "$(p99_of "$work/$run.log")" \
    "$(max_of "$work/$run.log")" "$(late_of "$work/$run.log")"
done
printf '%-48s %s\n' "p50 ratio, bridge idle / no bridge" "$(ratio "$(p50_of "$work/idle.log")" "$(p50_of "$work/base.log")")"
printf '%-48s %s\n' "p50 ratio, client attached / no bridge" \
  "$(ratio "$(p50_of "$work/attached.log")" "$(p50_of "$work/base.log")")"
printf '%-48s %s sent, %s dropped\n' "frames to the client" "${sent:-n/a}" "${dropped:-n/a}"
echo "(bridge idle has no DDS reader: its ratio's distance from 1 is this machine's noise)"

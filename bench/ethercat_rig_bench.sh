#!/usr/bin/env bash
# The EtherCAT rig in realtime over a veth pair, as a drive on its own wire: virtual_drive --bus
# ethercat answering raw EtherCAT on one end inside a network namespace this script makes, and the
# composed chain (launch/virtual_rig_ethercat.yaml: drive_bridge, controller, estimator, evaluator)
# on the other end. `runs` runs of `seconds` s of the pulse at 1 kHz; each run: the bridge's and
# the drive's exit codes, working counter errors, cycles without the inputs in time, drive faults,
# the frame round trip (p50 / p99 / max: the bus cycle time), the chain latency, the drive's
# distributed-clock difference at the end (its crystal 100 ppm fast, kept on the master's time by a
# write each cycle); then the totals.
# The lockstep run over UDP beside it, for the real-time factor against the CANopen rig's.
# With sync0 = true the drive runs on SYNC0 of its distributed clock (drive.sync0, DC mode): the
# column sync0_missed counts the pulses that found no new outputs (the drive's 0x1C32:0B), late_out
# the outputs the bridge sent after their tick's pulse.
#   sudo bench/ethercat_rig_bench.sh [runs] [seconds] [sync0]   (default 20 runs of 10 s, sync0 false)
# Needs root (a namespace, raw sockets); exits 77 without it. Prints figures; exits 1 when a run did
# not end with exit 0 on both ends or counted a working counter error or a fault.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bin=build/bin
runs="${1:-20}"
seconds="${2:-10}"
sync0="${3:-false}"
domain="${PMLSM_DOMAIN:-51}"
if [ "$(id -u)" != 0 ]; then
  echo "$(basename "$0"): needs root (a network namespace and raw EtherCAT on a veth pair)" >&2
  exit 77
fi
work="$(mktemp -d)"
ns="pmlsm_ecat_$$"
master_end="pmecm$$"
drive_end="pmecd$$"
drive_pid=
cleanup() {
  [ -n "$drive_pid" ] && kill -INT "$drive_pid" 2>/dev/null && wait "$drive_pid" 2>/dev/null
  ip link del "$master_end" 2>/dev/null || true
  ip netns del "$ns" 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT
source bench/bench_lib.sh

ip netns add "$ns"
ip link add "$master_end" type veth peer name "$drive_end"
ip link set "$drive_end" netns "$ns"
ip link set "$master_end" up
ip netns exec "$ns" ip link set lo up
ip netns exec "$ns" ip link set "$drive_end" up
scenario="$work/pulse_${seconds}s.yaml"
sed "s/^duration_s: {value: [0-9.]*/duration_s: {value: $seconds.0/" configs/scenarios/pulse.yaml >"$scenario"

echo "[1/2] lockstep, PI, pulse, EtherCAT over UDP on loopback and the CANopen rig"
"$bin/launcher" launch/virtual_rig_ethercat.yaml --arg domain="$domain" --arg out="$work" >"$work/lock_ecat.log" 2>&1
"$bin/launcher" launch/virtual_rig.yaml --arg domain="$domain" --arg out="$work" >"$work/lock_can.log" 2>&1
ecat_rtf=$(rtf_of "$work/lock_ecat.log")
can_rtf=$(rtf_of "$work/lock_can.log")
echo "  real-time factor: EtherCAT rig ${ecat_rtf}x, CANopen rig ${can_rtf}x, ratio $(awk -v a="$can_rtf" -v b="$ecat_rtf" 'BEGIN { printf "%.2f", b / a }')"
grep "round trip" "$work/lock_ecat.log" | sed 's/^\[drive_bridge\] drive_bridge: /  lockstep, UDP: /'

echo "[2/2] realtime, composed, raw EtherCAT over a veth pair: $runs runs of $seconds s, drive on SYNC0: $sync0"
printf '%4s %6s %6s %6s %7s %7s %11s %11s %11s %10s %11s %12s %8s\n' run bridge drive wkc_err missed faults trip_p50_us trip_p99_us trip_max_us chain_p50 dc_diff_ns sync0_missed late_out
failed=0
total_wkc=0
total_missed=0
total_faults=0
for ((r = 1; r <= runs; r++)); do
  dlog="$work/drive_$r.log"
  blog="$work/bridge_$r.log"
  ip netns exec "$ns" "$bin/virtual_drive" --bus ethercat --ethercat-interface "$drive_end" --clock realtime \
    --ethercat-dc-drift-ppm 100 --scenario "$scenario" --domain "$domain" >"$dlog" 2>&1 &
  drive_pid=$!
  wait_for_line "$dlog" "virtual EtherCAT CiA 402 drive on"
  bridge_code=0
  "$bin/launcher" launch/virtual_rig_ethercat.yaml --arg clock=realtime --arg virtual_drive=false \
    --arg ethercat_interface="$master_end" --arg scenario="$scenario" --arg domain="$domain" \
    --arg sync0="$sync0" --arg out="$work/out_$r" >"$blog" 2>&1 || bridge_code=$?
  kill -INT "$drive_pid"
  drive_code=0
  wait "$drive_pid" || drive_code=$?
  drive_pid=
  wkc=$(field 's/.* \([0-9]*\) working counter errors.*/\1/p' "$blog")
  missed=$(field 's/.* \([0-9]*\) cycles without the inputs in time.*/\1/p' "$blog")
  faults=$(field 's/.*faults \([0-9]*\) (last error.*/\1/p' "$dlog")
  trip="$(grep "frame round trip" "$blog" || true)"
  chain="$(grep "chain latency" "$blog" || true)"
  dc=$(field 's/.*difference 0x092C \([-0-9]*\) ns at the end.*/\1/p' "$blog")
  sync0_missed=$(field 's/.*SYNC0: [0-9]* pulses .*, \([0-9]*\) in OP without new outputs.*/\1/p' "$dlog")
  late_out=$(field 's/.*SYNC0: \([0-9]*\) of [0-9]* outputs sent after.*/\1/p' "$blog")
  printf '%4d %6s %6s %6s %7s %7s %11s %11s %11s %10s %11s %12s %8s\n' "$r" "$bridge_code" "$drive_code" "${wkc:-?}" "${missed:-?}" \
    "${faults:-?}" "$(sed -n 's/.*p50 \([0-9.]*\) us.*/\1/p' <<<"$trip")" "$(sed -n 's/.*p99 \([0-9.]*\) us.*/\1/p' <<<"$trip")" \
    "$(sed -n 's/.*max \([0-9.]*\) us.*/\1/p' <<<"$trip")" "$(sed -n 's/.*p50 \([0-9.]*\) us.*/\1/p' <<<"$chain")" "${dc:-?}" \
    "${sync0_missed:--}" "${late_out:--}"
  total_wkc=$((total_wkc + ${wkc:-1}))
  total_missed=$((total_missed + ${missed:-0}))
  total_faults=$((total_faults + ${faults:-1}))
  if [ "$bridge_code" != 0 ] || [ "$drive_code" != 0 ] || [ "${wkc:-1}" != 0 ] || [ "${faults:-1}" != 0 ]; then
    failed=1
    echo "  run $r: bridge exit $bridge_code, drive exit $drive_code; logs:" >&2
    grep -E "lost|fault|FAULT|error" "$blog" "$dlog" | head -20 >&2 || true
  fi
done
echo "totals over $runs runs: $total_wkc working counter errors, $total_missed cycles without the inputs in time, $total_faults drive faults"
exit "$failed"

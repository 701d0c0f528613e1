#!/usr/bin/env bash
# Fast DDS 2.9.1's lease-check abort (PDP.cpp, check_remote_participant_liveliness), reproduced and
# avoided: `procs` participant_churn processes, each creating batches of 6 participants that live
# 38 ms and leave one after the other, for `seconds` s, once per lease:
#   40 ms:    every peer's lease check runs during each life (a lease shorter than a life, as the
#             shipped 3 s lease was against any run longer than 3 s);
#   shipped:  the profiles' lease (20 s): no check runs in a life.
# Per lease: cycles done, processes that died in the assertion (SIGABRT), in another signal, and
# those that ran to the end. Prints figures only; exits 1 when the shipped lease lost a process.
#   bench/participant_churn_bench.sh [seconds] [procs]   (default 60 3)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bin="$root/${PMLSM_BIN_DIR:-build/bin}"
seconds="${1:-60}"
procs="${2:-3}"
for v in "$seconds" "$procs"; do
  [[ "$v" =~ ^[1-9][0-9]*$ ]] || { echo "participant_churn_bench: seconds and procs must be positive integers, got '$v'" >&2; exit 2; }
done
[ -x "$bin/participant_churn" ] || { echo "participant_churn_bench: no $bin/participant_churn (build it, or set PMLSM_BIN_DIR)" >&2; exit 2; }
work="$(mktemp -d)"
pids=()
cleanup() {
  for pid in ${pids[@]+"${pids[@]}"}; do kill "$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT
domain=$((150 + $$ % 50))
shipped_lost=0
for lease in 40 shipped; do
  lease_ms=0
  [ "$lease" = shipped ] || lease_ms="$lease"
  pids=()
  for i in $(seq 1 "$procs"); do
    # Bounded by `seconds`: the cycle count is out of reach; SIGINT ends it between two cycles.
    timeout --preserve-status --signal=INT "$seconds" "$bin/participant_churn" --domain "$domain" --cycles 1000000 --batch 6 \
      --life-ms 38 --lease-ms "$lease_ms" >"$work/$lease.$i.log" 2>&1 &
    pids+=("$!")
  done
  aborted=0 crashed=0 ran=0
  for pid in "${pids[@]}"; do
    rc=0
    wait "$pid" || rc=$?
    case "$rc" in
      0) ran=$((ran + 1)) ;;
      134) aborted=$((aborted + 1)) ;;
      *) crashed=$((crashed + 1)) ;;
    esac
  done
  pids=()
  asserts=$(cat "$work/$lease".*.log | grep -c "check_remote_participant_liveliness" || true)
  # Cycles of the processes that ran to the end (those that died print nothing).
  cycles=$(sed -n 's/^participant_churn: \([0-9]*\) cycles.*/\1/p' "$work/$lease".*.log | awk "{ s += \$1 } END { print s + 0 }")
  echo "lease $lease: $procs processes x $seconds s: $aborted aborted in the lease check ($asserts assertion lines), $crashed died otherwise, $ran ran to the end (${cycles:-0} cycles)"
  [ "$lease" = shipped ] && shipped_lost=$((aborted + crashed))
done
[ "$shipped_lost" -eq 0 ] || exit 1

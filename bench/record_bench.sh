#!/usr/bin/env bash
# Recording benchmark: `pmlsm record` on every topic of a realtime 1 kHz run (plant_sim,
# controller, kalman_estimator), then on a lockstep run in voltage mode (CurrentFeedback and
# VoltageCommand at 32 kHz). Prints lost samples, raw CDR bytes against the file (zstd), the
# size per hour, and the same run's file with lz4 for comparison.
#   bench/record_bench.sh [realtime_seconds]   (default 600, the 10-minute target)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="${PMLSM_BIN_DIR:-$root/build/bin}"
realtime_s="${1:-600}"
domain="${PMLSM_BENCH_DOMAIN:-77}"
work="$(mktemp -d /tmp/pmlsm_record_bench.XXXXXX)"
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; rm -rf "$work"; }
trap cleanup EXIT
cd "$root"

# One run: $1 label, $2 scenario, $3 compression, $4.. extra node args. Prints the recorder's summary line.
record_run() {
  local label="$1" scenario="$2" compression="$3"; shift 3
  "$bin/pmlsm" --domain "$domain" record -o "$work/$label.mcap" --compression "$compression" \
    --stop-after-idle-s 3 --no-progress >"$work/$label.record.log" 2>&1 &
  local recorder=$!; pids+=("$recorder")
  until grep -q "topics on domain" "$work/$label.record.log" 2>/dev/null; do sleep 0.05; done
  "$bin/kalman_estimator" --domain "$domain" -s "$scenario" "$@" >"$work/$label.estimator.log" 2>&1 &
  pids+=("$!")
  "$bin/controller" --domain "$domain" -s "$scenario" "$@" >"$work/$label.controller.log" 2>&1 &
  pids+=("$!")
  "$bin/plant_sim" --domain "$domain" -s "$scenario" --peers 3 "$@" >"$work/$label.plant.log" 2>&1 || true
  wait "$recorder" || true
  grep "^recorded " "$work/$label.record.log"
}

sed "s/^duration_s: .*/duration_s: ${realtime_s}.0/" configs/scenarios/pulse.yaml >"$work/long.yaml"
echo "[1/3] realtime 1 kHz, all topics, ${realtime_s} s, zstd"
zstd_line=$(record_run realtime_zstd "$work/long.yaml" zstd --clock realtime)
echo "  $zstd_line"
echo "[2/3] realtime 1 kHz, all topics, 60 s, lz4"
sed "s/^duration_s: .*/duration_s: 60.0/" configs/scenarios/pulse.yaml >"$work/minute.yaml"
lz4_line=$(record_run realtime_lz4 "$work/minute.yaml" lz4 --clock realtime)
echo "  $lz4_line"
echo "[3/3] lockstep voltage mode (32 kHz CurrentFeedback/VoltageCommand), pulse 2 s, zstd"
voltage_line=$(record_run voltage "configs/scenarios/pulse.yaml" zstd --command-level voltage)
echo "  $voltage_line"

file_bytes=$(stat -c %s "$work/realtime_zstd.mcap")
echo
printf '%-44s %s\n' "realtime ${realtime_s} s lost samples" "$(sed -n 's/.*, \([0-9]*\) lost;.*/\1/p' <<<"$zstd_line")"
printf '%-44s %s\n' "realtime zstd: raw CDR / file" "$(sed -n 's/.*(\([0-9.]*x\) smaller).*/\1/p' <<<"$zstd_line")"
printf '%-44s %s\n' "realtime lz4:  raw CDR / file" "$(sed -n 's/.*(\([0-9.]*x\) smaller).*/\1/p' <<<"$lz4_line")"
printf '%-44s %.1f MB\n' "zstd file size per hour of recording" "$(echo "$file_bytes * 3600 / $realtime_s / 1000000" | bc -l)"
printf '%-44s %s\n' "voltage mode (32 kHz) lost samples" "$(sed -n 's/.*, \([0-9]*\) lost;.*/\1/p' <<<"$voltage_line")"

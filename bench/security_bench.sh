#!/usr/bin/env bash
# DDS Security's cost on this machine, open and secure in one run: the lockstep real-time
# factor (launch/sim.yaml, 4 nodes), the realtime chain latency MotorFeedback -> ForceCommand
# p50/p99 (plant_sim + controller, as bench/distributed_bench.sh measures it), and the time
# from the drive's start until every peer matched (its own start-up, participant creation and,
# secure, the authentication handshakes included). Three set-ups: open; secure with payloads,
# discovery and liveliness encrypted and submessages unprotected (metadata_protection: none);
# the same with every submessage encrypted too (metadata_protection: encrypt); whole RTPS
# messages encrypted instead, payloads and submessages not on their own (rtps_protection:
# encrypt, data and metadata none: one cipher operation a datagram). Prints figures and ratios.
#   bench/security_bench.sh [realtime_seconds]   (default 20)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bin=build/bin
realtime_s="${1:-20}"
domain="${PMLSM_DOMAIN:-44}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

field() { sed -n "$1" "$2" | head -n 1; }
rtf_of() { field 's/.*ticks in [0-9.]* s (\([0-9.]*\)x real time).*/\1/p' "$1"; }
p50_of() { field 's/.*p50 \([0-9.]*\) us.*/\1/p' "$1"; }
p99_of() { field 's/.*p99 \([0-9.]*\) us.*/\1/p' "$1"; }
matched_of() { field 's/.*peers matched \([0-9.]*\) ms after start.*/\1/p' "$1"; }
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { if (a == "" || b == "" || b + 0 == 0) print "n/a"; else printf "%.3g", a / b }'; }

echo "[1/4] keystores from configs/security/policy.yaml: payload, full (the shipped one), rtps"
governance() {  # set-up, data, metadata, rtps protection
  sed -e "s/^  data_protection: [a-z]*/  data_protection: $2/" -e "s/^  metadata_protection: [a-z]*/  metadata_protection: $3/" \
    -e "s/^  rtps_protection: [a-z]*/  rtps_protection: $4/" configs/security/policy.yaml >"$work/policy_$1.yaml"
  "$bin/pmlsm" security create "$work/ks_$1" --policy "$work/policy_$1.yaml" >/dev/null
}
governance payload encrypt none none
governance full encrypt encrypt none
governance rtps none none encrypt
setups=(open payload full rtps)
keystore_of() { if [ "$1" = open ]; then echo none; else echo "$work/ks_$1"; fi; }

echo "[2/4] lockstep, force level, 4 nodes (launch/sim.yaml), each set-up"
for s in "${setups[@]}"; do
  "$bin/launcher" launch/sim.yaml --arg domain="$domain" --arg out="$work" --arg keystore="$(keystore_of "$s")" \
    >"$work/lockstep_$s.log" 2>&1 || echo "  lockstep $s: launch failed (see figures)"
done

echo "[3/4] realtime, plant_sim + controller, ${realtime_s} s each set-up"
sed "s/^duration_s: .*/duration_s: ${realtime_s}.0/" configs/scenarios/pulse.yaml >"$work/long.yaml"
for s in "${setups[@]}"; do
  ks="$(keystore_of "$s")"
  "$bin/controller" --domain "$domain" -s "$work/long.yaml" --clock realtime --plant-lost-ms 5000 --keystore "$ks" \
    >"$work/rt_${s}_controller.log" 2>&1 &
  controller_pid=$!
  "$bin/plant_sim" --domain "$domain" -s "$work/long.yaml" --clock realtime --peers 1 --keystore "$ks" \
    --watchdog-ms 1000 --controller-lost-ms 5000 >"$work/rt_$s.log" 2>&1 || true
  wait "$controller_pid" || true
done

echo "[4/4] figures"
echo
printf '%-44s %14s %14s %14s %14s\n' "figure" "open" "payload" "payload+meta" "rtps"
row() {  # label, extractor, file prefix
  printf '%-44s' "$1"
  for s in "${setups[@]}"; do printf ' %14s' "$("$2" "$work/$3_$s.log")"; done
  printf '\n'
}
row "lockstep real-time factor [x]" rtf_of lockstep
row "lockstep chain latency p50 [us]" p50_of lockstep
row "lockstep peers matched after start [ms]" matched_of lockstep
row "realtime chain latency p50 [us]" p50_of rt
row "realtime chain latency p99 [us]" p99_of rt
row "realtime peers matched after start [ms]" matched_of rt
echo
for s in payload full rtps; do
  printf '%-44s lockstep RTF %s, p50 %s, p99 %s, matched %s\n' "ratio $s / open:" \
    "$(ratio "$(rtf_of "$work/lockstep_$s.log")" "$(rtf_of "$work/lockstep_open.log")")" \
    "$(ratio "$(p50_of "$work/rt_$s.log")" "$(p50_of "$work/rt_open.log")")" \
    "$(ratio "$(p99_of "$work/rt_$s.log")" "$(p99_of "$work/rt_open.log")")" \
    "$(ratio "$(matched_of "$work/lockstep_$s.log")" "$(matched_of "$work/lockstep_open.log")")"
done
for f in "$work"/lockstep_*.log "$work"/rt_*.log; do
  if grep -q "security error" "$f"; then echo "$(basename "$f"): $(grep -m1 'security error' "$f")"; fi
done

#!/usr/bin/env bash
# launch/rig_split.yaml across two hosts in realtime: two network namespaces joined by a veth pair
# (each with its own /dev/shm, the UDP-only profile), the drive and the controller composed on
# "rig", estimator, compensator and evaluator on "ctrl". Three conditions, `runs` runs of `seconds`
# s each, alternating:
#   clean:     the link as it is;
#   loss:      `loss_pct` % of the packets entering either namespace dropped at random (nftables
#              `numgen random`);
#   partition: every packet between the hosts dropped for 300 ms, `seconds` / 2 into the run.
# Per condition: runs that did not end 0 on each host, watchdog trips, the compensation on time
# (share of ticks after the first one), late episodes after it and the longest gap (ticks), the
# chain latency p50 / max at the drive. Needs root (namespaces, nftables); prints figures only;
# exits 1 when a rig's run did not end 0 (ctrl's evaluator ends 4 on a run with ticks never estimated). PMLSM_BENCH_KEEP=1 keeps every host's log (the folder is printed).
# `inputs`: how the chain's inputs cross the link (the launch file's realtime_inputs): best_effort
# (its default) or reliable, to compare.
#   bench/rig_split_bench.sh [runs] [seconds] [loss_pct] [compensator] [inputs]   (default 5 10 2 rnn best_effort)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bin="$root/${PMLSM_BIN_DIR:-build/bin}"
runs="${1:-5}"
seconds="${2:-10}"
loss_pct="${3:-2}"
compensator="${4:-rnn}"
inputs="${5:-best_effort}"
[[ "$inputs" =~ ^(best_effort|reliable)$ ]] || { echo "rig_split_bench: inputs must be best_effort or reliable, got '$inputs'" >&2; exit 2; }
for v in "$runs" "$seconds" "$loss_pct"; do
  [[ "$v" =~ ^[0-9]+$ ]] || { echo "rig_split_bench: runs, seconds and loss_pct must be integers, got '$v'" >&2; exit 2; }
done
[ "$(id -u)" -eq 0 ] || { echo "rig_split_bench: network namespaces and nftables need root" >&2; exit 2; }
command -v nft >/dev/null || { echo "rig_split_bench: nft not found (scripts/install_deps.sh installs nftables)" >&2; exit 2; }
[ -x "$bin/launcher" ] || { echo "rig_split_bench: no $bin/launcher (build it, or set PMLSM_BIN_DIR)" >&2; exit 2; }
source bench/bench_lib.sh
work="$(mktemp -d)"
rig_ns="pmlsm_split_rig_$$"
ctrl_ns="pmlsm_split_ctrl_$$"
pids=()
cleanup() {
  for pid in ${pids[@]+"${pids[@]}"}; do kill "$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
  ip netns del "$rig_ns" 2>/dev/null || true
  ip netns del "$ctrl_ns" 2>/dev/null || true
  if [ -n "${PMLSM_BENCH_KEEP:-}" ]; then echo "rig_split_bench: logs kept in $work"; else rm -rf "$work"; fi
}
trap cleanup EXIT

# The two hosts.
subnet="10.232.$(($$ % 250))"
ip netns add "$rig_ns"
ip netns add "$ctrl_ns"
ip link add "vr$$" type veth peer name "vc$$"
ip link set "vr$$" netns "$rig_ns"
ip link set "vc$$" netns "$ctrl_ns"
setup_host() {  # NS VETH ADDRESS
  ip netns exec "$1" ip link set lo up
  ip netns exec "$1" ip addr add "$3/24" dev "$2"
  ip netns exec "$1" ip link set "$2" up multicast on
  ip netns exec "$1" ip route add 224.0.0.0/4 dev "$2"
  ip netns exec "$1" nft add table inet pmlsm_bench
  ip netns exec "$1" nft add chain inet pmlsm_bench input '{ type filter hook input priority 0; policy accept; }'
}
setup_host "$rig_ns" "vr$$" "$subnet.1"
setup_host "$ctrl_ns" "vc$$" "$subnet.2"
drop_at_random() {  # PCT: every packet entering either host over the veth dropped with this chance
  for ns in "$rig_ns" "$ctrl_ns"; do
    ip netns exec "$ns" nft add rule inet pmlsm_bench input iifname != lo numgen random mod 100 '<' "$1" drop
  done
}
drop_all() {
  for ns in "$rig_ns" "$ctrl_ns"; do ip netns exec "$ns" nft add rule inet pmlsm_bench input iifname != lo drop; done
}
restore_link() {
  for ns in "$rig_ns" "$ctrl_ns"; do ip netns exec "$ns" nft flush chain inet pmlsm_bench input; done
}

sed "s/^duration_s: .*/duration_s: ${seconds}.0/" configs/scenarios/pulse.yaml >"$work/long.yaml"
slice() {  # NS HOST LOG: that host's slice of the launch file, in its namespace, /dev/shm its own
  ip netns exec "$1" unshare --mount --propagation private sh -c "mount -t tmpfs tmpfs /dev/shm && exec \
    '$bin/launcher' '$root/launch/rig_split.yaml' --host $2 --arg domain=9 --arg profile=pmlsm_udp_only \
    --arg config='$root/configs/system.yaml' --arg scenario='$work/long.yaml' \
    --arg profiles='$root/configs/dds/profiles.xml' --arg weights='$root/configs/rnn_weights.yaml' \
    --arg out='$work' --arg compensator=$compensator --arg realtime_inputs=$inputs" >"$3" 2>&1
}

failed=0
echo "rig_split_bench: ${runs} runs of ${seconds} s per condition, compensator ${compensator}, ${inputs} inputs, namespaces ${rig_ns} / ${ctrl_ns}"
for i in $(seq "$runs"); do
  for condition in clean loss partition; do
    mkdir -p "$work/$condition"
    restore_link
    [ "$condition" = loss ] && drop_at_random "$loss_pct"
    slice "$ctrl_ns" ctrl "$work/$condition/ctrl_$i.log" &
    ctrl_pid=$!
    pids+=("$ctrl_pid")
    slice "$rig_ns" rig "$work/$condition/rig_$i.log" &
    rig_pid=$!
    pids+=("$rig_pid")
    if [ "$condition" = partition ]; then
      deadline=$((SECONDS + 60))
      until grep -q "peers matched" "$work/$condition/rig_$i.log" 2>/dev/null || ((SECONDS >= deadline)); do sleep 0.05; done
      sleep "$(awk -v s="$seconds" 'BEGIN { print s / 2 }')"
      drop_all
      sleep 0.3
      restore_link
    fi
    rig_code=0; wait "$rig_pid" || rig_code=$?
    ctrl_code=0; wait "$ctrl_pid" || ctrl_code=$?
    pids=()
    echo "$rig_code $ctrl_code" >"$work/$condition/codes_$i"
    if [ "$rig_code" -ne 0 ]; then failed=1; fi
    log="$work/$condition/rig_$i.log"
    printf '  %-9s run %d: exit rig %s ctrl %s, p50 %s us, max %s us, %s\n' "$condition" "$i" "$rig_code" "$ctrl_code" \
      "$(p50_of "$log")" "$(max_of "$log")" \
      "$(sed -n 's/.*compensation [a-z]* (\([0-9]* ticks without;.*\)).*/\1/p' "$log" | head -n 1)"
  done
done
restore_link

echo
printf '%-10s %-9s %-10s %-6s %-24s %-9s %-13s %-12s %s\n' condition "rig !=0" "ctrl !=0" trips "comp. on time (worst)" episodes "longest gap" "p50 us" "max us (worst)"
for condition in clean loss partition; do
  bad_rig=$(cut -d' ' -f1 "$work/$condition"/codes_* | grep -vc '^0$' || true)
  bad_ctrl=$(cut -d' ' -f2 "$work/$condition"/codes_* | grep -vc '^0$' || true)
  trips=$(cat "$work/$condition"/rig_*.log | grep -c "watchdog: tick" || true)
  ticks=$((seconds * 1000))
  # After the start (the first compensation on time): the share of ticks with one at most 3 ticks old.
  on_time=$(cat "$work/$condition"/rig_*.log |
    sed -n 's/.*compensation [a-z]* (\([0-9]*\) ticks without; at the start \([0-9]*\),.*/\1 \2/p' |
    awk -v t="$ticks" '{ s = 100 * (1 - ($1 - $2) / (t - $2)); if (NR == 1 || s < m) m = s; sum += s }
      END { if (NR) printf "%.2f %% (%.2f %%)", sum / NR, m; else print "n/a" }')
  episodes=$(cat "$work/$condition"/rig_*.log | sed -n 's/.*then late \([0-9]*\) times.*/\1/p' | awk '{ s += $1 } END { print s + 0 }')
  longest=$(cat "$work/$condition"/rig_*.log | sed -n 's/.*the longest \([0-9]*\) ticks.*/\1/p' | sort -n | tail -n 1)
  p50=$(for f in "$work/$condition"/rig_*.log; do p50_of "$f"; done | sort -g | awk '{ v[NR] = $1 } END { if (NR) print v[int((NR + 1) / 2)]; else print "n/a" }')
  mx=$(for f in "$work/$condition"/rig_*.log; do max_of "$f"; done | sort -g | tail -n 1)
  printf '%-10s %-9s %-10s %-6s %-24s %-9s %-13s %-12s %s\n' "$condition" "$bad_rig" "$bad_ctrl" "$trips" "$on_time" "$episodes" "${longest:-n/a} ticks" "$p50" "$mx"
done
echo "(comp. on time: after the first compensation, the share of ticks with one at most 3 ticks old, mean and worst"
echo " run; episodes: summed over the runs; partition: 300 ms = 300 ticks; ctrl !=0: its evaluator misses ticks that"
echo " were never estimated, a lost feedback or a partition, and says so with exit 4)"
exit "$failed"

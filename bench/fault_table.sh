#!/usr/bin/env bash
# The drive's safety behaviour with real processes, in one run (realtime clock,
# plant_sim and controller tuned as a rig runs them: SCHED_FIFO 80, memory
# locked, cores kept out of idle states, the plant polling the clock for the
# last 100 us before each tick; needs root):
#   1. a controller SIGKILLed mid-run: kill -> zero force (the plant's 3 ms
#      watchdog) and kill -> controller lost (its 50 ms timeout), `kills` times;
#   2. fault-free starts: how many of 20 short runs trip the watchdog, tuned
#      and with normal scheduling;
#   3. a plant SIGKILLed mid-run: kill -> the controller's "plant lost" (its
#      50 ms timeout), `kills` times;
#   4. the fault table: the 4-node system, each node SIGKILLed in turn in a
#      fresh system; who notices, how fast, what the drive does, exit codes;
#      then the same system with no kill, as a control.
# Delays are the [wall ...] stamp (CLOCK_REALTIME) of a node's log line minus
# the time taken just before `kill -9` ($EPOCHREALTIME, the same clock, read
# without forking). Prints figures only; it asserts nothing.
#   bench/fault_table.sh [kills]   (default 10; PMLSM_DOMAIN: DDS domain, default 45)
set -euo pipefail
export LC_ALL=C
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bin=build/bin
kills="${1:-10}"
domain="${PMLSM_DOMAIN:-45}"
starts=20
survive_s=15
work="$(mktemp -d)"

echo "command: $0 $*  (PMLSM_DOMAIN=$domain)"
echo "date:    $(date -u '+%Y-%m-%d %H:%M:%S UTC') on $(hostname), $(nproc) cores"

# Every process this script starts: its PID and its start time (field 22 of
# /proc/PID/stat). Bash reaps its children by itself and keeps their exit
# codes for `wait`, so a PID may be reused once its process ended: a PID is
# signalled only while its start time is still the recorded one.
started=()
declare -A start_of=()
# stat_fields PID: the fields of /proc/PID/stat from the state on, in ${stat_f[@]}.
stat_fields() {
  local line
  stat_f=()
  { read -r line <"/proc/$1/stat"; } 2>/dev/null || return 1
  read -r -a stat_f <<<"${line##*) }"
}
# ours PID: the process we started under this PID still exists (maybe a zombie).
ours() {
  stat_fields "$1" && [ "${stat_f[19]}" = "${start_of[$1]:-}" ]
}
# running PID: the process we started has not exited yet.
running() {
  ours "$1" && [ "${stat_f[0]}" != "Z" ]
}
forget() {
  local keep=() p
  for p in "${started[@]}"; do [ "$p" = "$1" ] || keep+=("$p"); done
  started=("${keep[@]+"${keep[@]}"}")
}
cleanup() {
  local p
  for p in "${started[@]+"${started[@]}"}"; do ours "$p" && kill -9 "$p" 2>/dev/null || true; done
  for p in "${started[@]+"${started[@]}"}"; do wait "$p" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# A sleep without forking: a read that times out on a pipe nobody writes to.
exec {nap_fd}<> <(:)
nap() { read -r -t "$1" -u "$nap_fd" _ || true; }

# launch VAR LOG PROGRAM ARGS...: start a node in the background, its PID in VAR.
launch() {
  local var="$1" log="$2"; shift 2
  : >"$log"
  "$@" >"$log" 2>&1 &
  started+=("$!")
  start_of[$!]="gone"
  stat_fields "$!" && start_of[$!]="${stat_f[19]}"
  printf -v "$var" '%s' "$!"
}
# signal SIG PID: send SIG to a process of ours that is still running.
signal() { if running "$2"; then kill "-$1" "$2" 2>/dev/null || true; fi; }
# reap PID: wait for it (it must have exited or be about to), exit code in $rc.
reap() {
  rc=0
  wait "$1" 2>/dev/null || rc=$?
  forget "$1"
}
# now_us: $now, CLOCK_REALTIME in integer microseconds (no fork).
now_us() { local t=$EPOCHREALTIME; now=$((10#${t/./})); }
# wait_line LOG PATTERN TIMEOUT_S PID: poll LOG until PATTERN shows, PID dies
# or the deadline passes; status 0 only when the line showed.
wait_line() {
  local deadline
  now_us; deadline=$((now + $3 * 1000000))
  while :; do
    grep -q -- "$2" "$1" && return 0
    running "$4" || { grep -q -- "$2" "$1"; return; }
    now_us; [ "$now" -lt "$deadline" ] || return 1
    nap 0.01
  done
}
# wait_exit PID TIMEOUT_S: poll until PID exits (then reaped: $rc, $t_end) or the
# deadline passes (status 1, still running).
wait_exit() {
  local deadline
  now_us; deadline=$((now + $2 * 1000000))
  while running "$1"; do
    now_us; [ "$now" -lt "$deadline" ] || return 1
    nap 0.01
  done
  t_end=$EPOCHREALTIME
  reap "$1"
}
# stop PID: SIGINT, up to 5 s to end, then SIGKILL; $rc is its exit code.
stop() {
  signal INT "$1"
  if ! wait_exit "$1" 5; then signal KILL "$1"; reap "$1"; fi
}

# wall_of LINE: the [wall S s] stamp of a log line, or nothing.
wall_of() { sed -n 's/.*\[wall \([0-9.]*\) s\].*/\1/p' <<<"$1"; }
# ms_since T0 T1: (T1 - T0) in ms with one decimal, "n/a" without T1.
ms_since() { awk -v a="$1" -v b="$2" 'BEGIN { if (b == "") print "n/a"; else printf "%.1f", (b - a) * 1e3 }'; }
# stats VALUES...: "min X, median Y, max Z" over the numeric values (n/a skipped).
stats() {
  printf '%s\n' "$@" | awk '$1 ~ /^-?[0-9.]+$/' | sort -g | awk '
    { v[n++] = $1 }
    END {
      if (n == 0) { print "no values"; exit }
      med = (n % 2) ? v[int(n / 2)] : (v[n / 2 - 1] + v[n / 2]) / 2
      printf "min %.1f, median %.1f, max %.1f (%d values)", v[0], med, v[n - 1], n
    }'
}
# count_within LIMIT VALUES...: how many values are at most LIMIT.
count_within() {
  local limit="$1"; shift
  printf '%s\n' "$@" | awk -v l="$limit" '$1 ~ /^-?[0-9.]+$/ && $1 + 0 <= l { n++ } END { print n + 0 }'
}

# Scenarios: copies of the pulse test, only the duration (and the cost window,
# which must not exceed it) changed.
scenario() {  # scenario FILE DURATION_S
  local window=1.0
  awk -v d="$2" 'BEGIN { exit !(d < 1.0) }' && window="$2"
  sed -e "s/^duration_s: {value: [0-9.]*/duration_s: {value: $2/" \
      -e "s/^cost_window_s: {value: [0-9.]*/cost_window_s: {value: $window/" \
      configs/scenarios/pulse.yaml >"$1"
}
scenario "$work/long.yaml" 30.0
scenario "$work/short.yaml" 0.5
scenario "$work/system.yaml" 20.0

common() {  # common SCENARIO: the options every node takes
  node_opts=(--domain "$domain" --config configs/system.yaml --scenario "$1"
             --profiles configs/dds/profiles.xml --clock realtime)
}
tuned=(--rt-priority 80 --cpu-dma-latency-us 0)
plant_tuned=("${tuned[@]}" --wake-early-us 100)

# ---------------------------------------------------------------------------
# Parts 1 and 3: plant_sim + controller on the 30 s scenario, tuned; one of the
# two SIGKILLed 0.3 s after the watchdog armed.
# pair_kill VICTIM(controller|plant_sim) INDEX: logs in $work/pair_<victim>_<i>_*.log,
# the kill time in $t_kill, the survivor's exit code in $survivor_rc.
pair_kill() {
  local victim="$1" i="$2" prefix="$work/pair_${1}_${2}" controller plant survivor jitter
  common "$work/long.yaml"
  launch controller "${prefix}_controller.log" "$bin/controller" "${node_opts[@]}" "${tuned[@]}"
  launch plant "${prefix}_plant.log" "$bin/plant_sim" "${node_opts[@]}" --peers 1 "${plant_tuned[@]}"
  t_kill=""; survivor_rc="n/a"
  if ! wait_line "${prefix}_plant.log" "watchdog armed" 20 "$plant"; then
    echo "  kill $i: the plant's watchdog never armed; not killed"
    stop "$plant"; stop "$controller"
    return 1
  fi
  # 0.3 s plus 0 to 999 us, so the kills fall at every phase of the 1 ms tick.
  printf -v jitter '0.300%03d' $((RANDOM % 1000))
  nap "$jitter"
  if [ "$victim" = controller ]; then survivor="$plant"; victim="$controller"; else survivor="$controller"; victim="$plant"; fi
  if ! running "$victim"; then
    echo "  kill $i: the $1 had ended before the kill; not killed"
    reap "$victim"; stop "$survivor"
    return 1
  fi
  t_kill=$EPOCHREALTIME
  kill -9 "$victim"
  reap "$victim"
  if wait_exit "$survivor" 40; then survivor_rc="$rc"; else survivor_rc="running at +40 s"; stop "$survivor"; fi
}

echo "[1/4] controller SIGKILLed, ${kills} times (plant_sim + controller tuned, watchdog 3 ms, controller lost 50 ms)"
zero_ms=(); lost_ms=(); pre_tripped=0
for i in $(seq 1 "$kills"); do
  pair_kill controller "$i" || { zero_ms+=("n/a"); lost_ms+=("n/a"); continue; }
  log="$work/pair_controller_${i}_plant.log"
  wd_line=$(grep -m1 "plant_sim: watchdog:" "$log" || true)
  cl_line=$(grep -m1 "controller lost" "$log" || true)
  z=$(ms_since "$t_kill" "$(wall_of "$wd_line")"); l=$(ms_since "$t_kill" "$(wall_of "$cl_line")")
  lost_ms+=("$l")
  note=""
  if awk -v z="$z" 'BEGIN { exit !(z != "n/a" && z + 0 < 0) }'; then
    # The force was already zero when the controller died: no kill -> zero force figure.
    note=" (the watchdog had tripped before the kill: not counted)"
    pre_tripped=$((pre_tripped + 1))
    zero_ms+=("n/a")
  else
    zero_ms+=("$z")
  fi
  printf '  kill %2d: kill -> zero force %7s ms, kill -> controller lost %7s ms, plant exit %s%s\n' \
    "$i" "$z" "$l" "$survivor_rc" "$note"
done

echo "[2/4] fault-free starts: ${starts} runs of plant_sim + controller on a 0.5 s pulse, tuned, then ${starts} untuned"
# start_runs NAME [options for both] -- [options for the plant only]: sets
# $trips (runs with a watchdog line) and $codes (exit codes seen, with counts).
start_runs() {
  local name="$1" both=() plant_only=() controller plant i prc crc
  shift
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do both+=("$1"); shift; done
  [ $# -gt 0 ] && shift
  plant_only=("$@")
  common "$work/short.yaml"
  trips=0; bad=0
  : >"$work/${name}_codes"
  for i in $(seq 1 "$starts"); do
    launch controller "$work/${name}_${i}_controller.log" "$bin/controller" "${node_opts[@]}" "${both[@]+"${both[@]}"}"
    launch plant "$work/${name}_${i}_plant.log" "$bin/plant_sim" "${node_opts[@]}" --peers 1 \
      "${both[@]+"${both[@]}"}" "${plant_only[@]+"${plant_only[@]}"}"
    if wait_exit "$plant" 30; then prc="$rc"; else prc="running at +30 s"; stop "$plant"; fi
    if wait_exit "$controller" 30; then crc="$rc"; else crc="running at +30 s"; stop "$controller"; fi
    grep -q "plant_sim: watchdog:" "$work/${name}_${i}_plant.log" && trips=$((trips + 1))
    [ "$prc" = 0 ] && [ "$crc" = 0 ] || bad=$((bad + 1))
    echo "plant_sim $prc" >>"$work/${name}_codes"
    echo "controller $crc" >>"$work/${name}_codes"
  done
  codes=$(sort "$work/${name}_codes" | uniq -c | awk '
    { node = $2; code = $3; for (i = 4; i <= NF; i++) code = code " " $i
      s[node] = s[node] (s[node] == "" ? "" : ", ") "exit " code " x" $1 }
    END { printf "plant_sim %s; controller %s", s["plant_sim"], s["controller"] }')
}
start_runs starts_tuned "${tuned[@]}" -- --wake-early-us 100
tuned_trips=$trips; tuned_bad=$bad; tuned_codes=$codes
start_runs starts_untuned
untuned_trips=$trips; untuned_bad=$bad; untuned_codes=$codes

echo "[3/4] plant_sim SIGKILLed, ${kills} times (plant_sim + controller tuned, controller's plant lost after 50 ms)"
plost_ms=()
for i in $(seq 1 "$kills"); do
  pair_kill plant_sim "$i" || { plost_ms+=("n/a"); continue; }
  log="$work/pair_plant_sim_${i}_controller.log"
  pl_line=$(grep -m1 "plant lost" "$log" || true)
  p=$(ms_since "$t_kill" "$(wall_of "$pl_line")")
  plost_ms+=("$p")
  printf '  kill %2d: kill -> controller notices plant lost %7s ms, controller exit %s\n' "$i" "$p" "$survivor_rc"
done

echo "[4/4] fault table: evaluator, kalman_estimator, controller, plant_sim --peers 3 (plant and controller tuned), 20 s pulse;"
echo "      each node SIGKILLed in a fresh system 1 s after the watchdog armed, survivors given ${survive_s} s; then a control run, no kill"
nodes=(plant_sim controller kalman_estimator evaluator)
# The last system is killed nowhere: a control run, to tell what the kills
# cause from what this host does to the realtime system by itself.
short_name() {
  case "$1" in plant_sim) echo plant;; controller) echo controller;; kalman_estimator) echo estimator;; evaluator) echo evaluator;; esac
}
# What a notice line says, in a few words.
label_of() {
  case "$1" in
    *"watchdog:"*) echo "watchdog";;
    *"controller lost"*) echo "controller lost";;
    *"plant lost"*) echo "plant lost";;
    *" only "*) sed -n 's/.* \(only [0-9]* of [0-9]* ticks complete\).*/\1/p' <<<"$1";;
    *restarted*) echo "drive restarted";;
    *) echo "?";;
  esac
}
table_rows=(); details=(); system=0
for victim in "${nodes[@]}" none; do
  tag="$victim killed"; [ "$victim" = none ] && tag="control run (no kill)"
  echo "  system $((++system)) of 5: $tag"
  common "$work/system.yaml"
  declare -A pid=() rc_of=() end_of=() lines_of=()
  prefix="$work/sys_${victim}"
  launch p "${prefix}_evaluator.log" "$bin/evaluator" "${node_opts[@]}" --out "$work/out_${victim}"
  pid[evaluator]=$p
  launch p "${prefix}_kalman_estimator.log" "$bin/kalman_estimator" "${node_opts[@]}"
  pid[kalman_estimator]=$p
  launch p "${prefix}_controller.log" "$bin/controller" "${node_opts[@]}" "${tuned[@]}"
  pid[controller]=$p
  launch p "${prefix}_plant_sim.log" "$bin/plant_sim" "${node_opts[@]}" --peers 3 "${plant_tuned[@]}"
  pid[plant_sim]=$p
  if ! wait_line "${prefix}_plant_sim.log" "watchdog armed" 30 "${pid[plant_sim]}"; then
    table_rows+=("| $victim | (not run: the plant's watchdog never armed) | | | |")
    for n in "${nodes[@]}"; do if running "${pid[$n]}"; then stop "${pid[$n]}"; else reap "${pid[$n]}"; fi; done
    continue
  fi
  nap 1.0
  if [ "$victim" != none ] && ! running "${pid[$victim]}"; then
    table_rows+=("| $victim | (not run: $victim had ended before the kill) | | | |")
    for n in "${nodes[@]}"; do if running "${pid[$n]}"; then stop "${pid[$n]}"; else reap "${pid[$n]}"; fi; done
    unset pid rc_of end_of lines_of
    continue
  fi
  t_kill=$EPOCHREALTIME
  if [ "$victim" != none ]; then
    kill -9 "${pid[$victim]}"
    reap "${pid[$victim]}"
  fi
  survivors=()
  for n in "${nodes[@]}"; do [ "$n" = "$victim" ] || survivors+=("$n"); done
  # Watch the survivors end on their own, up to survive_s after the kill.
  deadline=$((10#${t_kill/./} + survive_s * 1000000))
  while :; do
    alive=0
    for n in "${survivors[@]}"; do
      [ -n "${rc_of[$n]+x}" ] && continue
      if running "${pid[$n]}"; then alive=1; else t_end=$EPOCHREALTIME; reap "${pid[$n]}"; rc_of[$n]=$rc; end_of[$n]=$t_end; fi
    done
    [ "$alive" = 0 ] && break
    now_us; [ "$now" -lt "$deadline" ] || break
    nap 0.01
  done
  # Only what the survivors wrote before any SIGINT of ours counts.
  for n in "${survivors[@]}"; do lines_of[$n]=$(wc -l <"${prefix}_${n}.log"); done
  # Those still running get SIGINT all at once, as the launcher would send it.
  for n in "${survivors[@]}"; do [ -n "${rc_of[$n]+x}" ] || signal INT "${pid[$n]}"; done
  for n in "${survivors[@]}"; do
    [ -n "${rc_of[$n]+x}" ] && continue
    if wait_exit "${pid[$n]}" 5; then
      rc_of[$n]="still running at +${survive_s} s, SIGINT: exit $rc"
    else
      signal KILL "${pid[$n]}"; reap "${pid[$n]}"
      rc_of[$n]="still running at +${survive_s} s, and 5 s after SIGINT: SIGKILLed"
    fi
  done

  # Who noticed, how fast.
  notices=(); first_ms=""; exits=()
  for n in "${survivors[@]}"; do
    log="${prefix}_${n}.log"
    seen=$(head -n "${lines_of[$n]}" "$log" | grep -E "lost|watchdog|only|restarted" | grep -v "watchdog armed" || true)
    if [ "$n" = plant_sim ]; then
      # The drive's two stages: the watchdog (zero force), then controller lost.
      first=$( (grep -m1 "watchdog:" <<<"$seen" || true); (grep -m1 "controller lost" <<<"$seen" || true) )
    else
      first=$(head -n 1 <<<"$seen")
    fi
    said=()
    while IFS= read -r line; do
      [ -n "$line" ] || continue
      d=$(ms_since "$t_kill" "$(wall_of "$line")")
      if [ "$d" = "n/a" ]; then said+=("$(label_of "$line"), no stamp"); else said+=("$(label_of "$line") $d ms"); fi
      if [ "$d" != "n/a" ] && { [ -z "$first_ms" ] || awk -v a="$d" -v b="$first_ms" 'BEGIN { exit !(a + 0 < b + 0) }'; }; then
        first_ms="$d"; first_who="$n"
      fi
      details+=("  $tag: $n: $line  -> delay $d ms")
    done <<<"$first"
    if [ "$(wc -l <"$log")" -gt "${lines_of[$n]}" ]; then
      after=$(tail -n +"$((lines_of[$n] + 1))" "$log" | grep -m1 -E "lost|watchdog|only|restarted" || true)
      [ -n "$after" ] && details+=("  $tag: $n, after our SIGINT at +${survive_s} s: $after")
    fi
    if [ ${#said[@]} -gt 0 ]; then
      joined=$(printf '%s, then ' "${said[@]}"); notices+=("$n (${joined%, then })")
    else
      details+=("  $tag: $n: no line with lost/watchdog/only/restarted before +${survive_s} s")
    fi
    if [ -n "${end_of[$n]+x}" ]; then
      exits+=("$(short_name "$n") ${rc_of[$n]} (ended +$(awk -v a="$t_kill" -v b="${end_of[$n]}" 'BEGIN { printf "%.2f", b - a }') s)")
    else
      exits+=("$(short_name "$n") ${rc_of[$n]}")
    fi
  done
  who=$(printf '%s; ' "${notices[@]+"${notices[@]}"}"); who="${who%; }"; [ -n "$who" ] || who="nobody"
  silent=()
  for n in "${survivors[@]}"; do
    grep -q "^$n (" <<<"$(printf '%s\n' "${notices[@]+"${notices[@]}"}")" || silent+=("$n")
  done
  if [ -n "$first_ms" ]; then fast="first: $first_who after $first_ms ms"; else fast="no stamped notice"; fi
  [ ${#silent[@]} -gt 0 ] && fast="$fast; not noticed by $(printf '%s, ' "${silent[@]}" | sed 's/, $//')"

  # What the drive does, from the plant's own lines.
  plog="${prefix}_plant_sim.log"
  if [ "$victim" = plant_sim ]; then
    drive="n/a: the drive itself was killed"
  else
    state=$(sed -n 's/.*safe ticks [0-9]*, drive \(.*\)$/\1/p' "$plog" | head -n 1)
    summary=$(sed -n 's/^plant_sim: \([0-9]* ticks\) in .*/\1/p' "$plog" | head -n 1)
    wd=$(head -n "${lines_of[plant_sim]}" "$plog" | grep -m1 "watchdog:" || true)
    cl=$(head -n "${lines_of[plant_sim]}" "$plog" | grep -m1 "controller lost" || true)
    if [ -n "$wd" ]; then
      drive="fault $(sed -n 's/.*fault \(0x[0-9a-f]*\).*/\1/p' <<<"$wd"), zero force"
      [ -n "$cl" ] && drive="$drive, then controller lost"
    elif [ -n "$cl" ]; then
      drive="controller lost, no watchdog trip"
    elif [ -n "${end_of[plant_sim]+x}" ]; then
      drive="keeps running to the end"
    else
      drive="keeps running (still at +${survive_s} s)"
    fi
    drive="$drive; ${summary:-?} in all, ends in ${state:-?}"
  fi
  label="$victim"; [ "$victim" = none ] && label="none (control run, same system)"
  table_rows+=("| $label | $who | $fast | $drive | $(printf '%s, ' "${exits[@]}" | sed 's/, $//') |")
  unset pid rc_of end_of lines_of
done

echo
echo "== 1. controller SIGKILLed, ${kills} times: kill -> zero force (watchdog 3 ms; target at most watchdog + 1 tick = 4 ms)"
echo "kill -> zero force (ms)          $(stats "${zero_ms[@]}"); $(count_within 4.0 "${zero_ms[@]}") of them within 4 ms"
[ "$pre_tripped" -gt 0 ] && echo "  (${pre_tripped} of ${kills} kills found the force already zero: the watchdog had tripped before the kill)"
echo "kill -> controller lost (ms)     $(stats "${lost_ms[@]}")"
echo
echo "== 2. fault-free starts (0.5 s pulse, plant_sim + controller)"
echo "tuned:    ${tuned_trips} of ${starts} starts tripped the watchdog; ${tuned_bad} of ${starts} had a non-zero exit; ${tuned_codes}"
echo "untuned:  ${untuned_trips} of ${starts} starts tripped the watchdog; ${untuned_bad} of ${starts} had a non-zero exit; ${untuned_codes}"
echo
echo "== 3. plant_sim SIGKILLed, ${kills} times: kill -> controller's plant lost (timeout 50 ms)"
echo "kill -> plant lost (ms)          $(stats "${plost_ms[@]}")"
echo
echo "== 4. fault table (realtime, 4 nodes; delays from the kill to the [wall] stamp of each node's line; exit codes: 0 ok, 4 peer lost, 5 force off)"
echo "| node killed | who notices | how fast | what the drive does | exit codes |"
echo "|---|---|---|---|---|"
printf '%s\n' "${table_rows[@]}"
echo
echo "(in the control run, delays count from the moment a node would have been killed)"
control_wd=$(grep -m1 "watchdog:" "$work/sys_none_plant_sim.log" 2>/dev/null || true)
if [ -n "$control_wd" ]; then
  echo "the control run, with no kill, tripped the watchdog as well ($(ms_since "$t_kill" "$(wall_of "$control_wd")") ms after the would-be kill):"
  echo "a trip in the other rows need not come from their kill"
fi
echo "the lines behind the table (first line with lost/watchdog/only/restarted per survivor):"
printf '%s\n' "${details[@]}"

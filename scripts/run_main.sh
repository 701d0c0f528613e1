#!/usr/bin/env bash
# The main job: installs what is missing, builds, and runs the simulated
# system as separate DDS processes (lockstep clock) on the paper's two
# scenarios, four ways: PI only (launch/sim.yaml), PI + load-acceleration
# feedback (launch/sim_accel.yaml), PI + the Jordan RNN (launch/sim_rnn.yaml) and PI +
# model-following state feedback (launch/sim_state.yaml).
# Prints the comparison table and plots out/pulse.png, out/free_vibration.png
# and (after a training run) out/training.png. The pulse PI + RNN run is also recorded
# (out/pulse_pi_rnn.mcap, `pmlsm record`) and plotted from the recording (`pmlsm plot`).
#
# The RNN's weights: configs/rnn_weights.yaml, made by de_trainer (docs/rnn.md gives the command
# and why CMA-ES; the file's source says what it ran with). With --train the weights are made again first with
# configs/training.yaml (the paper's DE, 52,000 closed-loop runs) into out/. PMLSM_DOMAIN picks the
# DDS domain (default 42); other arguments go to the launcher (e.g. --arg clock=realtime).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
train=false
launcher_args=()
for a in "$@"; do
  if [ "$a" = "--train" ]; then train=true; else launcher_args+=("$a"); fi
done
PROGRESS_NAME=run_main
. "$root/scripts/progress.sh"
t_start=$SECONDS
# Phases, each announced with how far along it is: packages, build, the 12 distributed runs, plots.
phase_start "[1/4] packages" "Debian packages and npm packages the project needs (scripts/install_deps.sh)"
"$root/scripts/install_deps.sh"
phase_end
phase_start "[2/4] build" "about 6 minutes the first time on 2 cores, seconds after that (scripts/build.sh)"
"$root/scripts/build.sh"
phase_end
cd "$root"
mkdir -p out
domain="${PMLSM_DOMAIN:-42}"
weights=configs/rnn_weights.yaml
history=configs/rnn_weights.history.csv
if [ "$train" = true ]; then
  echo "run_main: training the weights again first (--train: the paper's DE, about 3 minutes)" >&2
  ./build/bin/de_trainer --out out/rnn_weights.yaml --domain "$domain"
  weights=out/rnn_weights.yaml
  history=out/rnn_weights.yaml.history.csv
fi

phase_start "[3/4] runs" "2 scenarios x 4 systems over DDS, the same 8 on the virtual CANopen rig and the virtual EtherCAT rig, then the pulse over 21 nudged plants on both rigs"
run=0
runs=108
header=true
for scenario in pulse free_vibration; do
  for variant in sim sim_accel sim_rnn sim_state; do
    run=$((run + 1))
    echo "run_main: run $run/$runs: $scenario, launch/$variant.yaml ($((SECONDS - t_start)) s since start)" >&2
    log="out/${scenario}_${variant}.launch.log"
    extra=()
    [ "$variant" = sim_rnn ] && extra=(--arg weights="$weights")
    recorder=
    if [ "$scenario/$variant" = pulse/sim_rnn ]; then
      # This run is also recorded (every topic, MCAP) and plotted from the recording.
      ./build/bin/pmlsm --domain "$domain" record -o out/pulse_pi_rnn.mcap --stop-after-idle-s 2 --no-progress \
        >out/pulse_pi_rnn.record.log 2>&1 &
      recorder=$!
      until grep -q "topics on domain" out/pulse_pi_rnn.record.log 2>/dev/null; do sleep 0.05; done
    fi
    if ! ./build/bin/launcher "launch/$variant.yaml" --arg scenario="configs/scenarios/$scenario.yaml" \
         --arg out=out --arg domain="$domain" --arg header="$header" "${extra[@]}" \
         "${launcher_args[@]+"${launcher_args[@]}"}" >"$log" 2>&1; then
      cat "$log" >&2
      echo "run_main: the $scenario run of launch/$variant.yaml failed (log above, also in $log)" >&2
      exit 1
    fi
    sed -n 's/^\[evaluator\] //p' "$log"
    if [ -n "$recorder" ]; then
      wait "$recorder" || { cat out/pulse_pi_rnn.record.log >&2; echo "run_main: the recorder failed" >&2; exit 1; }
      recording_summary=$(grep "^recorded " out/pulse_pi_rnn.record.log)
      ./build/bin/pmlsm plot out/pulse_pi_rnn.mcap -o out/pulse_pi_rnn_plots >/dev/null
    fi
    header=false
  done
done
echo "cost = sum over the first second of |V_ref - v_L| (eq. 23), true and Kalman-estimated v_L (the paper's best: 5.6)"

# The same eight runs on the virtual rigs: drive_bridge (the CiA 402 master) and virtual_drive (the
# simulated drive behind a CiA 402 slave) on the UDP multicast CAN bus (launch/virtual_rig.yaml),
# and over EtherCAT on UDP (launch/virtual_rig_ethercat.yaml).
mkdir -p out/virtual_rig out/virtual_rig_ethercat
echo
echo "virtual rigs (CANopen and EtherCAT, lockstep) next to the simulated drive: true cost and 2 % settling time [s]"
printf '%-15s %-6s %10s %11s %10s %11s %8s %10s %11s %8s\n' scenario comp sim_cost sim_settle can_cost can_settle diff_% ecat_cost ecat_settle diff_%
# Rows: scenario label cost_true cost_est vib track settle|"not settled" ...
row() { sed -n "s/^\[\(evaluator\|chain\)\] \($scenario .*\)/\2/p" "$1" | awk '{s = ($7 == "not") ? "not_settled" : $7; print $3, s}'; }
for scenario in pulse free_vibration; do
  for comp in none accel rnn state; do
    case $comp in none) variant=sim ;; accel) variant=sim_accel ;; rnn) variant=sim_rnn ;; state) variant=sim_state ;; esac
    read -r sim_cost sim_settle < <(row "out/${scenario}_${variant}.launch.log")
    cells=()
    for rig in virtual_rig virtual_rig_ethercat; do
      run=$((run + 1))
      echo "run_main: run $run/$runs: $scenario, launch/$rig.yaml, compensator $comp ($((SECONDS - t_start)) s since start)" >&2
      log="out/$rig/${scenario}_${comp}.launch.log"
      if ! ./build/bin/launcher "launch/$rig.yaml" --arg scenario="configs/scenarios/$scenario.yaml" \
           --arg out="out/$rig" --arg domain="$domain" --arg compensator="$comp" --arg weights="$weights" \
           --arg label="rig_$comp" >"$log" 2>&1; then
        cat "$log" >&2
        echo "run_main: the $scenario run of launch/$rig.yaml (compensator $comp) failed (log above, also in $log)" >&2
        exit 1
      fi
      read -r rig_cost rig_settle < <(row "$log")
      diff=$(awk -v a="$sim_cost" -v b="$rig_cost" 'BEGIN { printf "%+.2f", 100 * (b - a) / a }')
      cells+=("$rig_cost" "$rig_settle" "$diff")
    done
    printf '%-15s %-6s %10s %11s %10s %11s %8s %10s %11s %8s\n' "$scenario" "$comp" "$sim_cost" "$sim_settle" "${cells[@]}"
  done
done
echo "the torque (per mille of 675 N) and position (1 um) on the bus are the only difference; logs in out/virtual_rig/ and out/virtual_rig_ethercat/"

# A compensated pulse's cost depends on the trace's last digits (the encoder's 1 um steps and the
# bearings' stick at the rests decide which count a stop lands on: docs/results.md), so one rig run
# against one simulated run says little. Both over the same neighbourhood of the plant: its load
# mass nudged by -10 to +10 parts per million (21 plants, `pmlsm config write`), the simulated
# drive in process (closed_loop, the same trace as the DDS chain) and both rigs in lockstep,
# composed (the same trace as a process a node, in a tenth of the time); each rig's median within
# 2 % of the simulated drive's is its bar (the RNN's spread is a fifth of its cost: a median of 11
# plants moved by 2 %). The two buses carry the same quantisation (per mille of the rated force,
# 1 um), so the EtherCAT rig's trace is the CANopen rig's byte for byte: counted, not assumed.
mkdir -p out/virtual_rig_nudged
echo
echo "the pulse over 21 plants whose load mass is nudged by -10..+10 ppm: the simulated drive against the CANopen and EtherCAT rigs"
printf '%-6s %-26s %-28s %7s %-28s %7s  %s\n' comp "simulated: min median max" "CANopen rig: min median max" diff_% \
  "EtherCAT rig: min median max" diff_% "medians within 2 %"
nudges=(-10 -9 -8 -7 -6 -5 -4 -3 -2 -1 0 1 2 3 4 5 6 7 8 9 10)
for n in "${nudges[@]}"; do
  mass=$(awk -v n="$n" 'BEGIN { printf "%.17g", 4.0 * (1 + n * 1e-6) }')
  ./build/bin/pmlsm config write --set plant.mechanics.load_mass_kg="$mass" --reason "the plant's load mass nudged by $n ppm" \
    -o "out/virtual_rig_nudged/plant_${n}ppm.yaml" >/dev/null
done
# min, median and max of numbers on standard input
spread() { sort -g | awk '{ v[NR] = $1 } END { printf "%.3f %.3f %.3f\n", v[1], v[(NR + 1) / 2], v[NR] }'; }
outside=()
same_traces=0
scenario=pulse  # for row()
for comp in none accel rnn state; do
  sims=() rigs=() ecats=()
  extra=()
  [ "$comp" = rnn ] && extra=(--weights "$weights")
  for n in "${nudges[@]}"; do
    run=$((run + 1))
    echo "run_main: run $run/$runs: pulse, the plant nudged by $n ppm, compensator $comp ($((SECONDS - t_start)) s since start)" >&2
    config="out/virtual_rig_nudged/plant_${n}ppm.yaml"
    log="out/virtual_rig_nudged/pulse_${comp}_${n}ppm"
    ./build/bin/closed_loop -c "$config" -s configs/scenarios/pulse.yaml --compensator "$comp" "${extra[@]}" \
      -o "$log.sim" >"$log.sim.log" 2>&1 || { cat "$log.sim.log" >&2; echo "run_main: closed_loop failed ($log.sim.log)" >&2; exit 1; }
    sims+=("$(awk '$1 ~ /^pulse/ { print $2; exit }' "$log.sim.log")")
    for bus in rig ecat; do
      launch=launch/virtual_rig.yaml
      [ "$bus" = ecat ] && launch=launch/virtual_rig_ethercat.yaml
      if ! ./build/bin/launcher "$launch" --arg config="$config" --arg scenario=configs/scenarios/pulse.yaml \
           --arg out="$log.$bus" --arg domain="$domain" --arg compensator="$comp" --arg weights="$weights" \
           --arg label="rig_$comp" --arg compose=true >"$log.$bus.log" 2>&1; then
        cat "$log.$bus.log" >&2
        echo "run_main: the nudged pulse on $launch (compensator $comp, $n ppm) failed ($log.$bus.log)" >&2
        exit 1
      fi
    done
    rigs+=("$(row "$log.rig.log" | awk '{ print $1 }')")
    ecats+=("$(row "$log.ecat.log" | awk '{ print $1 }')")
    cmp -s "$log.rig/pulse_rig_$comp.csv" "$log.ecat/pulse_rig_$comp.csv" && same_traces=$((same_traces + 1))
  done
  read -r sim_min sim_median sim_max < <(printf '%s\n' "${sims[@]}" | spread)
  cells=()
  within=yes
  for rig in CANopen EtherCAT; do
    if [ "$rig" = CANopen ]; then costs=("${rigs[@]}"); else costs=("${ecats[@]}"); fi
    read -r rig_min rig_median rig_max < <(printf '%s\n' "${costs[@]}" | spread)
    diff=$(awk -v a="$sim_median" -v b="$rig_median" 'BEGIN { printf "%+.2f", 100 * (b - a) / a }')
    if ! awk -v d="$diff" 'BEGIN { exit !(d <= 2 && d >= -2) }'; then
      within=NO
      outside+=("$comp on the $rig rig ($diff %)")
    fi
    cells+=("$rig_min $rig_median $rig_max" "$diff")
  done
  printf '%-6s %-26s %-28s %7s %-28s %7s  %s\n' "$comp" "$sim_min $sim_median $sim_max" "${cells[@]}" "$within"
done
if [ ${#outside[@]} -eq 0 ]; then
  echo "every compensator's median on both rigs within 2 % of the simulated drive's; runs in out/virtual_rig_nudged/"
else
  echo "rig medians outside 2 % of the simulated drive's: ${outside[*]} (21 plants a median; runs in out/virtual_rig_nudged/)"
fi
echo "the EtherCAT rig's trace the CANopen rig's byte for byte: $same_traces of $((4 * ${#nudges[@]})) runs"
# The rigs' verdict is the job's: a median outside its bar or a bus whose trace is not the other's
# ends it non-zero (after the plots, so what was measured is all there).
rig_verdict=""
[ ${#outside[@]} -eq 0 ] || rig_verdict="rig medians outside 2 % of the simulated drive's: ${outside[*]}"
if [ "$same_traces" -ne $((4 * ${#nudges[@]})) ]; then
  rig_verdict="${rig_verdict:+$rig_verdict; }the EtherCAT rig's trace differs from the CANopen rig's on $((4 * ${#nudges[@]} - same_traces)) runs"
fi
phase_end
echo
echo "distributed lockstep runs over Fast DDS; RNN weights from $weights; logs and traces in out/"
phase_start "[4/4] plots" "gnuplot"
gnuplot -e "outdir='out'; history='$history'" scripts/plot_traces.gp
echo "plots: out/pulse.png (Figs. 11-12) out/free_vibration.png (Fig. 10) out/training.png (Figs. 6-7, $history)"
echo "recording of the pulse PI + RNN run: $recording_summary"
echo "  plotted from the recording: out/pulse_pi_rnn_plots/{velocities,forces,phase_plane}.png"
phase_end
if [ -n "$rig_verdict" ]; then
  echo "run_main: the virtual rigs failed their verdict: $rig_verdict (runs in out/virtual_rig_nudged/)" >&2
  exit 3
fi
echo "run_main: all done in $((SECONDS - t_start)) s" >&2

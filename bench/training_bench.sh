#!/usr/bin/env bash
# Figures of the weight search on this machine, in one run:
#  1. evaluations per second: local threads (1 and all cores) and 1 or 2
#     de_worker processes over DDS (1 thread each), with the ratio 2 workers / 1;
#  2. evaluations each optimiser needs to reach a given cost (23), over seeds:
#     DE/rand/1/bin (the paper), jDE and CMA-ES (pagmo2), same population size
#     and initial population for a seed.
#   bench/training_bench.sh [evaluations_per_run] [seeds]   (defaults 6000, 5)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bin=build/bin
budget="${1:-6000}"
seeds="${2:-5}"
domain="${PMLSM_DOMAIN:-44}"
work="$(mktemp -d)"
pids=()
cleanup() { for p in "${pids[@]+"${pids[@]}"}"; do kill "$p" 2>/dev/null || true; done; rm -rf "$work"; }
trap cleanup EXIT

rate_of() { sed -n 's/.* in [0-9.]* s: \([0-9.]*\) evaluations\/s.*/\1/p' "$1" | head -n 1; }
trainer() { "$bin/de_trainer" --no-progress --domain "$domain" "$@"; }

echo "== evaluations per second (NP 120, 1200 evaluations each)"
trainer --threads 1 --train-set max_evaluations=1200 --out "$work/t1.yaml" >"$work/t1.log"
trainer --train-set max_evaluations=1200 --out "$work/tn.yaml" >"$work/tn.log"
start_workers() {
  for i in $(seq 1 "$1"); do
    "$bin/de_worker" --domain "$domain" --threads 1 --id "bench-$i" --idle-exit-s 5 >"$work/w$1_$i.log" 2>&1 &
    pids+=($!)
  done
}
start_workers 1
trainer --threads 1 --wait-workers 1 --train-set max_evaluations=1200 --out "$work/w1.yaml" >"$work/w1.log"
wait "${pids[@]}" 2>/dev/null || true; pids=()
start_workers 2
trainer --threads 1 --wait-workers 2 --train-set max_evaluations=1200 --out "$work/w2.yaml" >"$work/w2.log"
wait "${pids[@]}" 2>/dev/null || true; pids=()
r1=$(rate_of "$work/t1.log"); rn=$(rate_of "$work/tn.log"); w1=$(rate_of "$work/w1.log"); w2=$(rate_of "$work/w2.log")
printf '%-34s %10s\n' "evaluator" "evals/s"
printf '%-34s %10s\n' "local, 1 thread" "$r1" "local, $(nproc) threads" "$rn" "1 de_worker (1 thread)" "$w1" "2 de_workers (1 thread each)" "$w2"
awk -v a="$w2" -v b="$w1" 'BEGIN { printf "2 workers / 1 worker: %.2fx\n", a / b }'
for f in t1 tn w1 w2; do
  cmp -s <(sed -n '/^weights:/,$p' "$work/t1.yaml") <(sed -n '/^weights:/,$p' "$work/$f.yaml") ||
    { echo "training_bench: $f found other weights than t1: not deterministic" >&2; exit 1; }
done
echo "(all four runs found the same weights)"

echo "== evaluations to reach a cost, $seeds seeds x $budget evaluations (pulse test, NP 120)"
thresholds=(30 20 15 12 10)
printf '%-16s' "optimiser"; for t in "${thresholds[@]}"; do printf ' %16s' "cost<=$t"; done; printf ' %14s\n' "best (median)"
for opt in de jde cmaes; do
  for s in $(seq 1 "$seeds"); do
    trainer --train-set optimiser=$opt seed=$s max_evaluations="$budget" --out "$work/$opt-$s.yaml" >"$work/$opt-$s.log"
  done
  printf '%-16s' "$opt"
  for t in "${thresholds[@]}"; do
    # Per seed: the evaluations at the first generation whose best cost is <= t.
    cell=$(for s in $(seq 1 "$seeds"); do
             awk -F, -v t="$t" 'NR > 1 && $3 <= t { print $2; exit }' "$work/$opt-$s.yaml.history.csv"
           done | sort -n | awk -v n="$seeds" '{ v[NR] = $1 } END { if (NR == 0) { print "0/" n; exit }
             printf "%d/%d, med %d", NR, n, v[int((NR + 1) / 2)] }')
    printf ' %16s' "$cell"
  done
  best=$(for s in $(seq 1 "$seeds"); do tail -n 1 "$work/$opt-$s.yaml.history.csv" | cut -d, -f3; done |
         sort -g | awk '{ v[NR] = $1 } END { printf "%.2f", v[int((NR + 1) / 2)] }')
  printf ' %14s\n' "$best"
done
echo "cells: seeds that reached the cost / seeds, and the median evaluations among those that did"

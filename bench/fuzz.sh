#!/usr/bin/env bash
# Fuzzing: builds the libFuzzer targets of fuzz/ with clang, AddressSanitizer and
# UndefinedBehaviorSanitizer (build dir build-fuzz), then runs each for SECONDS, starting from its
# seed corpus (fuzz/corpus/<target>/) and its regression inputs (fuzz/regressions/<target>/).
# Prints, per target, the executions, executions per second, the corpus it grew and whether it
# crashed. New inputs go to build-fuzz/corpus/<target>/ (kept between runs), crash inputs to
# build-fuzz/crashes/<target>/: fix the code, then copy the input to fuzz/regressions/<target>/.
#   bench/fuzz.sh [SECONDS] [TARGET...]   (default 600 s, every target)
# Environment: PMLSM_FUZZ_JOBS (build jobs, default 2), PMLSM_FUZZ_BUILD (default build-fuzz),
# CXX (default clang++-14).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
seconds="${1:-600}"
shift || true
build="${PMLSM_FUZZ_BUILD:-$root/build-fuzz}"
jobs="${PMLSM_FUZZ_JOBS:-2}"
cxx="${CXX:-clang++-14}"
command -v "$cxx" >/dev/null || { echo "fuzz.sh: $cxx not found (scripts/install_deps.sh installs clang-14)" >&2; exit 1; }

targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  # The list in fuzz/CMakeLists.txt, in its order.
  mapfile -t targets < <(sed -n '/^set(pmlsm_fuzz_targets$/,/^)/p' "$root/fuzz/CMakeLists.txt" |
                          sed -n 's/^  \([a-z_]*\).*/\1/p')
fi

mkdir -p "$build"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER="$cxx" \
  -DPMLSM_FUZZ=ON -DPMLSM_SANITIZE=address,undefined >"$build/configure.log" 2>&1 ||
  { cat "$build/configure.log" >&2; exit 1; }
build_targets=()
for t in "${targets[@]}"; do build_targets+=(--target "fuzz_$t"); done
cmake --build "$build" -j"$jobs" "${build_targets[@]}" >"$build/build.log" 2>&1 ||
  { tail -40 "$build/build.log" >&2; exit 1; }

export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:symbolize=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
printf '%-18s %8s %12s %10s %8s %s\n' target seconds executions exec/s corpus result
status=0
for t in "${targets[@]}"; do
  work="$build/corpus/$t"
  crashes="$build/crashes/$t"
  log="$build/fuzz_$t.log"
  mkdir -p "$work" "$crashes"
  seeds=("$root/fuzz/corpus/$t")
  [ -d "$root/fuzz/regressions/$t" ] && seeds+=("$root/fuzz/regressions/$t")
  # -timeout: an input running longer is a hang; -rss_limit_mb / -malloc_limit_mb: a parser
  # that lets input size its allocations is a defect too.
  set +e
  "$build/bin/fuzz_$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=1024 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$crashes/" "$work" "${seeds[@]}" >"$log" 2>&1
  rc=$?
  set -e
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  files=$(find "$work" -type f | wc -l)
  if [ "$rc" -eq 0 ]; then
    result="no crash"
  else
    result="CRASH (exit $rc): $(grep -m1 -E 'ERROR: |runtime error|deadly signal|out-of-memory|timeout' "$log" | cut -c1-100); input in $crashes, log $log"
    status=1
  fi
  printf '%-18s %8s %12s %10s %8s %s\n' "$t" "$seconds" "${runs:-?}" "${rate:-?}" "$files" "$result"
done
exit "$status"

#!/usr/bin/env bash
# Configures and builds into build/ (Release). Generated IDL code goes to build/idl/generated.
# Says how far along it is: the build's percent (make's "[ 45%]" or ninja's "[n/m]"), every
# 5 % (in place on a terminal); warnings and errors pass through; the whole output in
# build/build.log; fastddsgen's own output in build/idl/fastddsgen.log. A first build takes 5-6
# minutes on 2 cores (unity builds, see CMakeLists.txt).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PROGRESS_NAME=build
. "$root/scripts/progress.sh"
mkdir -p "$root/build"
log="$root/build/build.log"
# PMLSM_WERROR=ON (CI): every compiler warning is an error. Unset, the build keeps what it had
# (a change of flags would compile everything again).
config_args=(-DCMAKE_BUILD_TYPE=Release)
[ -n "${PMLSM_WERROR:-}" ] && config_args+=(-DPMLSM_WERROR="$PMLSM_WERROR")
phase_start "configure" "cmake -S . -B build ${config_args[*]}"
if ! cmake -S "$root" -B "$root/build" "${config_args[@]}" >"$log" 2>&1; then
  cat "$log" >&2
  echo "build: cmake configure failed (log above, also in $log)" >&2
  exit 1
fi
phase_end
phase_start "compile" "cmake --build build -j $(nproc) (log build/build.log)"
# Progress lines become "PERCENT<TAB>what"; everything else (warnings, errors) goes to stderr as it is.
if ! cmake --build "$root/build" -j "$(nproc)" 2>&1 | tee -a "$log" |
     line_awk '/^\[ *[0-9]+%\]/ { p = $0; sub(/^\[ */, "", p); pct = int(p); sub(/^\[ *[0-9]+%\] /, ""); print pct "\t" $0; fflush(); next }
          /^\[[0-9]+\/[0-9]+\]/ { split(substr($1, 2), nm, "/"); sub(/^\[[0-9]+\/[0-9]+\] /, "");
                                  print int(100 * nm[1] / nm[2]) "\t" $0; fflush(); next }
          /^(Scanning dependencies|Consolidate compiler|gmake|make)/ { next }
          { print > "/dev/stderr" }' | percent_filter "compiling"; then
  tail -n 40 "$log" >&2
  echo "build: the build failed (last lines above, all of it in $log)" >&2
  exit 1
fi
phase_end

#!/usr/bin/env bash
# The test command: installs what is missing, builds, runs the whole suite. Each phase says
# what it does and how long it took; ctest prints every test as it ends ("n/N Test #i: ...").
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PROGRESS_NAME=test
. "$root/scripts/progress.sh"
t_start=$SECONDS
phase_start "[1/3] packages" "scripts/install_deps.sh"
"$root/scripts/install_deps.sh"
phase_end
phase_start "[2/3] build" "about 15 minutes the first time on 2 cores (scripts/build.sh)"
"$root/scripts/build.sh"
phase_end
cd "$root/build"
phase_start "[3/3] tests" "ctest, $(ctest -N | sed -n 's/^Total Tests: //p') tests, about 15 minutes on 2 cores; each printed as it ends"
ctest --output-on-failure -j "$(nproc)"
phase_end
echo "test: all done in $((SECONDS - t_start)) s" >&2

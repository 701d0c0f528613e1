#!/usr/bin/env bash
# The test command: installs what is missing, builds, runs the whole suite. Each phase says
# what it does and how long it took; ctest prints every test as it ends ("n/N Test #i: ...").
#   --quick   the unit tests only (ctest -L unit: libraries in-process, no DDS domain), for
#             the edit-build-test cycle; the whole suite is what CI runs.
set -euo pipefail
quick=0
case "${1:-}" in
  "") ;;
  --quick) quick=1 ;;
  -h|--help) sed -n '2,5p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
  *) echo "test: unknown option '$1' (--quick, --help)" >&2; exit 2 ;;
esac
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PROGRESS_NAME=test
. "$root/scripts/progress.sh"
t_start=$SECONDS
phase_start "[1/3] packages" "scripts/install_deps.sh"
"$root/scripts/install_deps.sh"
phase_end
phase_start "[2/3] build" "about 6 minutes the first time on 2 cores, seconds after that (scripts/build.sh)"
"$root/scripts/build.sh"
phase_end
cd "$root/build"
if [ "$quick" = 1 ]; then
  phase_start "[3/3] unit tests" "ctest -L unit, $(ctest -N -L unit | sed -n 's/^Total Tests: //p') tests; each printed as it ends"
  ctest --output-on-failure -j "$(nproc)" -L unit
else
  phase_start "[3/3] tests" "ctest, $(ctest -N | sed -n 's/^Total Tests: //p') tests, about 5 minutes on 2 cores; each printed as it ends"
  ctest --output-on-failure -j "$(nproc)"
fi
phase_end
echo "test: all done in $((SECONDS - t_start)) s" >&2

#!/usr/bin/env bash
# clang-tidy-14 (.clang-tidy: function size, naming) over the C++ sources a change touched:
#   scripts/tidy.sh [REF]    the .cpp files changed since REF (default: HEAD~1), or given by
#                            PMLSM_TIDY_FILES (space separated)
#   scripts/tidy.sh --all    every production source (common/, nodes/, tools/; not tests, fuzz,
#                            bench): what CI runs, about 2 minutes on 2 cores
# It needs build/compile_commands.json (./scripts/build.sh); with unity builds each source is
# checked with the flags of the unity file that includes it. Exit 1 when a check reports.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
tidy=$(command -v clang-tidy-14 || true)
[ -n "$tidy" ] || { echo "tidy: clang-tidy-14 is not installed (apt-get install clang-tidy-14)" >&2; exit 77; }
[ -f build/compile_commands.json ] || { echo "tidy: no build/compile_commands.json: run ./scripts/build.sh" >&2; exit 2; }
if [ "${1:-}" = "--all" ]; then
  mapfile -t files < <(git ls-files 'common/*.cpp' 'nodes/*.cpp' 'tools/*.cpp')
elif [ -n "${PMLSM_TIDY_FILES:-}" ]; then
  read -r -a files <<<"$(tr '\n' ' ' <<<"$PMLSM_TIDY_FILES")"
else
  mapfile -t files < <(git diff --name-only --diff-filter=AM "${1:-HEAD~1}" -- '*.cpp' | grep -v '^tests/node/' || true)
fi
[ "${#files[@]}" -gt 0 ] || { echo "tidy: no C++ source changed"; exit 0; }
# A compile database with one entry per source: the unity file's command for each source it includes.
db=$(mktemp -d)
trap 'rm -rf "$db"' EXIT
python3 - "$root" "$db/compile_commands.json" <<'PY'
import json, re, sys
root, out = sys.argv[1], sys.argv[2]
entries = []
# The warning policy is GCC's and the build enforces it (PMLSM_WERROR); clang's own diagnostics
# under -Werror would otherwise fail tidy on warnings GCC does not have.
for e in json.load(open(f"{root}/build/compile_commands.json")):
    e["command"] = e["command"].replace(" -Werror", "")
    if "/Unity/unity_" not in e["file"]:
        entries.append(e)
        continue
    for line in open(e["file"]):
        m = re.match(r'#include "(.+)"', line)
        if m:
            source = m.group(1)
            entries.append({"directory": e["directory"], "file": source,
                            "command": e["command"].replace(e["file"], source)})
json.dump(entries, open(out, "w"))
PY
# One clang-tidy per core; each file's findings are printed together as it ends.
report="$db/report.txt"
printf '%s\n' "${files[@]}" | xargs -P "$(nproc)" -I{} sh -c \
  'out=$("$0" -p "$1" --quiet "$2" 2>/dev/null | grep -E "warning|error"); echo "tidy: $2" >&2; [ -z "$out" ] || echo "$out"' \
  "$tidy" "$db" {} | tee "$report"
if [ -s "$report" ]; then
  echo "tidy: $(grep -c . "$report") finding(s) in ${#files[@]} file(s)" >&2
  exit 1
fi
echo "tidy: ${#files[@]} file(s), nothing reported"

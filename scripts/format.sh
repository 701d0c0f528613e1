#!/usr/bin/env bash
# The code style (.clang-format, clang-format-14) over every C++ file of the tree:
#   scripts/format.sh            rewrites the files that differ
#   scripts/format.sh --check    lists them and exits 1 (the test `code_format`); 77 when
#                                clang-format-14 is not installed (scripts/install_deps.sh installs it)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
check=0
case "${1:-}" in
  "") ;;
  --check) check=1 ;;
  *) echo "format: unknown option '$1' (--check)" >&2; exit 2 ;;
esac
formatter=$(command -v clang-format-14 || true)
if [ -z "$formatter" ]; then
  echo "format: clang-format-14 is not installed (apt-get install clang-format-14): not checked" >&2
  exit 77
fi
cd "$root"
if [ -d .git ] && command -v git >/dev/null; then
  # Tracked and new (not ignored) files: a file not yet added is checked too.
  mapfile -t files < <(git ls-files --cached --others --exclude-standard '*.cpp' '*.hpp' '*.h' | grep -v '/node_modules/')
else
  mapfile -t files < <(find common nodes tools tests bench fuzz -name node_modules -prune -o \
                            \( -name '*.cpp' -o -name '*.hpp' -o -name '*.h' \) -print | sort)
fi
differ=()
for f in "${files[@]}"; do
  if ! "$formatter" --style=file "$f" | cmp -s - "$f"; then differ+=("$f"); fi
done
if [ "$check" = 1 ]; then
  if [ "${#differ[@]}" -gt 0 ]; then
    printf 'format: %s differs from .clang-format (scripts/format.sh rewrites it)\n' "${differ[@]}" >&2
    echo "format: ${#differ[@]} of ${#files[@]} files differ" >&2
    exit 1
  fi
  echo "format: all ${#files[@]} files follow .clang-format"
  exit 0
fi
for f in "${differ[@]}"; do "$formatter" -i --style=file "$f"; done
echo "format: ${#differ[@]} of ${#files[@]} files rewritten"

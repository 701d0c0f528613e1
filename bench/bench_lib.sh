# Sourced by the bench scripts: the figures the drive nodes print at the end of a run, picked
# out of their logs (the first match).
field() { sed -n "$1" "$2" | head -n 1; }
rtf_of() { field 's/.*ticks in [0-9.]* s (\([0-9.]*\)x real time).*/\1/p' "$1"; }
p50_of() { field 's/.*p50 \([0-9.]*\) us.*/\1/p' "$1"; }
p99_of() { field 's/.*p99 \([0-9.]*\) us.*/\1/p' "$1"; }
max_of() { field 's/.*max \([0-9.]*\) us.*/\1/p' "$1"; }
late_of() { field 's/.*late \([0-9]*\),.*/\1/p' "$1"; }
miss_of() { field 's/.*deadline misses \([0-9]*\).*/\1/p' "$1"; }
ppm_of() { field 's/.*nominal [0-9.]* us, \([-+0-9.]*\) ppm.*/\1/p' "$1"; }
# Polls FILE for a line holding TEXT (the programs print when they are ready); fails after 15 s,
# naming the caller ($0) and printing the file.
wait_for_line() {
  local file="$1" text="$2" deadline=$((SECONDS + 15))
  until grep -q -- "$text" "$file" 2>/dev/null; do
    if ((SECONDS >= deadline)); then
      echo "$(basename "$0"): '$text' not in $file within 15 s:" >&2
      cat "$file" >&2
      exit 1
    fi
    sleep 0.05
  done
}

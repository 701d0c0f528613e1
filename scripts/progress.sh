# Progress helpers sourced by the scripts (install_deps, build, run_main, test): each phase
# says what it does, how far along it is, and how long it took, so a first run on a fresh
# machine (minutes of packages and build) never looks hung.
#   phase_start LABEL [DETAIL]  "<script>: LABEL: DETAIL (hh:mm:ss)"
#   phase_end                   "<script>: LABEL done in N s"
#   percent_filter     reads lines, prints "<script>: <what> NN% ..." when the percent moves by
#                      a step (every line on a terminal, rewritten in place); other lines pass
#   line_awk ARGS...   awk reading its input line by line (for pipes of progress lines)
# PROGRESS_NAME names the script in the messages.
PROGRESS_NAME="${PROGRESS_NAME:-$(basename "$0" .sh)}"
_phase_label=""
_phase_t0=0

phase_start() {
  _phase_label="$1"
  _phase_t0=$SECONDS
  echo "$PROGRESS_NAME: $1${2:+: $2} ($(date +%H:%M:%S))" >&2
}

phase_end() {
  echo "$PROGRESS_NAME: $_phase_label done in $((SECONDS - _phase_t0)) s" >&2
}

# Lines "PERCENT<TAB>TEXT" on stdin (made by the callers' awk) become progress lines on stderr.
# Not on a terminal (CI logs): one line per 5 % step, and a line whenever 20 s went by without
# one (the last percent and step again, "(still)"), so a log is never silent for more than about
# 21 s; on a terminal: one line rewritten in place.
# mawk (Debian's awk) reads a pipe in blocks of kilobytes, so progress lines would arrive in
# bursts minutes apart; its -W interactive reads line by line. Other awks read lines already.
if awk -W version 2>&1 | head -n 1 | grep -q mawk; then
  line_awk() { awk -W interactive "$@"; }
else
  line_awk() { awk "$@"; }
fi

percent_filter() {
  local step=5 tty=0
  [ -t 2 ] && tty=1
  # A "tick" line a second beside the input: a step that prints nothing for long (one large file
  # compiling, dpkg unpacking) still gets its line every 20 s, with the last percent and text.
  {
    cat &
    local reader=$!
    while kill -0 "$reader" 2>/dev/null; do
      sleep 1
      printf 'tick\t\n'
    done
    wait "$reader"
  } | line_awk -v name="$PROGRESS_NAME" -v what="$1" -v step="$step" -v tty="$tty" -F '\t' '
    BEGIN { last = -step; printed = systime(); p = 0; text = "" }
    $1 == "tick" {
      if (!tty && systime() - printed >= 20) {
        printf "%s: %s %3d%% %s (still)\n", name, what, p, text > "/dev/stderr"; printed = systime(); fflush("/dev/stderr")
      }
      next
    }
    {
      p = int($1); text = $2; if (p < last) last = -step;  # a new pass (download, then install)
      if (tty) { printf "\r\033[K%s: %s %3d%% %s", name, what, p, substr($2, 1, 70) > "/dev/stderr"; shown = 1 }
      else if (p >= last + step || (p == 100 && last != 100) || systime() - printed >= 20) {
        printf "%s: %s %3d%% %s\n", name, what, p, $2 > "/dev/stderr"; if (p >= last + step) last = p; printed = systime()
      }
      fflush("/dev/stderr")
    }
    END { if (tty && shown) printf "\n" > "/dev/stderr" }'
}

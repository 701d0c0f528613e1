// How a chain node reads the end of an input whose writers all left. No DDS here.
#pragma once

#include <cstddef>
#include <cstdint>

namespace pmlsm::node {

/// What the writers' leaving says about the ticks still missing.
enum class InputEnd {
  kRunComplete,  ///< nothing was missing: every tick of the run arrived
  kTailLost,     ///< the writer ran to the end; its last samples were lost on a best-effort link
  kLeftEarly,    ///< the writer stopped before the run's end: a lost peer
};

/// A writer that leaves after writing tick `run_ticks` - 1 had time to write every tick after the
/// last one taken (`next_tick` - 1, taken `since_last_s` before the leaving was seen): the
/// missing ticks n = run_ticks - next_tick would have been written n control periods after it.
/// So, in realtime, n * period <= since_last_s + period says the writer ran to the end and the
/// link lost its last samples (a best-effort input loses some, the evaluator counts them); a
/// writer that stopped early leaves within milliseconds of its last sample, long before its
/// missing ticks would have been due. Slack of one period (the last sample may be taken just
/// before the next is written) and kInputEndLateS (that sample may have come late, in a burst
/// after a held link or a held reader). In lockstep nothing is lost: a missing tick is an early end.
inline constexpr double kInputEndLateS = 0.05;
inline InputEnd input_end(std::uint64_t next_tick, std::uint64_t run_ticks, double period_s, double since_last_s,
                          bool realtime) {
  if (next_tick >= run_ticks) return InputEnd::kRunComplete;
  if (!realtime) return InputEnd::kLeftEarly;
  const double due_s = static_cast<double>(run_ticks - next_tick) * period_s;
  return due_s <= since_last_s + period_s + kInputEndLateS ? InputEnd::kTailLost : InputEnd::kLeftEarly;
}

/// Watches an input's writers while a node waits for tick `next_tick`: once every writer left,
/// input_end() judges the ticks still missing, at the moment the leaving was first seen (later
/// polls must not turn an early end into a lost tail just because time went by). A writer that
/// matches again, or a sample taken, starts afresh: a restarted writer is followed as before.
/// Times are CLOCK_MONOTONIC nanoseconds (monotonic_ns()).
class InputEndWatch {
 public:
  InputEndWatch(std::uint64_t run_ticks, double period_s, bool realtime)
      : run_ticks_(run_ticks), period_s_(period_s), realtime_(realtime) {}

  /// A sample was taken at `now_ns`.
  void taken(std::int64_t now_ns) {
    last_taken_ns_ = now_ns;
    any_taken_ = true;
    left_seen_ = false;
  }

  /// Polled while nothing is taken: true once the writers (`matched_writers` of them now) left
  /// after writing to the run's end and the link lost the last samples (end the wait, exit 0).
  /// Before the first sample a reader with no writer has simply not matched yet: false.
  bool tail_lost(std::size_t matched_writers, std::uint64_t next_tick, std::int64_t now_ns) {
    if (matched_writers > 0 || !any_taken_) {
      left_seen_ = false;
      return false;
    }
    if (!left_seen_) {
      left_seen_ = true;
      judged_ =
          input_end(next_tick, run_ticks_, period_s_, static_cast<double>(now_ns - last_taken_ns_) * 1e-9, realtime_);
    }
    return judged_ == InputEnd::kTailLost;
  }

  /// The ticks the run still lacked when the writers were seen leaving.
  std::uint64_t missing(std::uint64_t next_tick) const { return next_tick < run_ticks_ ? run_ticks_ - next_tick : 0; }

 private:
  std::uint64_t run_ticks_;
  double period_s_;
  bool realtime_;
  std::int64_t last_taken_ns_ = 0;
  bool any_taken_ = false;
  bool left_seen_ = false;
  InputEnd judged_ = InputEnd::kLeftEarly;
};

}  // namespace pmlsm::node

// Whether an input that another process computes (the compensation, from the estimate of the
// feedback the controller sent out) is on time at each tick, and the episodes when it is not.
//
// Output k-1 of a compensator belongs to tick k; in realtime the controller never waits for it:
// it takes the newest one there is and uses it while it is at most `max_age_ticks` old (a
// compensation older than that pushes against a load that has moved on). A late input is not
// used, the tick counted; the first tick it is on time again it is used again. Each change is an
// event the node reports (once per episode, never per tick), with the gap's length. The start of a
// run, before the first input on time, is counted apart: it is the peers starting, not the link.
#pragma once

#include <algorithm>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

namespace pmlsm {

class InputFreshness {
 public:
  enum class Change {
    kNone,
    kFirst,  ///< the first input on time (after `gap_ticks` ticks of the start without one)
    kLate,   ///< this tick starts an episode without an input on time
    kBack,   ///< on time again after `gap_ticks` ticks without
  };
  struct Step {
    bool on_time = false;  ///< use the input at this tick
    Change change = Change::kNone;
    std::uint64_t gap_ticks = 0;  ///< kFirst, kBack: how many ticks went without
  };
  /// The start (before the first input on time: the other process still starting, discovery)
  /// apart from the episodes after it, which are what a link or a host did to the run.
  struct Counters {
    std::uint64_t ticks = 0;               ///< ticks judged
    std::uint64_t ticks_before_first = 0;  ///< without an input at the start
    std::uint64_t late_ticks = 0;          ///< without an input on time after the first
    std::uint64_t episodes = 0;            ///< runs of late ticks after the first (one still open included)
    std::uint64_t longest_gap_ticks = 0;   ///< the longest of them (one still open included)
  };

  /// @throws std::invalid_argument for a max_age_ticks of 0 (an input is never for its own tick).
  explicit InputFreshness(std::uint64_t max_age_ticks) : max_age_ticks_(max_age_ticks) {
    if (max_age_ticks == 0) {
      throw std::invalid_argument("InputFreshness: max_age_ticks must be at least 1, got 0");
    }
  }

  /// At tick `k`, the newest input received is for tick `newest` (none: nothing received yet).
  /// Tick 0 has no input to wait for and is not judged.
  Step step(std::uint64_t k, std::optional<std::uint64_t> newest) {
    Step out;
    if (k == 0) return out;
    ++counters_.ticks;
    out.on_time = newest.has_value() && *newest + max_age_ticks_ >= k;
    if (!started_) {
      if (!out.on_time) {
        ++counters_.ticks_before_first;
        return out;
      }
      started_ = true;
      out.change = Change::kFirst;
      out.gap_ticks = counters_.ticks_before_first;
      return out;
    }
    if (out.on_time) {
      if (late_run_ > 0) {
        out.change = Change::kBack;
        out.gap_ticks = late_run_;
      }
      late_run_ = 0;
      return out;
    }
    ++counters_.late_ticks;
    if (late_run_ == 0) {
      out.change = Change::kLate;
      ++counters_.episodes;
    }
    ++late_run_;
    counters_.longest_gap_ticks = std::max(counters_.longest_gap_ticks, late_run_);
    return out;
  }

  /// A new run of the drive: nothing is owed from before; it starts anew.
  void reset() {
    late_run_ = 0;
    started_ = false;
  }

  const Counters& counters() const { return counters_; }
  std::uint64_t max_age_ticks() const { return max_age_ticks_; }

 private:
  std::uint64_t max_age_ticks_;
  bool started_ = false;
  std::uint64_t late_run_ = 0;
  Counters counters_;
};

}  // namespace pmlsm

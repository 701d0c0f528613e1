// Which MotorFeedback ticks a node on the chain takes. No DDS here.
#pragma once

#include <cstdint>

namespace pmlsm::node {

/// Ticks are taken in order: the expected one or a later one (a realtime reader
/// may see gaps); older ones are rejected. A tick more than `max_jump` past the
/// expected one is taken only once the tick after it arrives: a writer whose
/// history overflowed skips ticks for real, and its stream goes on from there,
/// while a single malformed far-future tick, taken, would make every genuine
/// sample after it look stale. The first tick is taken whatever it is (a node
/// may join a running system).
class TickFilter {
 public:
  explicit TickFilter(std::uint64_t max_jump = 4096) : max_jump_(max_jump) {}

  /// True: take this sample (expected() moves past it); false: reject it.
  bool accept(std::uint64_t tick) {
    if (any_ && tick < expected_) return false;
    const bool near = !any_ || tick - expected_ <= max_jump_;
    const bool resync = has_far_candidate_ && tick == far_candidate_ + 1;
    if (!near && !resync) {
      far_candidate_ = tick;
      has_far_candidate_ = true;
      return false;
    }
    expected_ = tick + 1;
    any_ = true;
    has_far_candidate_ = false;
    return true;
  }

  /// The tick the node waits for next (0 before any).
  std::uint64_t expected() const { return expected_; }

 private:
  std::uint64_t max_jump_;
  std::uint64_t expected_ = 0;
  bool any_ = false;
  // A far tick rejected once, taken if its successor follows. Not a std::optional: GCC's
  // -Wmaybe-uninitialized misreads one in a TickFilter assigned afresh inside a loop.
  bool has_far_candidate_ = false;
  std::uint64_t far_candidate_ = 0;
};

}  // namespace pmlsm::node

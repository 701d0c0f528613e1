// A component's cycle as its executor runs it (ros2_control's controller manager, Drake's
// Simulator): the component has no loop and no wait of its own; its update() takes what has
// arrived, does what it can and says how it went, and the executor decides what comes next. The
// rule for waiting on inputs lives here, once: work resets the wait; a component waiting longer
// than its input timeout since it last worked has lost its inputs; a wait is cut into slices of at
// most kCycleSlice so a stop request is seen. Pure: times are given, nothing sleeps here.
#pragma once

#include <algorithm>
#include <cstdint>

namespace pmlsm {

/// What one update() did.
enum class Progress {
  kWorked,    ///< it did some work (a tick): update it again at once, more may be ready
  kWaiting,   ///< its inputs are not there yet: update it again when they may be
  kFinished,  ///< its run is over (the exit code with it)
};

/// The longest the executor sleeps before updating again: a stop request is seen within it.
inline constexpr std::int64_t kCycleSliceNs = 50'000'000;

/// The executor's decision after an update, for one component.
class CycleWait {
 public:
  enum class Next {
    kUpdate,      ///< update again now
    kSleep,       ///< sleep at most sleep_ns(), or until the inputs move, then update
    kInputsLost,  ///< waited longer than the input timeout since it last worked
    kFinished,
  };

  /// `input_timeout_ns`: how long it may wait without working; `start_ns`: when it was activated
  /// (the first wait counts from there).
  CycleWait(std::int64_t input_timeout_ns, std::int64_t start_ns)
      : timeout_ns_(input_timeout_ns), last_work_ns_(start_ns) {}

  Next after(Progress progress, std::int64_t now_ns) {
    switch (progress) {
      case Progress::kFinished: return Next::kFinished;
      case Progress::kWorked: last_work_ns_ = now_ns; return Next::kUpdate;
      case Progress::kWaiting: break;
    }
    return now_ns - last_work_ns_ >= timeout_ns_ ? Next::kInputsLost : Next::kSleep;
  }

  /// After kSleep at `now_ns`: the longest to sleep before updating again.
  std::int64_t sleep_ns(std::int64_t now_ns) const {
    return std::max<std::int64_t>(0, std::min(last_work_ns_ + timeout_ns_ - now_ns, kCycleSliceNs));
  }

  /// A new input timeout from now on (realtime: the plant-lost timeout once the plant ticks).
  void set_timeout_ns(std::int64_t input_timeout_ns) { timeout_ns_ = input_timeout_ns; }

 private:
  std::int64_t timeout_ns_;
  std::int64_t last_work_ns_;
};

}  // namespace pmlsm

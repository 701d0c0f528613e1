// A component's cycle as its executor runs it (ros2_control's controller manager, Drake's
// Simulator): the component has no loop and no wait of its own; its update() takes what has
// arrived, does what it can and says how it went, and the executor decides what comes next. The
// rules for waiting live here, once: work resets the wait; a component waiting longer than its
// input timeout since it last worked has lost its inputs; a component may name a time to be
// updated by (a deadline inside a tick) or not before (the next tick of its clock); a wait is cut
// into slices of at most kCycleSlice so a stop request is seen. Pure: times are given, nothing
// sleeps here.
#pragma once

#include <algorithm>
#include <cstdint>

namespace pmlsm {

/// What one update() did.
enum class Progress {
  kWorked,    ///< it did some work (a tick): update it again at once, more may be ready
  kWaiting,   ///< its inputs are not there yet: update it again when they may be (or by its wake time)
  kSleeping,  ///< nothing to do before its wake time (its clock's next tick), whatever arrives
  kFinished,  ///< its run is over (the exit code with it)
};

/// What one update() returned.
struct CycleStep {
  Progress progress = Progress::kWorked;
  int exit_code = 0;  ///< with kFinished
  /// CLOCK_MONOTONIC ns. kWaiting: update again by this time at the latest, inputs or not (0:
  /// only when they move); kSleeping: not before this time.
  std::int64_t wake_ns = 0;
  /// kSleeping: sleep until wake_ns - spin_ns, then poll the clock to wake_ns (a sleeping thread
  /// may wake tens of microseconds late).
  std::int64_t spin_ns = 0;

  static CycleStep worked() { return {Progress::kWorked}; }
  static CycleStep waiting() { return {Progress::kWaiting}; }
  static CycleStep waiting_until(std::int64_t wake_ns) { return {Progress::kWaiting, 0, wake_ns}; }
  static CycleStep sleeping_until(std::int64_t wake_ns, std::int64_t spin_ns = 0) {
    return {Progress::kSleeping, 0, wake_ns, spin_ns};
  }
  static CycleStep finished(int exit_code) { return {Progress::kFinished, exit_code}; }
};

/// The longest the executor sleeps before updating again: a stop request is seen within it.
inline constexpr std::int64_t kCycleSliceNs = 50'000'000;

/// The executor's decision after an update, for one component.
class CycleWait {
 public:
  enum class Next {
    kUpdate,      ///< update again now
    kSleep,       ///< sleep until wake_ns(), or until the inputs move, then update
    kSleepUntil,  ///< sleep until the step's wake time, whatever arrives, then update
    kInputsLost,  ///< waited longer than the input timeout since it last worked
    kFinished,
  };

  /// `input_timeout_ns`: how long it may wait without working; `start_ns`: when it was activated
  /// (the first wait counts from there).
  CycleWait(std::int64_t input_timeout_ns, std::int64_t start_ns)
      : timeout_ns_(input_timeout_ns), last_work_ns_(start_ns) {}

  Next after(const CycleStep& step, std::int64_t now_ns) {
    switch (step.progress) {
      case Progress::kFinished: return Next::kFinished;
      case Progress::kWorked: last_work_ns_ = now_ns; return Next::kUpdate;
      case Progress::kSleeping:
        // Its own decision, not a wait for inputs: the input timeout counts from its wake time.
        last_work_ns_ = std::max(now_ns, step.wake_ns);
        wake_ns_ = step.wake_ns;
        return Next::kSleepUntil;
      case Progress::kWaiting: break;
    }
    if (now_ns - last_work_ns_ >= timeout_ns_) return Next::kInputsLost;
    wake_ns_ = now_ns + std::max<std::int64_t>(0, std::min(last_work_ns_ + timeout_ns_ - now_ns, kCycleSliceNs));
    if (step.wake_ns > 0) wake_ns_ = std::max(now_ns, std::min(wake_ns_, step.wake_ns));
    return Next::kSleep;
  }
  Next after(Progress progress, std::int64_t now_ns) { return after(CycleStep{progress}, now_ns); }

  /// After kSleep or kSleepUntil: when to update it again (kSleep: at the latest).
  std::int64_t wake_ns() const { return wake_ns_; }

  /// A new input timeout from now on (realtime: the plant-lost timeout once the plant ticks).
  void set_timeout_ns(std::int64_t input_timeout_ns) { timeout_ns_ = input_timeout_ns; }

 private:
  std::int64_t timeout_ns_;
  std::int64_t last_work_ns_;
  std::int64_t wake_ns_ = 0;
};

}  // namespace pmlsm

// The drive loop's clock. Realtime: ticks on absolute CLOCK_MONOTONIC time, t_k = t_0 + k T,
// so time spent computing never accumulates into drift; optionally sleeps to `wake_early`
// before the tick and polls the clock to its start (a sleeping thread may wake tens of
// microseconds late). Lockstep: no pacing; the plant is the clock and the loop moves on as
// soon as the tick's command is in.
#pragma once

#include <cstdint>

namespace pmlsm::drive {

class TickClock {
 public:
  /// @throws std::invalid_argument for period_ns <= 0 or wake_early_ns outside [0, period_ns).
  TickClock(std::int64_t period_ns, bool realtime, std::int64_t wake_early_ns = 0);

  /// Starts tick 0 now.
  void start();
  /// The CLOCK_MONOTONIC time tick k is due.
  std::int64_t tick_start_ns() const { return next_ns_; }
  /// Realtime: advances to the next tick's start time and waits for it; true when the tick
  /// just ended overran it (a deadline miss). Lockstep: returns false at once.
  bool wait_next_tick();
  bool realtime() const { return realtime_; }

  /// How the clock sleeps until a CLOCK_MONOTONIC time: by default clock_nanosleep; a node in
  /// a container hands the thread to the other components instead (its Wakeup).
  using Sleeper = void (*)(void* context, std::int64_t until_ns);
  void set_sleeper(Sleeper sleeper, void* context) {
    sleeper_ = sleeper;
    sleeper_context_ = context;
  }

 private:
  Sleeper sleeper_ = nullptr;
  void* sleeper_context_ = nullptr;
  std::int64_t period_ns_;
  bool realtime_;
  std::int64_t wake_early_ns_;
  std::int64_t next_ns_ = 0;
};

}  // namespace pmlsm::drive

// The drive loop's clock. Realtime: ticks on absolute CLOCK_MONOTONIC time, t_k = t_0 + k T (t_0 a
// whole multiple of T),
// so time spent computing never accumulates into drift; the executor sleeps to `wake_early`
// before the tick and polls the clock to its start (a sleeping thread may wake tens of
// microseconds late). Lockstep: no pacing; the plant is the clock and the loop moves on as
// soon as the tick's command is in. Pure but for reading the clock: nothing sleeps here.
#pragma once

#include <cstdint>

namespace pmlsm::drive {

class TickClock {
 public:
  /// @throws std::invalid_argument for period_ns <= 0 or wake_early_ns outside [0, period_ns).
  TickClock(std::int64_t period_ns, bool realtime, std::int64_t wake_early_ns = 0);

  /// Realtime: tick 0 at the next whole period of CLOCK_MONOTONIC (t_0 = ceil(now / T) T, at most
  /// T away; the caller waits for it), so every loop's ticks fall on the same grid of the host's
  /// clock, the grid a drive's distributed clock runs SYNC0 on when its master keeps it on the host's
  /// time (EtherCAT). Lockstep: now.
  void start();
  /// The CLOCK_MONOTONIC time tick k is due.
  std::int64_t tick_start_ns() const { return next_ns_; }
  /// Realtime: advances to the next tick's start time (tick_start_ns()); true when the tick just
  /// ended overran it (a deadline miss). Lockstep: returns false.
  bool advance();
  bool realtime() const { return realtime_; }
  /// How long before a tick's start the executor stops sleeping and polls the clock.
  std::int64_t wake_early_ns() const { return wake_early_ns_; }

 private:
  std::int64_t period_ns_;
  bool realtime_;
  std::int64_t wake_early_ns_;
  std::int64_t next_ns_ = 0;
};

}  // namespace pmlsm::drive

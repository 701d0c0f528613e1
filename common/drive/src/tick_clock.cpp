#include "pmlsm/drive/tick_clock.hpp"

#include <stdexcept>
#include <string>

#include "pmlsm/util/clock.hpp"

namespace pmlsm::drive {

TickClock::TickClock(std::int64_t period_ns, bool realtime, std::int64_t wake_early_ns)
    : period_ns_(period_ns), realtime_(realtime), wake_early_ns_(wake_early_ns) {
  if (period_ns <= 0) throw std::invalid_argument("period_ns: must be > 0, got " + std::to_string(period_ns));
  if (wake_early_ns < 0 || wake_early_ns >= period_ns) {
    throw std::invalid_argument("wake_early_ns: must be in [0, period " + std::to_string(period_ns) + "), got " +
                                std::to_string(wake_early_ns));
  }
}

void TickClock::start() {
  const std::int64_t now = monotonic_ns();
  next_ns_ = realtime_ ? (now + period_ns_ - 1) / period_ns_ * period_ns_ : now;
}

bool TickClock::advance() {
  if (!realtime_) return false;
  next_ns_ += period_ns_;
  return monotonic_ns() > next_ns_;
}

}  // namespace pmlsm::drive

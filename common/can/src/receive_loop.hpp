// The deadline loop both buses' receive() share (private to common/can/src).
#pragma once

#include <cerrno>
#include <chrono>
#include <cstddef>
#include <ctime>
#include <poll.h>

namespace pmlsm::can::detail {

/// How many dropped datagrams (own echoes, malformed) one receive() call skips past its
/// deadline: enough to clear a full default socket receive buffer, so that a zero timeout
/// still reaches a frame queued behind them, and few enough that a flood cannot hold the
/// caller for more than about a millisecond past the deadline.
inline constexpr std::size_t kDrainBudget = 1024;

/// Calls `attempt()` (non-blocking; returns Poll::frame, ::dropped, ::empty or ::error)
/// until it yields a frame or an error, the queue is empty at the deadline, or the deadline
/// has passed and kDrainBudget datagrams were dropped; waits in ppoll() on `fd` while
/// nothing is queued. Returns the last outcome: frame, error, or empty on timeout.
template <typename Poll, typename Attempt>
Poll receive_until(int fd, std::chrono::nanoseconds timeout, Attempt&& attempt) noexcept {
  using Clock = std::chrono::steady_clock;
  if (timeout < std::chrono::nanoseconds::zero()) timeout = std::chrono::nanoseconds::zero();
  const Clock::time_point deadline = Clock::now() + timeout;
  std::size_t dropped = 0;
  for (;;) {
    const Poll got = attempt();
    if (got == Poll::frame || got == Poll::error) return got;
    if (got == Poll::dropped) {
      if (++dropped < kDrainBudget || Clock::now() < deadline) continue;
      return Poll::empty;
    }
    const Clock::time_point now = Clock::now();
    if (now >= deadline) return Poll::empty;
    const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(deadline - now);
    timespec wait{};
    wait.tv_sec = static_cast<std::time_t>(left.count() / 1'000'000'000);
    wait.tv_nsec = static_cast<long>(left.count() % 1'000'000'000);
    pollfd p{fd, POLLIN, 0};
    if (::ppoll(&p, 1, &wait, nullptr) < 0 && errno != EINTR) return Poll::error;
  }
}

}  // namespace pmlsm::can::detail

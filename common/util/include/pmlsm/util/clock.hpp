// Clock helpers: the one copy of the conversions every loop and stamp needs.
// CLOCK_MONOTONIC paces loops and measures intervals (it never jumps);
// CLOCK_REALTIME stamps samples, so latencies can be taken across hosts whose
// clocks are synchronised.
#pragma once

#include <time.h>

#include <cerrno>
#include <cstdint>

namespace pmlsm {

inline constexpr std::int64_t kNanosecondsPerSecond = 1000000000LL;

inline std::int64_t to_ns(const timespec& t) {
  return static_cast<std::int64_t>(t.tv_sec) * kNanosecondsPerSecond + t.tv_nsec;
}

/// ns -> timespec with 0 <= tv_nsec < 1e9 (also for negative ns).
inline timespec to_timespec(std::int64_t ns) {
  std::int64_t sec = ns / kNanosecondsPerSecond;
  std::int64_t nsec = ns % kNanosecondsPerSecond;
  if (nsec < 0) {
    nsec += kNanosecondsPerSecond;
    --sec;
  }
  timespec t{};
  t.tv_sec = static_cast<time_t>(sec);
  t.tv_nsec = static_cast<long>(nsec);
  return t;
}

/// CLOCK_MONOTONIC in ns: loop pacing, watchdogs, intervals.
inline std::int64_t monotonic_ns() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return to_ns(t);
}

/// CLOCK_REALTIME in ns: stamps compared across processes and hosts.
inline std::int64_t wall_time_ns() {
  timespec t{};
  clock_gettime(CLOCK_REALTIME, &t);
  return to_ns(t);
}

/// Sleeps until the CLOCK_MONOTONIC time `ns` (absolute: no drift from the
/// time spent computing; an interrupted sleep is resumed).
inline void sleep_until_monotonic_ns(std::int64_t ns) {
  const timespec t = to_timespec(ns);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, nullptr) == EINTR) {
  }
}

}  // namespace pmlsm

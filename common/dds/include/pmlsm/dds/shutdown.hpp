// Clean shutdown on SIGINT/SIGTERM: the handler only sets a flag (the one
// async-signal-safe thing to do); node loops poll stop_requested() and wake
// any Wakeup they wait on at their next deadline.
#pragma once

#include <chrono>
#include <cstdint>

namespace pmlsm::dds {

/// After a stop request, how long a node may still spend handing over what it wrote (flushing
/// writers, closing the publisher thread's queues): a reader that never acknowledges must not
/// hold a shutdown, and every node and container is to be gone within 1 s of SIGINT.
inline constexpr std::chrono::milliseconds kStopGrace{400};

/// Installs the SIGINT/SIGTERM handlers. Call once at the start of main().
void install_shutdown_handlers();
bool stop_requested();
/// Lets code other than the signal handler end the loops (tests, fatal errors).
void request_stop();
/// CLOCK_MONOTONIC ns of the first stop request; 0 while there was none.
std::int64_t stop_requested_at_ns();
/// `deadline_ns` (CLOCK_MONOTONIC), cut to the stop request's time + kStopGrace once there was one.
std::int64_t within_stop_grace(std::int64_t deadline_ns);

}  // namespace pmlsm::dds

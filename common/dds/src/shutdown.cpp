#include "pmlsm/dds/shutdown.hpp"

#include <time.h>

#include <algorithm>
#include <atomic>
#include <csignal>

namespace pmlsm::dds {

namespace {
// The process-wide flag and the time it was first set: a signal handler can reach nothing else.
volatile std::sig_atomic_t g_stop = 0;
// Lock-free on every target we build for (a signal handler may store to it).
std::atomic<std::int64_t> g_stop_at_ns{0};
static_assert(std::atomic<std::int64_t>::is_always_lock_free, "the stop time is stored from a signal handler");

void mark_stop() {
  g_stop = 1;
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);  // async-signal-safe (POSIX)
  std::int64_t expected = 0;
  const std::int64_t now = static_cast<std::int64_t>(t.tv_sec) * 1000000000LL + t.tv_nsec;
  g_stop_at_ns.compare_exchange_strong(expected, now > 0 ? now : 1);
}

extern "C" void on_signal(int) { mark_stop(); }
}  // namespace

void install_shutdown_handlers() {
  struct sigaction action {};
  action.sa_handler = on_signal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

bool stop_requested() { return g_stop != 0; }

void request_stop() { mark_stop(); }

std::int64_t stop_requested_at_ns() { return g_stop_at_ns.load(); }

std::int64_t within_stop_grace(std::int64_t deadline_ns) {
  const std::int64_t at = stop_requested_at_ns();
  if (at == 0) return deadline_ns;
  return std::min(deadline_ns, at + std::chrono::duration_cast<std::chrono::nanoseconds>(kStopGrace).count());
}

}  // namespace pmlsm::dds

#include "pmlsm/dds/shutdown.hpp"

#include <csignal>

namespace pmlsm::dds {

namespace {
// The one process-wide flag: a signal handler can reach nothing else.
volatile std::sig_atomic_t g_stop = 0;

extern "C" void on_signal(int) { g_stop = 1; }
}  // namespace

void install_shutdown_handlers() {
  struct sigaction action {};
  action.sa_handler = on_signal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

bool stop_requested() { return g_stop != 0; }

void request_stop() { g_stop = 1; }

}  // namespace pmlsm::dds

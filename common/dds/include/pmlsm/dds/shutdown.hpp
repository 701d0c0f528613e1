// Clean shutdown on SIGINT/SIGTERM: the handler only sets a flag (the one
// async-signal-safe thing to do); node loops poll stop_requested() and wake
// any Wakeup they wait on at their next deadline.
#pragma once

namespace pmlsm::dds {

/// Installs the SIGINT/SIGTERM handlers. Call once at the start of main().
void install_shutdown_handlers();
bool stop_requested();
/// Lets code other than the signal handler end the loops (tests, fatal errors).
void request_stop();

}  // namespace pmlsm::dds

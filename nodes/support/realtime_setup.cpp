#include "realtime_setup.hpp"

#include <fcntl.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <stdexcept>

namespace pmlsm::node {

namespace {
std::string refused(const std::string& what, int error) {
  return what + " refused: " + std::strerror(error);
}
}  // namespace

RealtimeSetup::RealtimeSetup(const RealtimeOptions& o) {
  if (o.rt_priority < 0 || o.rt_priority > 99) {
    throw std::invalid_argument("rt priority must be 0 (off) or 1..99, got " + std::to_string(o.rt_priority));
  }
  if (o.cpu_dma_latency_us > 10'000'000) {
    throw std::invalid_argument("cpu_dma_latency must be at most 10000000 us, got " +
                                std::to_string(o.cpu_dma_latency_us));
  }
  // Normal threads' timers may fire up to 50 us late by default (timer slack),
  // which is a twentieth of a 1 ms tick; threads made later inherit the slack.
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  summary_ = "timer slack 1 ns";
  if (o.cpu_dma_latency_us >= 0) {
    // The request holds while the file stays open (Documentation/power/pm_qos_interface.rst).
    latency_fd_ = ::open(o.cpu_dma_latency_device.c_str(), O_WRONLY | O_CLOEXEC);
    if (latency_fd_ < 0) {
      throw std::runtime_error(refused("opening " + o.cpu_dma_latency_device, errno) +
                               " (a PM QoS request needs root)");
    }
    const std::int32_t value = o.cpu_dma_latency_us;
    if (::write(latency_fd_, &value, sizeof value) != static_cast<ssize_t>(sizeof value)) {
      const int error = errno;
      ::close(latency_fd_);
      latency_fd_ = -1;
      throw std::runtime_error(refused("writing " + std::to_string(value) + " to " + o.cpu_dma_latency_device, error));
    }
    summary_ += ", cpu_dma_latency " + std::to_string(value) + " us";
  }
  if (o.rt_priority > 0) {
    sched_param param{};
    param.sched_priority = o.rt_priority;
    if (sched_setscheduler(0, SCHED_FIFO, &param) != 0) {
      const int error = errno;
      if (latency_fd_ >= 0) ::close(latency_fd_);
      throw std::runtime_error(refused("SCHED_FIFO priority " + std::to_string(o.rt_priority), error) +
                               " (needs CAP_SYS_NICE or an rtprio limit, ulimit -r)");
    }
    // Page faults in the loop would cost more than a tick's work.
    if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
      const int error = errno;
      if (latency_fd_ >= 0) ::close(latency_fd_);
      throw std::runtime_error(refused("mlockall", error) + " (needs CAP_IPC_LOCK or a memlock limit, ulimit -l)");
    }
    summary_ = "SCHED_FIFO " + std::to_string(o.rt_priority) + ", memory locked, " + summary_;
  }
}

RealtimeSetup::~RealtimeSetup() {
  if (latency_fd_ >= 0) ::close(latency_fd_);
}

}  // namespace pmlsm::node

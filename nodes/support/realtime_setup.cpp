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
std::string refused(const std::string& what, int error) { return what + " refused: " + std::strerror(error); }
}  // namespace

RealtimeSetup::LatencyRequest::~LatencyRequest() {
  if (fd >= 0) ::close(fd);
}

RealtimeSetup::RealtimeSetup(const RealtimeOptions& o) {
  if (o.rt_priority < 0 || o.rt_priority > 99) {
    throw std::invalid_argument("rt priority must be 0 (off) or 1..99, got " + std::to_string(o.rt_priority));
  }
  if (o.cpu_dma_latency_us < -1 || o.cpu_dma_latency_us > 10'000'000) {
    throw std::invalid_argument("cpu_dma_latency must be -1 (no request) or 0..10000000 us, got " +
                                std::to_string(o.cpu_dma_latency_us));
  }
  // Normal threads' timers may fire up to 50 us late by default (timer slack),
  // which is a twentieth of a 1 ms tick; threads made later inherit the slack.
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  summary_ = "timer slack 1 ns";
  if (o.cpu_dma_latency_us >= 0) {
    // The request holds while the file stays open (Documentation/power/pm_qos_interface.rst).
    latency_.fd = ::open(o.cpu_dma_latency_device.c_str(), O_WRONLY | O_CLOEXEC);
    if (latency_.fd < 0) {
      throw std::runtime_error(refused("opening " + o.cpu_dma_latency_device, errno) +
                               " (a PM QoS request needs root)");
    }
    const std::int32_t value = o.cpu_dma_latency_us;
    if (::write(latency_.fd, &value, sizeof value) != static_cast<ssize_t>(sizeof value)) {
      throw std::runtime_error(refused("writing " + std::to_string(value) + " to " + o.cpu_dma_latency_device, errno));
    }
    summary_ += ", cpu_dma_latency " + std::to_string(value) + " us";
  }
  if (o.rt_priority > 0) {
    sched_param param{};
    param.sched_priority = o.rt_priority;
    if (sched_setscheduler(0, SCHED_FIFO, &param) != 0) {
      throw std::runtime_error(refused("SCHED_FIFO priority " + std::to_string(o.rt_priority), errno) +
                               " (needs CAP_SYS_NICE or an rtprio limit, ulimit -r)");
    }
    // Page faults in the loop would cost more than a tick's work. MCL_FUTURE also locks
    // the stacks of the threads Fast DDS starts later (8 MB each by default).
    if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
      const int error = errno;
      sched_param normal{};
      sched_setscheduler(0, SCHED_OTHER, &normal);  // all or nothing
      throw std::runtime_error(refused("mlockall", error) + " (needs CAP_IPC_LOCK or a memlock limit, ulimit -l)");
    }
    summary_ = "SCHED_FIFO " + std::to_string(o.rt_priority) + ", memory locked, " + summary_;
  }
}

}  // namespace pmlsm::node

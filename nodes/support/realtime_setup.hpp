// What a node on the control chain asks of the operating system, as a lab
// rig's real-time tuning does: a fixed real-time priority with locked memory,
// a PM QoS request that keeps the cores out of deep idle states, and a timer
// slack of 1 ns. Applied before the DDS participant exists, so every thread
// Fast DDS starts inherits the priority and the slack. No DDS here.
#pragma once

#include <string>

namespace pmlsm::node {

struct RealtimeOptions {
  /// SCHED_FIFO priority, 1..99, with all memory locked (mlockall); 0 leaves
  /// the scheduler and memory alone.
  int rt_priority = 0;
  /// Held for the node's life through /dev/cpu_dma_latency: the cores may
  /// only enter idle states that wake within this many microseconds (0: poll,
  /// never halt). On a virtual machine, waking a halted virtual core costs
  /// tens of microseconds per message hop. Negative: no request.
  int cpu_dma_latency_us = -1;
  /// The PM QoS device; a test points it at a file.
  std::string cpu_dma_latency_device = "/dev/cpu_dma_latency";
};

/// Applies RealtimeOptions for its lifetime (the latency request ends when it
/// is destroyed; priority and locking stay with the process).
class RealtimeSetup {
 public:
  /// @throws std::invalid_argument for a priority outside 0..99 or a latency over 10 s
  /// @throws std::runtime_error naming the call and the reason when the system refuses
  explicit RealtimeSetup(const RealtimeOptions& options);
  RealtimeSetup(const RealtimeSetup&) = delete;
  RealtimeSetup& operator=(const RealtimeSetup&) = delete;

  /// One line saying what was applied ("SCHED_FIFO 80, memory locked, timer slack 1 ns, cpu_dma_latency 0 us").
  const std::string& summary() const { return summary_; }

 private:
  /// Closes the PM QoS device (ending the request) on every path, a throwing constructor included.
  struct LatencyRequest {
    int fd = -1;
    ~LatencyRequest();
  } latency_;
  std::string summary_;
};

}  // namespace pmlsm::node

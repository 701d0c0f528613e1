// A single-threaded, in-memory CAN bus with a fake clock for the CANopen tests: every exchange
// between a master and a slave is deterministic.
#pragma once

#include <algorithm>
#include <cstdint>
#include <deque>
#include <functional>
#include <vector>

#include "pmlsm/can/can_bus.hpp"

namespace pmlsm::canopen::test {

struct FakeClock {
  std::int64_t ns = 1000000000;
};

/// The master's end of the bus: what it sends goes straight to the slave (which may answer
/// into the inbox); receive() on an empty inbox moves the fake clock on, letting the slave
/// produce its heartbeats, up to the timeout.
class MemoryBus final : public can::CanBus {
 public:
  explicit MemoryBus(FakeClock& clock) : clock_(clock) {}
  bool send(const can::CanFrame& frame) noexcept override {
    sent.push_back(frame);
    if (on_send) on_send(frame);
    return true;
  }
  bool receive(can::CanFrame& frame, std::chrono::nanoseconds timeout) noexcept override {
    const std::int64_t deadline = clock_.ns + timeout.count();
    for (;;) {
      if (!inbox.empty()) {
        frame = inbox.front();
        inbox.pop_front();
        clock_.ns += 10000;  // 10 us on the wire
        return true;
      }
      if (clock_.ns >= deadline) return false;
      clock_.ns = std::min(deadline, clock_.ns + 1000000);
      if (on_idle) on_idle();
    }
  }
  std::function<void(const can::CanFrame&)> on_send;
  std::function<void()> on_idle;
  std::deque<can::CanFrame> inbox;
  std::vector<can::CanFrame> sent;

 private:
  FakeClock& clock_;
};

}  // namespace pmlsm::canopen::test

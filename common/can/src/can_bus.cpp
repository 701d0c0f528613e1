#include "pmlsm/can/can_bus.hpp"

namespace pmlsm::can {

int CanBus::fd() const noexcept { return -1; }

std::string CanBus::describe() const { return "CAN bus"; }

CanBusCounters CanBus::counters() const noexcept {
  CanBusCounters c;
  c.sent = sent_.load(std::memory_order_relaxed);
  c.received = received_.load(std::memory_order_relaxed);
  c.send_errors = send_errors_.load(std::memory_order_relaxed);
  c.receive_errors = receive_errors_.load(std::memory_order_relaxed);
  c.malformed_dropped = malformed_.load(std::memory_order_relaxed);
  c.own_echo_dropped = own_echo_.load(std::memory_order_relaxed);
  c.unsupported_dropped = unsupported_.load(std::memory_order_relaxed);
  return c;
}

}  // namespace pmlsm::can

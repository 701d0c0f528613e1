// A CAN bus on a Linux SocketCAN interface (can0, vcan0): one CAN_RAW socket bound to the
// interface, classic frames only (no CAN FD, no error frames). The kernel's defaults give
// the same own-frame behaviour as UdpMulticastBus: other sockets on the host receive what
// this one sends (CAN_RAW_LOOPBACK on), this one does not (CAN_RAW_RECV_OWN_MSGS off).
#pragma once

#include <chrono>
#include <string>

#include "pmlsm/can/can_bus.hpp"

namespace pmlsm::can {

class SocketCanBus final : public CanBus {
 public:
  /// Opens a CAN_RAW socket on `interface_name`. Throws std::invalid_argument for an
  /// empty or too long name, std::system_error (a std::runtime_error) naming the interface,
  /// the failed call and errno's text when the kernel has no AF_CAN ("Address family not
  /// supported by protocol", code() == std::errc::address_family_not_supported), the
  /// interface does not exist or is not a CAN interface.
  explicit SocketCanBus(const std::string& interface_name);
  ~SocketCanBus() override;

  bool send(const CanFrame& frame) noexcept override;
  bool receive(CanFrame& frame, std::chrono::nanoseconds timeout) noexcept override;
  int fd() const noexcept override { return fd_; }
  std::string describe() const override { return description_; }

 private:
  enum class Poll { frame, dropped, empty, error };
  Poll receive_one(CanFrame& frame) noexcept;

  int fd_ = -1;
  std::string description_;
};

}  // namespace pmlsm::can

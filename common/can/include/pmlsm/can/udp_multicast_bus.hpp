// A virtual CAN bus on UDP multicast, wire-compatible with python-can's "udp_multicast"
// interface (python-can 4.1): every frame is one datagram holding one MessagePack map (see
// pycan_wire.hpp) sent to a multicast group and port; every member of the group hears it.
// For hosts and containers without SocketCAN, and for talking to python-can tools.
//
// Sockets. As python-can: the receiving socket has SO_REUSEADDR, is bound to the group's
// port and joined to the group (here bound to the group address, so other groups on the
// same port stay out). Unlike python-can, frames leave through a second socket, bound to
// an ephemeral port on the interface and connected to the group, whose TTL / hop limit and
// multicast loopback are set from the params.
//
// Own echoes. With loopback on, every datagram also comes back to every member on this
// host, the sender included (that is how other processes here hear it). python-can 4.1 does
// not filter these: its bus receives its own frames. This bus drops datagrams whose source
// address and port are those of its own sending socket (an ephemeral port no other socket
// on the host can hold), counting them as own_echo_dropped; frames of every other bus, in
// this process or another, are received.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <string>
#include <sys/socket.h>

#include "pmlsm/can/can_bus.hpp"

namespace pmlsm::can {

struct UdpMulticastParams {
  /// Multicast group, a numeric IPv4 (224.0.0.0/4) or IPv6 (ff00::/8) address; its family
  /// selects IPv4 or IPv6. python-can's IPv4 default; its IPv6 default is
  /// "ff15:7079:7468:6f6e:6465:6d6f:6d63:6173".
  std::string group = "239.74.163.2";
  /// UDP port, 1..65535 (python-can's default).
  int port = 43113;
  /// The interface to join and send on. IPv4 group: an IPv4 address of a local interface,
  /// "127.0.0.1" for loopback, "0.0.0.0" for the default route's interface (what python-can
  /// uses). IPv6 group: an interface name ("lo", "eth0") or "::" for the default route's.
  std::string interface_address = "127.0.0.1";
  /// IPv4 time to live / IPv6 hop limit of sent datagrams, 0..255 (1: this link only).
  int ttl = 1;
  /// Whether sent datagrams are also delivered to members on this host (other processes
  /// need it; this bus drops its own either way). Acts on real interfaces only: on the
  /// loopback interface every datagram comes back in whatever this says.
  bool loopback = true;
};

/// Checks `params`; throws std::invalid_argument naming the field and the value
/// ("port: must be in [1, 65535], got 0").
void validate(const UdpMulticastParams& params);

class UdpMulticastBus final : public CanBus {
 public:
  /// Validates `params` (std::invalid_argument), opens, binds and joins (std::system_error,
  /// a std::runtime_error, naming the group, port, interface, the failed call and errno).
  explicit UdpMulticastBus(const UdpMulticastParams& params);
  ~UdpMulticastBus() override;

  bool send(const CanFrame& frame) noexcept override;
  bool receive(CanFrame& frame, std::chrono::nanoseconds timeout) noexcept override;
  /// The receiving socket.
  int fd() const noexcept override { return rx_fd_; }
  std::string describe() const override { return description_; }

  const UdpMulticastParams& params() const noexcept { return params_; }

  /// Largest datagram read whole; longer ones are dropped as malformed (python-can reads
  /// up to 4096 bytes; a classic frame's map is at most 164).
  static constexpr std::size_t kReceiveBufferSize = 4096;

 private:
  enum class Poll { frame, dropped, empty, error };
  Poll receive_one(CanFrame& frame) noexcept;
  bool is_own(const sockaddr_storage& source) const noexcept;

  UdpMulticastParams params_;
  int family_ = 0;
  int rx_fd_ = -1;
  int tx_fd_ = -1;
  sockaddr_storage own_source_{};  // the sending socket's address and port
  std::string description_;
  std::array<std::uint8_t, kReceiveBufferSize> rx_buffer_{};
};

}  // namespace pmlsm::can

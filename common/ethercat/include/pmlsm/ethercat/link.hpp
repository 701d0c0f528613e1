// Where EtherCAT frames travel: a Link sends an Ethernet frame and receives the next one. Three
// transports: a wire inside one process (tests), EtherCAT over UDP (port 34980: the same bytes
// from the EtherCAT header on, for machines and users without raw-socket rights) and, on Linux, a
// raw AF_PACKET socket on an interface (the real bus).
#pragma once

#include <array>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <string>

#include "pmlsm/ethercat/frame.hpp"

namespace pmlsm::ethercat {

class Link {
 public:
  virtual ~Link() = default;
  /// Sends one Ethernet frame (FrameBuilder::ethernet()). Never throws: false when the frame
  /// did not go (the caller counts it as lost).
  virtual bool send(Bytes ethernet_frame) = 0;
  /// The next frame as an Ethernet frame into `buffer` (kMaxEthernetFrameBytes long), waiting up
  /// to timeout_ns; 0 when none came. Never throws.
  virtual std::size_t receive(std::uint8_t* buffer, std::int64_t timeout_ns) = 0;
  /// The descriptor a frame makes readable (to wait on it with others); -1 when there is none.
  virtual int fd() const { return -1; }
  /// When the last frame receive() returned reached this host, CLOCK_MONOTONIC ns, as the kernel
  /// stamped it: a slave that reads its frames late still takes them in the order they came
  /// among its own events (SYNC0). -1 when the transport does not know.
  virtual std::int64_t last_arrival_ns() const { return -1; }
};

/// Two ends of a wire in one process: what one end sends, the other receives, in order. Up to
/// kQueuedFrames wait at an end; a frame beyond them is dropped, as a busy NIC would.
class InProcessWire {
 public:
  static constexpr std::size_t kQueuedFrames = 16;

  Link& end_a() { return a_; }
  Link& end_b() { return b_; }

 private:
  class Queue {
   public:
    bool push(Bytes frame);
    std::size_t pop(std::uint8_t* buffer, std::int64_t timeout_ns);

   private:
    std::mutex mutex_;
    std::condition_variable ready_;
    std::array<std::array<std::uint8_t, kMaxEthernetFrameBytes>, kQueuedFrames> frames_{};
    std::array<std::size_t, kQueuedFrames> sizes_{};
    std::size_t head_ = 0;
    std::size_t count_ = 0;
  };
  class End final : public Link {
   public:
    End(Queue& outgoing, Queue& incoming) : outgoing_(outgoing), incoming_(incoming) {}
    bool send(Bytes ethernet_frame) override { return outgoing_.push(ethernet_frame); }
    std::size_t receive(std::uint8_t* buffer, std::int64_t timeout_ns) override {
      return incoming_.pop(buffer, timeout_ns);
    }

   private:
    Queue& outgoing_;
    Queue& incoming_;
  };
  Queue to_a_;
  Queue to_b_;
  End a_{to_b_, to_a_};
  End b_{to_a_, to_b_};
};

struct UdpLinkParams {
  std::string local_address = "127.0.0.1";  ///< the IPv4 address to bind
  std::uint16_t local_port = kUdpPort;      ///< 0: one the kernel picks (bound_port())
  std::string peer_address = "127.0.0.1";   ///< where frames go
  /// 0: to whoever sent the last frame received (a slave answers its master wherever it is;
  /// nothing can be sent before a frame came).
  std::uint16_t peer_port = kUdpPort;
};

/// EtherCAT over UDP: each frame's EtherCAT part (header and datagrams) in one datagram. A
/// received one is handed on behind an Ethernet header (EtherType 0x88A4, the addresses zero),
/// so both transports parse alike.
class UdpLink final : public Link {
 public:
  /// @throws std::system_error naming the address when the socket cannot be made or bound.
  explicit UdpLink(const UdpLinkParams& params);
  ~UdpLink() override;
  UdpLink(const UdpLink&) = delete;
  UdpLink& operator=(const UdpLink&) = delete;
  bool send(Bytes ethernet_frame) override;
  std::size_t receive(std::uint8_t* buffer, std::int64_t timeout_ns) override;
  int fd() const override { return fd_; }
  std::int64_t last_arrival_ns() const override { return last_arrival_ns_; }
  /// Datagrams received that were no EtherCAT frame (too short): dropped.
  std::uint64_t dropped() const { return dropped_; }
  /// The port the link is bound to.
  std::uint16_t bound_port() const { return bound_port_; }

 private:
  int fd_ = -1;
  std::array<std::uint8_t, 16> peer_{};  ///< sockaddr_in
  bool answer_sender_ = false;
  bool peer_known_ = false;
  std::uint16_t bound_port_ = 0;
  std::uint64_t dropped_ = 0;
  std::int64_t last_arrival_ns_ = -1;
};

/// Raw Ethernet on an interface (Linux AF_PACKET, EtherType 0x88A4 only): the real bus. Needs
/// CAP_NET_RAW (root, or the capability on the program: docs/ethercat.md). Frames this socket
/// sent are not received back.
class RawSocketLink final : public Link {
 public:
  /// @throws std::system_error naming the interface when it is not there or the rights are not.
  explicit RawSocketLink(const std::string& interface);
  ~RawSocketLink() override;
  RawSocketLink(const RawSocketLink&) = delete;
  RawSocketLink& operator=(const RawSocketLink&) = delete;
  bool send(Bytes ethernet_frame) override;
  std::size_t receive(std::uint8_t* buffer, std::int64_t timeout_ns) override;
  int fd() const override { return fd_; }
  std::int64_t last_arrival_ns() const override { return last_arrival_ns_; }
  /// The interface's own MAC address (a master sends from it).
  const MacAddress& mac() const { return mac_; }

 private:
  int fd_ = -1;
  int interface_index_ = 0;
  MacAddress mac_{};
  std::int64_t last_arrival_ns_ = -1;
};

}  // namespace pmlsm::ethercat

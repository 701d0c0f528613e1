// The seam between CAN users (the CANopen codecs, the drive bridge) and a CAN transport:
// SocketCanBus (a kernel CAN_RAW socket) and UdpMulticastBus (python-can's "udp_multicast"
// virtual bus, for hosts without SocketCAN). Users cannot tell them apart.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <string>

#include "pmlsm/can/can_frame.hpp"

namespace pmlsm::can {

inline constexpr std::uint32_t kMaxStandardId = 0x7FF;       ///< 11-bit identifiers
inline constexpr std::uint32_t kMaxExtendedId = 0x1FFFFFFF;  ///< 29-bit identifiers
inline constexpr std::uint8_t kMaxClassicDlc = 8;

/// True when `frame` is a classic CAN frame a bus can carry: dlc <= 8 and the id fits
/// 11 bits (extended == false) or 29 bits (extended == true).
constexpr bool is_valid_frame(const CanFrame& frame) noexcept {
  return frame.dlc <= kMaxClassicDlc && frame.id <= (frame.extended ? kMaxExtendedId : kMaxStandardId);
}

/// A snapshot of a bus's counters (each counts since construction).
struct CanBusCounters {
  std::uint64_t sent = 0;                 ///< frames handed to the transport
  std::uint64_t received = 0;             ///< frames returned by receive()
  std::uint64_t send_errors = 0;          ///< send() returned false (invalid frame, socket error)
  std::uint64_t receive_errors = 0;       ///< receive() gave up on a socket error (not a timeout)
  std::uint64_t malformed_dropped = 0;    ///< undecodable or out-of-range input, dropped
  std::uint64_t own_echo_dropped = 0;     ///< our own transmissions coming back, dropped
  std::uint64_t unsupported_dropped = 0;  ///< well-formed but not classic data/remote frames
                                          ///< (CAN FD, error frames), dropped
};

/// A CAN transport. Implementations are neither copyable nor movable.
///
/// Threads: send() may be called from any thread, also concurrently with receive();
/// receive() from one thread at a time. counters() from anywhere.
class CanBus {
 public:
  virtual ~CanBus() = default;
  CanBus(const CanBus&) = delete;
  CanBus& operator=(const CanBus&) = delete;
  CanBus(CanBus&&) = delete;
  CanBus& operator=(CanBus&&) = delete;

  /// Sends one frame without blocking. Returns false (and counts a send error) when the
  /// frame is invalid (see is_valid_frame) or the transport refuses it (e.g. a full send
  /// queue); never throws. Does not allocate.
  virtual bool send(const CanFrame& frame) noexcept = 0;

  /// Waits up to `timeout` (<= 0: only what is already queued) for the next frame from
  /// another node and stores it in `frame`. Returns false on timeout or a socket error
  /// (counted), leaving `frame` unspecified. Input that is not a valid classic frame and
  /// the node's own transmissions are dropped and counted, and waiting goes on until the
  /// deadline; queued ones are skipped also past it (up to 1024 a call), so a zero timeout
  /// reaches a frame queued behind them. Data bytes past dlc (all of them for remote
  /// frames) are zero. Never throws; does not allocate.
  virtual bool receive(CanFrame& frame, std::chrono::nanoseconds timeout) noexcept = 0;

  /// A descriptor that becomes readable when receive() may have something, for an
  /// event loop (-1 when there is none). Readable does not imply a frame: the datagram may
  /// turn out to be dropped, so poll receive() with a zero timeout.
  virtual int fd() const noexcept;

  /// One line for logs: the transport and its addresses.
  virtual std::string describe() const;

  CanBusCounters counters() const noexcept;

 protected:
  CanBus() = default;

  void count_sent() noexcept { sent_.fetch_add(1, std::memory_order_relaxed); }
  void count_received() noexcept { received_.fetch_add(1, std::memory_order_relaxed); }
  void count_send_error() noexcept { send_errors_.fetch_add(1, std::memory_order_relaxed); }
  void count_receive_error() noexcept { receive_errors_.fetch_add(1, std::memory_order_relaxed); }
  void count_malformed() noexcept { malformed_.fetch_add(1, std::memory_order_relaxed); }
  void count_own_echo() noexcept { own_echo_.fetch_add(1, std::memory_order_relaxed); }
  void count_unsupported() noexcept { unsupported_.fetch_add(1, std::memory_order_relaxed); }

 private:
  std::atomic<std::uint64_t> sent_{0};
  std::atomic<std::uint64_t> received_{0};
  std::atomic<std::uint64_t> send_errors_{0};
  std::atomic<std::uint64_t> receive_errors_{0};
  std::atomic<std::uint64_t> malformed_{0};
  std::atomic<std::uint64_t> own_echo_{0};
  std::atomic<std::uint64_t> unsupported_{0};
};

}  // namespace pmlsm::can

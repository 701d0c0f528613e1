// python-can's "udp_multicast" wire format (python-can 4.1, can/interfaces/udp_multicast/
// utils.py): one MessagePack map per UDP datagram, the keyword arguments of can.Message,
// packed by msgpack.packb(..., use_bin_type=True):
//
//   key (str)                value as python-can packs it
//   "timestamp"              float 64 (seconds; receivers replace it with their own)
//   "arbitration_id"         uint (smallest encoding)
//   "is_extended_id"         bool
//   "is_remote_frame"        bool
//   "is_error_frame"         bool
//   "channel"                nil (or whatever the sender put in Message.channel)
//   "dlc"                    uint
//   "data"                   bin (dlc bytes; empty for remote frames)
//   "is_fd"                  bool
//   "bitrate_switch"         bool
//   "error_state_indicator"  bool
//
// encode() writes exactly these 11 keys in this order, so that python-can's
// can.Message(check=True, **map) accepts them; for timestamp 0.0 the bytes equal python-can's.
#pragma once

#include <cstddef>
#include <cstdint>

#include "pmlsm/can/can_frame.hpp"

namespace pmlsm::can::pycan_wire {

/// Enough for any encoded classic frame (the 11-key map is at most 164 bytes).
inline constexpr std::size_t kMaxEncodedSize = 256;

/// Encodes `frame` (which must satisfy is_valid_frame) with `timestamp_s` into `out`.
/// Returns the datagram's length, or 0 when the frame is invalid or `capacity` too small.
/// Does not allocate or throw.
std::size_t encode(const CanFrame& frame, double timestamp_s, std::uint8_t* out, std::size_t capacity) noexcept;

enum class DecodeStatus {
  ok,           ///< a classic data or remote frame
  malformed,    ///< not MessagePack, not a map, a missing or mistyped field, out of range
  unsupported,  ///< well-formed, but a CAN FD or error frame
};

struct DecodeResult {
  DecodeStatus status;
  const char* reason;  ///< static text, "" for ok (for tests and diagnostics)
};

/// Decodes one datagram. Required keys: arbitration_id (non-negative int), is_extended_id
/// and is_remote_frame (bool), dlc (non-negative int), data (bin, nil or an array of ints in
/// 0..255). Optional: is_error_frame, is_fd, bitrate_switch, error_state_indicator (bool, default
/// false); timestamp, channel and unknown keys are skipped whatever their type. Checks as
/// python-can's Message(check=True) does: ids within 11/29 bits, dlc <= 8, len(data) == dlc
/// for data frames (remote frames: data ignored, at most 8 bytes), no trailing bytes.
/// On ok, `frame` holds the frame with data bytes past dlc zeroed; otherwise `frame` is
/// unspecified. Bounded work, no allocation, never throws, for any input.
DecodeResult decode(const std::uint8_t* data, std::size_t size, CanFrame& frame) noexcept;

}  // namespace pmlsm::can::pycan_wire

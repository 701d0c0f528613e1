// Frames for the CANopen targets, from fuzz input. Each frame is
//   flags (bit 0 RTR, bit 1 extended id, bits 2-3 for the target, bits 4-7 the DLC modulo 9),
//   the id (2 bytes, 11 bits; 4 bytes, 29 bits when extended), 8 data bytes, and the
//   milliseconds that pass before it arrives (1 byte).
// Every frame is one a transport can deliver (is_valid_frame): the transports refuse others.
#pragma once

#include "fuzz_support.hpp"
#include "pmlsm/can/can_bus.hpp"
#include "pmlsm/canopen/frame.hpp"

namespace pmlsm::fuzz {

struct FuzzFrame {
  canopen::CanFrame frame{};
  std::uint8_t target_bits = 0;  // flags bits 2-3
  std::uint8_t elapsed_ms = 0;
};

inline FuzzFrame next_frame(ByteReader& in) {
  FuzzFrame out;
  const std::uint8_t flags = in.u8();
  out.frame.rtr = (flags & 1U) != 0;
  out.frame.extended = (flags & 2U) != 0;
  out.target_bits = static_cast<std::uint8_t>((flags >> 2) & 3U);
  out.frame.dlc = static_cast<std::uint8_t>((flags >> 4) % 9);
  out.frame.id = out.frame.extended ? in.u32() & can::kMaxExtendedId : in.u16() & can::kMaxStandardId;
  for (std::uint8_t& byte : out.frame.data) byte = in.u8();
  out.elapsed_ms = in.u8();
  return out;
}

}  // namespace pmlsm::fuzz

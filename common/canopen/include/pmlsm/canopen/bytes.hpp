// Little-endian field access in CAN payloads (CANopen transmits every number least significant
// byte first) and a zeroed frame. All noexcept, no allocation.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "pmlsm/canopen/frame.hpp"

namespace pmlsm::canopen {

inline constexpr std::uint8_t kCanMaxDlc = 8;
/// Largest 11-bit identifier.
inline constexpr std::uint32_t kCanMaxStandardId = 0x7FF;

/// A data frame (not remote, 11-bit) with the given id and DLC and all 8 data bytes zero.
inline CanFrame make_frame(std::uint32_t id, std::uint8_t dlc) noexcept {
  CanFrame frame{};
  frame.id = id;
  frame.dlc = dlc;
  frame.data.fill(0);
  frame.rtr = false;
  frame.extended = false;
  return frame;
}

inline std::uint16_t get_u16_le(const std::array<std::uint8_t, 8>& data, std::size_t at) noexcept {
  return static_cast<std::uint16_t>(data[at] | (data[at + 1] << 8));
}

inline std::uint32_t get_u32_le(const std::array<std::uint8_t, 8>& data, std::size_t at) noexcept {
  return static_cast<std::uint32_t>(data[at]) | (static_cast<std::uint32_t>(data[at + 1]) << 8) |
         (static_cast<std::uint32_t>(data[at + 2]) << 16) | (static_cast<std::uint32_t>(data[at + 3]) << 24);
}

inline void put_u16_le(std::array<std::uint8_t, 8>& data, std::size_t at, std::uint16_t value) noexcept {
  data[at] = static_cast<std::uint8_t>(value & 0xFFU);
  data[at + 1] = static_cast<std::uint8_t>(value >> 8);
}

inline void put_u32_le(std::array<std::uint8_t, 8>& data, std::size_t at, std::uint32_t value) noexcept {
  for (std::size_t i = 0; i < 4; ++i) data[at + i] = static_cast<std::uint8_t>((value >> (8 * i)) & 0xFFU);
}

}  // namespace pmlsm::canopen

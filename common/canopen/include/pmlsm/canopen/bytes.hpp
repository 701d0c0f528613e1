// Little-endian field access in CAN payloads (CANopen transmits every number least significant
// byte first) and a zeroed frame. All noexcept, no allocation.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "pmlsm/canopen/frame.hpp"
#include "pmlsm/util/little_endian.hpp"

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
  return get_le16(data.data() + at);
}

inline std::uint32_t get_u32_le(const std::array<std::uint8_t, 8>& data, std::size_t at) noexcept {
  return get_le32(data.data() + at);
}

inline void put_u16_le(std::array<std::uint8_t, 8>& data, std::size_t at, std::uint16_t value) noexcept {
  put_le16(data.data() + at, value);
}

inline void put_u32_le(std::array<std::uint8_t, 8>& data, std::size_t at, std::uint32_t value) noexcept {
  put_le32(data.data() + at, value);
}

}  // namespace pmlsm::canopen

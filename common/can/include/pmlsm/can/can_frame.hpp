// One classic CAN 2.0 frame, the unit every CanBus transport carries and every CANopen encoder
// produces and decoder takes.
//
//   id        11-bit identifier (CANopen's predefined connection set) or 29-bit when extended
//   dlc       data length code, 0..8 (classic CAN); only data[0, dlc) is meaningful
//   data      payload; the CANopen encoders zero the bytes at and after dlc
//   rtr       remote transmission request (no payload); CANopen here uses none
//   extended  29-bit identifier; CANopen's predefined connection set uses 11-bit ones
//
// `CanFrame f;` leaves id, dlc and data uninitialised; `CanFrame f{};` zeroes them.
#pragma once

#include <array>
#include <cstdint>

namespace pmlsm::can {

struct CanFrame {
  std::uint32_t id;
  std::uint8_t dlc;
  std::array<std::uint8_t, 8> data;
  bool rtr = false;
  bool extended = false;
};

}  // namespace pmlsm::can

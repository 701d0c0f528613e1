// Internal: the checks every decoder makes before reading a frame's fields.
#pragma once

#include "pmlsm/canopen/frame.hpp"
#include "pmlsm/canopen/result.hpp"

namespace pmlsm::canopen::detail {

/// A data frame with an 11-bit id and a DLC of at most 8.
inline Status check_standard_data_frame(const CanFrame& frame) noexcept {
  if (frame.extended) return fail(Error::kExtendedFrame, "29-bit identifier: CANopen here uses 11-bit ones");
  if (frame.rtr) return fail(Error::kRemoteFrame, "RTR frame: only data frames are decoded");
  if (frame.dlc > 8) return fail(Error::kWrongDlc, "DLC over 8 (classic CAN)");
  return {};
}

template <typename T>
Result<T> as_result(const Status& status) noexcept {
  Result<T> result;
  static_cast<Status&>(result) = status;
  return result;
}

}  // namespace pmlsm::canopen::detail

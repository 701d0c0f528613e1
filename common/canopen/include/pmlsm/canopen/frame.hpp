// The CAN frame the CANopen codecs work on: the transports' own (pmlsm/can/can_frame.hpp), so a
// frame goes from a codec to a bus without a copy or a conversion.
#pragma once

#include "pmlsm/can/can_frame.hpp"

namespace pmlsm::canopen {

using CanFrame = can::CanFrame;

}  // namespace pmlsm::canopen

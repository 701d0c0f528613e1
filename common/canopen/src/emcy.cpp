// EMCY; see emcy.hpp.
#include "pmlsm/canopen/emcy.hpp"

#include "frame_checks.hpp"
#include "pmlsm/canopen/bytes.hpp"

namespace pmlsm::canopen {

const char* describe_emcy(std::uint16_t error_code) noexcept {
  switch (error_code) {
    case kEmcyNoError: return "error reset or no error";
    case kEmcyGeneric: return "generic error";
    case kEmcyContinuousOverCurrent: return "continuous over current";
    case kEmcyDcLinkOverVoltage: return "DC link over-voltage";
    case kEmcyExcessTemperature: return "excess temperature (device)";
    case kEmcyDeviceHardware: return "device hardware";
    case kEmcyParameterError: return "parameter error";
    case kEmcyCanOverrun: return "CAN overrun (objects lost)";
    case kEmcyHeartbeatError: return "life guard error or heartbeat error";
    case kEmcyPdoLength: return "PDO not processed due to length error";
    case kEmcyPdoLengthExceeded: return "PDO length exceeded";
    case kEmcyFollowingError: return "following error";
    case kEmcySyncLost: return "sync lost (SYNC or process data)";
    default: break;
  }
  if (error_code >= kEmcyManufacturerFirst) return "device specific";
  switch (error_code >> 12) {
    case 0x1: return "generic error";
    case 0x2: return "current";
    case 0x3: return "voltage";
    case 0x4: return "temperature";
    case 0x5: return "device hardware";
    case 0x6: return "device software";
    case 0x7: return "additional modules";
    case 0x8: return "monitoring";
    case 0x9: return "external error";
    case 0xF: return (error_code >> 8) == 0xF0 ? "additional functions" : "unknown error code";
    default: break;
  }
  return "unknown error code";
}

CanFrame encode_emcy(NodeId node, const EmcyMessage& message) noexcept {
  CanFrame frame = make_frame(emcy_cob_id(node), 8);
  put_u16_le(frame.data, 0, message.error_code);
  frame.data[2] = message.error_register;
  for (std::size_t i = 0; i < message.manufacturer.size(); ++i) frame.data[3 + i] = message.manufacturer[i];
  return frame;
}

Result<EmcyMessage> decode_emcy(const CanFrame& frame) noexcept {
  if (const Status s = detail::check_standard_data_frame(frame); !s) return detail::as_result<EmcyMessage>(s);
  const CobIdInfo info = classify(frame.id);
  if (info.function != FunctionCode::kEmcy) {
    return fail_with<EmcyMessage>(Error::kWrongCobId, "EMCY: COB-ID must be 0x081..0x0FF");
  }
  if (frame.dlc != 8) return fail_with<EmcyMessage>(Error::kWrongDlc, "EMCY: DLC must be 8");
  Result<EmcyMessage> result;
  result.value.node_id = info.node_id;
  result.value.error_code = get_u16_le(frame.data, 0);
  result.value.error_register = frame.data[2];
  for (std::size_t i = 0; i < result.value.manufacturer.size(); ++i) result.value.manufacturer[i] = frame.data[3 + i];
  return result;
}

}  // namespace pmlsm::canopen

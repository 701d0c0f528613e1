// EMCY (CiA 301 emergency object): COB-ID 0x080 + node, DLC 8:
//   bytes 0-1  emergency error code, little endian (CiA 301 / CiA 402 tables)
//   byte  2    the error register (object 0x1001)
//   bytes 3-7  manufacturer-specific error field
// An EMCY with error code 0x0000 ("error reset or no error") tells that the node's errors
// are gone.
#pragma once

#include <array>
#include <cstdint>

#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/canopen/frame.hpp"
#include "pmlsm/canopen/result.hpp"

namespace pmlsm::canopen {

// ---- emergency error codes (a selection of CiA 301 / CiA 402's table) -------------------------

inline constexpr std::uint16_t kEmcyNoError = 0x0000;                // error reset or no error
inline constexpr std::uint16_t kEmcyGeneric = 0x1000;                // generic error
inline constexpr std::uint16_t kEmcyContinuousOverCurrent = 0x2310;  // output: continuous over current
inline constexpr std::uint16_t kEmcyDcLinkOverVoltage = 0x3210;      // DC link over-voltage
inline constexpr std::uint16_t kEmcyExcessTemperature = 0x4210;      // device: excess temperature
inline constexpr std::uint16_t kEmcyDeviceHardware = 0x5000;         // device hardware
inline constexpr std::uint16_t kEmcyParameterError = 0x6320;         // software: parameter error
inline constexpr std::uint16_t kEmcyCanOverrun = 0x8110;             // CAN overrun (objects lost)
inline constexpr std::uint16_t kEmcyHeartbeatError = 0x8130;         // life guard / heartbeat error
inline constexpr std::uint16_t kEmcyPdoLength = 0x8210;              // PDO not processed: length error
inline constexpr std::uint16_t kEmcyPdoLengthExceeded = 0x8220;      // PDO length exceeded
inline constexpr std::uint16_t kEmcyFollowingError = 0x8611;         // CiA 402: following error
inline constexpr std::uint16_t kEmcySyncLost = 0x8700;  // monitoring: the cycle's clock lost (SYNC, process data)
inline constexpr std::uint16_t kEmcyManufacturerFirst = 0xFF00;  // 0xFF00..0xFFFF: device specific

// ---- error register (object 0x1001) bits -----------------------------------------------------

inline constexpr std::uint8_t kErrorRegisterGeneric = 1U << 0;
inline constexpr std::uint8_t kErrorRegisterCurrent = 1U << 1;
inline constexpr std::uint8_t kErrorRegisterVoltage = 1U << 2;
inline constexpr std::uint8_t kErrorRegisterTemperature = 1U << 3;
inline constexpr std::uint8_t kErrorRegisterCommunication = 1U << 4;
inline constexpr std::uint8_t kErrorRegisterDeviceProfile = 1U << 5;
inline constexpr std::uint8_t kErrorRegisterManufacturer = 1U << 7;

/// A short text for the codes above and their classes (0x2xxx "current", 0x3xxx "voltage",
/// 0x4xxx "temperature", 0x5xxx "device hardware", 0x6xxx "device software", 0x7xxx
/// "additional modules", 0x8xxx "monitoring", 0x9xxx "external error", 0xF0xx "additional
/// functions", 0xFFxx "device specific"); "unknown error code" otherwise.
const char* describe_emcy(std::uint16_t error_code) noexcept;

struct EmcyMessage {
  std::uint8_t node_id = 0;  // filled by decode_emcy; encode_emcy takes the node separately
  std::uint16_t error_code = kEmcyNoError;
  std::uint8_t error_register = 0;
  std::array<std::uint8_t, 5> manufacturer{};
};

CanFrame encode_emcy(NodeId node, const EmcyMessage& message) noexcept;
/// Errors: id not 0x081..0x0FF (kWrongCobId; 0x080 is SYNC), RTR / extended frame, DLC not 8.
Result<EmcyMessage> decode_emcy(const CanFrame& frame) noexcept;

}  // namespace pmlsm::canopen

// The object dictionary of our CiA 402 drive (the cyclic synchronous modes: torque, and velocity
// and position where the drive closes those loops itself) with the CiA 301 communication objects
// it needs. The power state machine, statusword and controlword
// codings are pmlsm::drive's (power_state.hpp); this only holds the objects.
//
//   index   sub  name                                  type  access  PDO  default
//   0x1000   0   device type                           u32   const        0x00020192 (CiA 402 servo)
//   0x1001   0   error register                        u8    ro           0
//   0x1008   0   manufacturer device name              text  const        config (segmented upload)
//   0x1016   0   consumer heartbeat: highest sub       u8    const        1
//            1   consumer heartbeat time 1             u32   rw           0 (node << 16 | ms)
//   0x1017   0   producer heartbeat time (ms)          u16   rw           config
//   0x1018   0   identity: highest sub                 u8    const        4
//          1-4   vendor id, product code, revision, serial number  u32 ro  config
//   0x1400   0   RPDO1 communication: highest sub      u8    const        2
//            1   COB-ID                                u32   rw           0x200 + node
//            2   transmission type                     u8    rw           1 (0..240 accepted)
//   0x1600   0   RPDO1 mapping: number of entries      u8    rw           2
//          1-8   mapping entries                       u32   rw           0x60400010, 0x60710010
//   0x1800   0   TPDO1 communication: highest sub      u8    const        5
//            1   COB-ID                                u32   rw           0x180 + node
//            2   transmission type                     u8    rw           1 (1..240 accepted)
//            3   inhibit time (100 us)                 u16   rw           0
//            5   event timer (ms)                      u16   rw           0
//   0x1A00   0   TPDO1 mapping: number of entries      u8    rw           3
//          1-8   mapping entries                       u32   rw           0x60410010, 0x60770010,
//                                                                         0x60640020
//   0x603F   0   error code                            u16   ro           0
//   0x6040   0   controlword                           u16   rw      yes  0
//   0x6041   0   statusword                            u16   ro      yes  0
//   0x6060   0   modes of operation                    i8    rw           0 (8, 9, 10 as 0x6502 says)
//   0x6061   0   modes of operation display            i8    ro           0
//   0x6064   0   position actual value (increments)    i32   ro      yes  0
//   0x606C   0   velocity actual value (increments/s)  i32   ro      yes  0
//   0x6071   0   target torque (per mille of 0x6076)   i16   rw      yes  0
//   0x6074   0   torque demand (per mille)             i16   ro      yes  0 (the force the period applied)
//   0x6076   0   rated torque (linear: rated force, mN) u32  ro           config
//   0x6077   0   torque actual value (per mille)       i16   ro      yes  0
//   0x607A   0   target position (increments)          i32   rw      yes  0
//   0x60B1   0   velocity offset (increments/s)        i32   rw      yes  0
//   0x60B2   0   torque offset (per mille)             i16   rw      yes  0
//   0x60FF   0   target velocity (increments/s)        i32   rw      yes  0
//   0x6502   0   supported drive modes                 u32   ro           config (bit 9 cst, 8 csv, 7 csp)
//   0x60E4   0   additional position actual: highest   u8    const        1
//            1   additional position actual value 1    i32   ro      yes  0 (a load encoder's, increments)
//   0x60C2   0   interpolation period: highest sub     u8    const        2
//            1   value                                 u8    rw           config (1 for 1 ms)
//            2   index (power of ten, s)               i8    rw           -3 (range -6..0)
//
// Writes the dictionary checks (abort codes):
//   0x6060: a mode whose bit 0x6502 does not set -> 0x06090030.
//   PDO COB-IDs: bit 29 (29-bit id) set, bits 28-11 set, or an id CiA 301 restricts
//     (0x000, 0x001-0x07F, 0x101-0x180, 0x581-0x5FF, 0x601-0x67F, 0x6E0-0x6FF, 0x701-0x77F,
//     0x780-0x7FF) in a valid COB-ID -> 0x06090030; changing the id of a valid PDO (bit 31
//     clear before and after) -> 0x06090030 (set bit 31 first, as CiA 301 asks).
//   Transmission types outside the accepted ranges -> 0x06090030.
//   PDO mapping (CiA 301's procedure: make the PDO invalid, write sub 0 = 0, write the
//     entries, write sub 0 = n, make the PDO valid): any mapping write while the PDO is valid,
//     or an entry write while sub 0 is not 0 -> 0x08000022 (present device state); sub 0 over
//     8 -> 0x06090031; sub 0 = n whose n entries do not form a valid mapping ->
//     validate_pdo_map's code (0x06020000, 0x06090011, 0x06040041, 0x06040042).
//   0x1016 sub 1: reserved bits 24-31 set or a node id over 127 -> 0x06090030.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/canopen/object_dictionary.hpp"
#include "pmlsm/drive/power_state.hpp"

namespace pmlsm::canopen {

// ---- indices ---------------------------------------------------------------------------------

inline constexpr std::uint16_t kObjectDeviceType = 0x1000;
inline constexpr std::uint16_t kObjectErrorRegister = 0x1001;
inline constexpr std::uint16_t kObjectDeviceName = 0x1008;
inline constexpr std::uint16_t kObjectConsumerHeartbeatTime = 0x1016;
inline constexpr std::uint16_t kObjectProducerHeartbeatTime = 0x1017;
inline constexpr std::uint16_t kObjectIdentity = 0x1018;
inline constexpr std::uint16_t kObjectRpdo1Communication = 0x1400;
inline constexpr std::uint16_t kObjectRpdo1Mapping = 0x1600;
inline constexpr std::uint16_t kObjectTpdo1Communication = 0x1800;
inline constexpr std::uint16_t kObjectTpdo1Mapping = 0x1A00;
/// TPDO3, a load sensor's reading (cia402_drive.hpp); a device's description adds it (as TPDO2).
inline constexpr std::uint16_t kObjectTpdo3Communication = 0x1802;
inline constexpr std::uint16_t kObjectTpdo3Mapping = 0x1A02;
inline constexpr std::uint16_t kObjectErrorCode = drive::kObjectErrorCode;      // 0x603F
inline constexpr std::uint16_t kObjectControlword = drive::kObjectControlword;  // 0x6040
inline constexpr std::uint16_t kObjectStatusword = drive::kObjectStatusword;    // 0x6041
inline constexpr std::uint16_t kObjectModesOfOperation = 0x6060;
inline constexpr std::uint16_t kObjectModesOfOperationDisplay = 0x6061;
inline constexpr std::uint16_t kObjectPositionActual = 0x6064;
inline constexpr std::uint16_t kObjectVelocityActual = 0x606C;
inline constexpr std::uint16_t kObjectTargetTorque = 0x6071;
inline constexpr std::uint16_t kObjectTorqueDemand = 0x6074;
inline constexpr std::uint16_t kObjectRatedTorque = 0x6076;
inline constexpr std::uint16_t kObjectTorqueActual = 0x6077;
inline constexpr std::uint16_t kObjectTargetPosition = 0x607A;
inline constexpr std::uint16_t kObjectVelocityOffset = 0x60B1;
inline constexpr std::uint16_t kObjectTorqueOffset = 0x60B2;
inline constexpr std::uint16_t kObjectInterpolationTimePeriod = 0x60C2;
inline constexpr std::uint16_t kObjectTargetVelocity = 0x60FF;
inline constexpr std::uint16_t kObjectAdditionalPositionActual = 0x60E4;
inline constexpr std::uint16_t kObjectSupportedDriveModes = 0x6502;

/// 0x1000 of a CiA 402 servo drive: device profile 402 (0x0192) in bits 0-15, type 0x0002
/// (servo drive) in bits 16-23.
inline constexpr std::uint32_t kDeviceTypeCia402Servo = 0x00020192;
/// 0x6060 / 0x6061: the cyclic synchronous modes (CiA 402-2): the master sends a target each
/// cycle, the drive interpolates nothing. Position (8): 0x607A, the drive closes position,
/// velocity and current loops (0x60B1 / 0x60B2 added to its velocity and torque); velocity (9):
/// 0x60FF, the drive closes velocity and current loops (0x60B2 added); torque (10): 0x6071.
inline constexpr std::int8_t kModeCyclicSynchronousPosition = 8;
inline constexpr std::int8_t kModeCyclicSynchronousVelocity = 9;
inline constexpr std::int8_t kModeCyclicSynchronousTorque = 10;
/// 0x6502's bit of a mode (CiA 402-2: bit 7 csp, 8 csv, 9 cst); 0 for modes we do not have.
std::uint32_t supported_mode_bit(std::int8_t mode) noexcept;
inline constexpr std::uint32_t kSupportedModesTorque = 1U << 9;
inline constexpr std::uint32_t kSupportedModesCyclicSynchronous = (1U << 7) | (1U << 8) | (1U << 9);
/// "cst", "csv", "csp" (a rig file's drive.mode), "none", or "another mode".
const char* mode_name(std::int8_t mode) noexcept;
/// "cyclic synchronous torque" (velocity, position), or mode_name's.
const char* describe_mode(std::int8_t mode) noexcept;
/// The mode of "cst", "csv" or "csp". @throws std::invalid_argument listing the choices.
std::int8_t mode_from_string(const std::string& name);
/// 0x6060 / 0x6061 before a mode is chosen.
inline constexpr std::int8_t kModeNone = 0;

struct Cia402DictionaryConfig {
  /// Rated torque 0x6076; for a linear motor the rated force in mN. >= 1. The torque objects
  /// 0x6071 / 0x6077 are per mille of it.
  std::uint32_t rated_torque = 1000;
  /// 0x1017 (0 = no heartbeat).
  std::uint16_t producer_heartbeat_ms = 100;
  /// 0x60C2 sub 1 with sub 2 = -3: the cycle in ms. 1..255.
  std::uint8_t interpolation_period_ms = 1;
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision_number = 0;
  std::uint32_t serial_number = 0;
  /// 0x1008, a VISIBLE_STRING (an EtherCAT slave's: its SII's name).
  std::string device_name = "PMLSM CiA 402 drive";
  /// 0x6502: the modes 0x6060 accepts (kSupportedModes*); torque always. A drive offers velocity
  /// and position only when its application closes those loops (Cia402ApplicationParams).
  std::uint32_t supported_drive_modes = kSupportedModesTorque;
};

/// The capacity of the dictionary make_cia402_dictionary returns: its ~60 entries leave room for
/// the application's own and a bus's (EtherCAT's sync manager objects and PDO mappings; add() them
/// right after, before any pointer into it is kept).
inline constexpr std::size_t kCia402DictionaryCapacity = 256;

/// The table above for `node` (the default PDO COB-IDs). @throws std::invalid_argument naming
/// the offending field ("rated_torque: must be >= 1, got 0").
ObjectDictionary make_cia402_dictionary(NodeId node, const Cia402DictionaryConfig& config = {});

}  // namespace pmlsm::canopen

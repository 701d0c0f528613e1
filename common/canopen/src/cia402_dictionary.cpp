// The CiA 402 drive's object dictionary and the checks of its writable entries; see
// cia402_dictionary.hpp.
#include "pmlsm/canopen/cia402_dictionary.hpp"

#include <cstdint>
#include <stdexcept>
#include <string>

#include "pmlsm/canopen/bytes.hpp"
#include "pmlsm/canopen/nmt.hpp"
#include "pmlsm/canopen/pdo.hpp"
#include "pmlsm/canopen/sdo.hpp"

namespace pmlsm::canopen {
namespace {

// ---- value checks (ValueCheck) -------------------------------------------------------------------

std::uint32_t check_mode_of_operation(const ObjectDictionary& dictionary, const Entry&, std::int64_t value) noexcept {
  if (value < INT8_MIN || value > INT8_MAX) return kAbortValueRange;
  const auto supported = static_cast<std::uint32_t>(dictionary.get_or(kObjectSupportedDriveModes, 0, 0));
  const std::uint32_t bit = supported_mode_bit(static_cast<std::int8_t>(value));
  return bit != 0 && (supported & bit) != 0 ? kAbortNone : kAbortValueRange;
}

// CiA 301's restricted CAN-IDs: no PDO may use them.
bool restricted_can_id(std::uint32_t id) noexcept {
  return id <= 0x07F || (id >= 0x101 && id <= 0x180) || (id >= 0x581 && id <= 0x5FF) || (id >= 0x601 && id <= 0x67F) ||
         (id >= 0x6E0 && id <= 0x6FF) || id >= 0x701;
}

std::uint32_t check_pdo_cob_id(const ObjectDictionary&, const Entry& entry, std::int64_t value) noexcept {
  const auto raw = static_cast<std::uint32_t>(value);
  if ((raw & kPdoCobIdExtended) != 0) return kAbortValueRange;  // 29-bit ids: not supported
  if ((raw & 0x1FFFF800U) != 0) return kAbortValueRange;        // bits 28-11 of an 11-bit id
  const bool valid = (raw & kPdoCobIdInvalid) == 0;
  const std::uint32_t id = raw & kCanMaxStandardId;
  if (valid && restricted_can_id(id)) return kAbortValueRange;
  const auto old_raw = static_cast<std::uint32_t>(entry.value);
  const bool was_valid = (old_raw & kPdoCobIdInvalid) == 0;
  if (valid && was_valid && id != (old_raw & kCanMaxStandardId)) return kAbortValueRange;
  return kAbortNone;
}

std::uint32_t check_rpdo_transmission_type(const ObjectDictionary&, const Entry&, std::int64_t value) noexcept {
  return value <= kPdoTransmissionSyncMax ? kAbortNone : kAbortValueRange;
}

std::uint32_t check_tpdo_transmission_type(const ObjectDictionary&, const Entry&, std::int64_t value) noexcept {
  return (value >= kPdoTransmissionSyncEvery && value <= kPdoTransmissionSyncMax) ? kAbortNone : kAbortValueRange;
}

// The PDO whose mapping `mapping_index` is, is valid (COB-ID bit 31 clear).
bool pdo_valid(const ObjectDictionary& dictionary, std::uint16_t mapping_index) noexcept {
  const auto cob = dictionary.get(static_cast<std::uint16_t>(mapping_index - kPdoMappingOffset), 1);
  return cob && (static_cast<std::uint32_t>(*cob) & kPdoCobIdInvalid) == 0;
}

std::uint32_t check_mapping_count(const ObjectDictionary& dictionary, const Entry& entry, std::int64_t value) noexcept {
  if (pdo_valid(dictionary, entry.index)) return kAbortDeviceState;
  if (value == 0) return kAbortNone;
  PdoMap map;
  for (std::int64_t sub = 1; sub <= value; ++sub) {
    const auto mapping = dictionary.get(entry.index, static_cast<std::uint8_t>(sub));
    if (!mapping) return kAbortSubindexMissing;
    const std::uint32_t code = map.add(decode_pdo_mapping(static_cast<std::uint32_t>(*mapping)));
    if (code != kAbortNone) return code;
  }
  const Result<PdoDirection> direction = pdo_direction_of(entry.index);
  if (!direction) return kAbortGeneral;
  const Status valid = validate_pdo_map(map, dictionary, direction.value);
  return valid ? kAbortNone : valid.abort_code;
}

std::uint32_t check_mapping_entry(const ObjectDictionary& dictionary, const Entry& entry, std::int64_t) noexcept {
  if (pdo_valid(dictionary, entry.index)) return kAbortDeviceState;
  if (dictionary.get_or(entry.index, 0, 0) != 0) return kAbortDeviceState;
  return kAbortNone;
}

std::uint32_t check_consumer_heartbeat(const ObjectDictionary&, const Entry&, std::int64_t value) noexcept {
  return decode_consumer_heartbeat_entry(static_cast<std::uint32_t>(value)).ok() ? kAbortNone : kAbortValueRange;
}

// ---- building ------------------------------------------------------------------------------------

Entry make(std::uint16_t index, std::uint8_t subindex, const char* name, DataType type, Access access,
           std::int64_t value, bool pdo_mappable = false) {
  Entry e;
  e.index = index;
  e.subindex = subindex;
  e.name = name;
  e.type = type;
  e.access = access;
  e.value = value;
  e.pdo_mappable = pdo_mappable;
  return e;
}

Entry with_check(Entry e, ValueCheck check) {
  e.check = check;
  return e;
}

Entry with_range(Entry e, std::int64_t min, std::int64_t max) {
  e.min = min;
  e.max = max;
  return e;
}

// The CiA 402 objects of the table (0x603F on).
void add_cia402_objects(ObjectDictionary& od, const Cia402DictionaryConfig& config) {
  using T = DataType;
  using A = Access;
  od.add(make(kObjectErrorCode, 0, "error code", T::kU16, A::kRo, 0));
  od.add(make(kObjectControlword, 0, "controlword", T::kU16, A::kRw, 0, true));
  od.add(make(kObjectStatusword, 0, "statusword", T::kU16, A::kRo, 0, true));
  od.add(with_check(make(kObjectModesOfOperation, 0, "modes of operation", T::kI8, A::kRw, kModeNone),
                    check_mode_of_operation));
  od.add(make(kObjectModesOfOperationDisplay, 0, "modes of operation display", T::kI8, A::kRo, kModeNone));
  od.add(make(kObjectPositionActual, 0, "position actual value", T::kI32, A::kRo, 0, true));
  od.add(make(kObjectVelocityActual, 0, "velocity actual value", T::kI32, A::kRo, 0, true));
  od.add(make(kObjectTargetTorque, 0, "target torque", T::kI16, A::kRw, 0, true));
  od.add(make(kObjectTorqueDemand, 0, "torque demand", T::kI16, A::kRo, 0, true));
  od.add(make(kObjectRatedTorque, 0, "rated torque", T::kU32, A::kRo, config.rated_torque));
  od.add(make(kObjectTorqueActual, 0, "torque actual value", T::kI16, A::kRo, 0, true));
  od.add(make(kObjectTargetPosition, 0, "target position", T::kI32, A::kRw, 0, true));
  od.add(make(kObjectVelocityOffset, 0, "velocity offset", T::kI32, A::kRw, 0, true));
  od.add(make(kObjectTorqueOffset, 0, "torque offset", T::kI16, A::kRw, 0, true));
  od.add(make(kObjectTargetVelocity, 0, "target velocity", T::kI32, A::kRw, 0, true));
  od.add(make(kObjectAdditionalPositionActual, 0, "additional position actual value: highest sub-index", T::kU8,
              A::kConst, 1));
  od.add(make(kObjectAdditionalPositionActual, 1, "additional position actual value 1", T::kI32, A::kRo, 0, true));
  od.add(make(kObjectSupportedDriveModes, 0, "supported drive modes", T::kU32, A::kRo, config.supported_drive_modes));
  od.add(make(kObjectInterpolationTimePeriod, 0, "interpolation time period: highest sub-index", T::kU8, A::kConst, 2));
  od.add(with_range(make(kObjectInterpolationTimePeriod, 1, "interpolation time period value", T::kU8, A::kRw,
                         config.interpolation_period_ms),
                    1, 255));
  od.add(with_range(make(kObjectInterpolationTimePeriod, 2, "interpolation time index", T::kI8, A::kRw, -3), -6, 0));
}

}  // namespace

std::uint32_t supported_mode_bit(std::int8_t mode) noexcept {
  switch (mode) {
    case kModeCyclicSynchronousPosition: return 1U << 7;
    case kModeCyclicSynchronousVelocity: return 1U << 8;
    case kModeCyclicSynchronousTorque: return 1U << 9;
    default: return 0;
  }
}

const char* mode_name(std::int8_t mode) noexcept {
  switch (mode) {
    case kModeCyclicSynchronousPosition: return "csp";
    case kModeCyclicSynchronousVelocity: return "csv";
    case kModeCyclicSynchronousTorque: return "cst";
    case kModeNone: return "none";
    default: return "another mode";
  }
}

const char* describe_mode(std::int8_t mode) noexcept {
  switch (mode) {
    case kModeCyclicSynchronousPosition: return "cyclic synchronous position";
    case kModeCyclicSynchronousVelocity: return "cyclic synchronous velocity";
    case kModeCyclicSynchronousTorque: return "cyclic synchronous torque";
    default: return mode_name(mode);
  }
}

std::int8_t mode_from_string(const std::string& name) {
  if (name == "cst") return kModeCyclicSynchronousTorque;
  if (name == "csv") return kModeCyclicSynchronousVelocity;
  if (name == "csp") return kModeCyclicSynchronousPosition;
  throw std::invalid_argument("must be one of cst (cyclic synchronous torque), csv (velocity), csp (position), got '" +
                              name + "'");
}

ObjectDictionary make_cia402_dictionary(NodeId node, const Cia402DictionaryConfig& config) {
  if (config.rated_torque < 1) throw std::invalid_argument("rated_torque: must be >= 1, got 0");
  if ((config.supported_drive_modes & kSupportedModesTorque) == 0 ||
      (config.supported_drive_modes & ~kSupportedModesCyclicSynchronous) != 0) {
    throw std::invalid_argument("supported_drive_modes: must have bit 9 (cst) and only bits 7-9, got " +
                                std::to_string(config.supported_drive_modes));
  }
  if (config.interpolation_period_ms < 1) {
    throw std::invalid_argument("interpolation_period_ms: must be in [1, 255], got 0");
  }
  using T = DataType;
  using A = Access;
  constexpr const char* kMappingNames[8] = {"mapping entry 1", "mapping entry 2", "mapping entry 3", "mapping entry 4",
                                            "mapping entry 5", "mapping entry 6", "mapping entry 7", "mapping entry 8"};

  ObjectDictionary od(kCia402DictionaryCapacity);
  od.add(make(kObjectDeviceType, 0, "device type", T::kU32, A::kConst, kDeviceTypeCia402Servo));
  od.add(make(kObjectErrorRegister, 0, "error register", T::kU8, A::kRo, 0));
  od.add_text({kObjectDeviceName, 0, "manufacturer device name", config.device_name});
  od.add(make(kObjectConsumerHeartbeatTime, 0, "consumer heartbeat time: highest sub-index", T::kU8, A::kConst, 1));
  od.add(with_check(make(kObjectConsumerHeartbeatTime, 1, "consumer heartbeat time 1", T::kU32, A::kRw, 0),
                    check_consumer_heartbeat));
  od.add(
      make(kObjectProducerHeartbeatTime, 0, "producer heartbeat time", T::kU16, A::kRw, config.producer_heartbeat_ms));
  od.add(make(kObjectIdentity, 0, "identity: highest sub-index", T::kU8, A::kConst, 4));
  od.add(make(kObjectIdentity, 1, "vendor id", T::kU32, A::kRo, config.vendor_id));
  od.add(make(kObjectIdentity, 2, "product code", T::kU32, A::kRo, config.product_code));
  od.add(make(kObjectIdentity, 3, "revision number", T::kU32, A::kRo, config.revision_number));
  od.add(make(kObjectIdentity, 4, "serial number", T::kU32, A::kRo, config.serial_number));

  // RPDO1: controlword and target torque, applied at each SYNC.
  od.add(make(kObjectRpdo1Communication, 0, "RPDO1 communication: highest sub-index", T::kU8, A::kConst, 2));
  od.add(with_check(make(kObjectRpdo1Communication, 1, "RPDO1 COB-ID", T::kU32, A::kRw, rpdo_cob_id(1, node)),
                    check_pdo_cob_id));
  od.add(with_check(make(kObjectRpdo1Communication, 2, "RPDO1 transmission type", T::kU8, A::kRw, 1),
                    check_rpdo_transmission_type));
  od.add(with_check(with_range(make(kObjectRpdo1Mapping, 0, "RPDO1 mapping: number of entries", T::kU8, A::kRw, 2), 0,
                               kPdoMaxEntries),
                    check_mapping_count));
  const std::uint32_t rpdo1[8] = {encode_pdo_mapping({kObjectControlword, 0, 16}),
                                  encode_pdo_mapping({kObjectTargetTorque, 0, 16})};
  for (std::uint8_t sub = 1; sub <= 8; ++sub) {
    od.add(with_check(make(kObjectRpdo1Mapping, sub, kMappingNames[sub - 1], T::kU32, A::kRw, rpdo1[sub - 1]),
                      check_mapping_entry));
  }

  // TPDO1: statusword, torque actual, position actual, sent at each SYNC.
  od.add(make(kObjectTpdo1Communication, 0, "TPDO1 communication: highest sub-index", T::kU8, A::kConst, 5));
  od.add(with_check(make(kObjectTpdo1Communication, 1, "TPDO1 COB-ID", T::kU32, A::kRw, tpdo_cob_id(1, node)),
                    check_pdo_cob_id));
  od.add(with_check(make(kObjectTpdo1Communication, 2, "TPDO1 transmission type", T::kU8, A::kRw, 1),
                    check_tpdo_transmission_type));
  od.add(make(kObjectTpdo1Communication, 3, "TPDO1 inhibit time", T::kU16, A::kRw, 0));
  od.add(make(kObjectTpdo1Communication, 5, "TPDO1 event timer", T::kU16, A::kRw, 0));
  od.add(with_check(with_range(make(kObjectTpdo1Mapping, 0, "TPDO1 mapping: number of entries", T::kU8, A::kRw, 3), 0,
                               kPdoMaxEntries),
                    check_mapping_count));
  const std::uint32_t tpdo1[8] = {encode_pdo_mapping({kObjectStatusword, 0, 16}),
                                  encode_pdo_mapping({kObjectTorqueActual, 0, 16}),
                                  encode_pdo_mapping({kObjectPositionActual, 0, 32})};
  for (std::uint8_t sub = 1; sub <= 8; ++sub) {
    od.add(with_check(make(kObjectTpdo1Mapping, sub, kMappingNames[sub - 1], T::kU32, A::kRw, tpdo1[sub - 1]),
                      check_mapping_entry));
  }

  add_cia402_objects(od, config);
  return od;
}

}  // namespace pmlsm::canopen

// PDO mapping, validation, packing and unpacking; see pdo.hpp.
#include "pmlsm/canopen/pdo.hpp"

#include "frame_checks.hpp"
#include "pmlsm/canopen/bytes.hpp"

namespace pmlsm::canopen {
namespace {

bool whole_object_length(std::uint8_t bits) noexcept { return bits == 8 || bits == 16 || bits == 32; }

Status mapping_error(std::uint32_t abort_code, const char* detail) noexcept {
  return fail(Error::kPdoMapping, detail, abort_code);
}

}  // namespace

std::uint32_t PdoMap::add(PdoMapEntry entry) noexcept {
  if (!whole_object_length(entry.bit_length)) return kAbortNotMappable;
  if (count_ >= kPdoMaxEntries || bits_ + entry.bit_length > kPdoMaxBits) return kAbortPdoLength;
  entries_[count_++] = entry;
  bits_ += entry.bit_length;
  return kAbortNone;
}

Status validate_pdo_map(const PdoMap& map, const ObjectDictionary& dictionary, PdoDirection direction) noexcept {
  for (const PdoMapEntry& mapped : map) {
    const Entry* entry = dictionary.find(mapped.index, mapped.subindex);
    if (entry == nullptr && dictionary.find_text(mapped.index, mapped.subindex) != nullptr) {
      return mapping_error(kAbortNotMappable, "PDO mapping: a text is not PDO-mappable");
    }
    if (entry == nullptr) {
      const std::uint32_t code = dictionary.locate(mapped.index, mapped.subindex);
      return mapping_error(code, code == kAbortSubindexMissing ? "PDO mapping: a mapped sub-index does not exist"
                                                               : "PDO mapping: a mapped object does not exist");
    }
    if (!entry->pdo_mappable)
      return mapping_error(kAbortNotMappable, "PDO mapping: a mapped entry is not PDO-mappable");
    if (direction == PdoDirection::kReceive && !writable(entry->access)) {
      return mapping_error(kAbortNotMappable, "PDO mapping: an RPDO maps an entry that is not writable");
    }
    if (direction == PdoDirection::kTransmit && !readable(entry->access)) {
      return mapping_error(kAbortNotMappable, "PDO mapping: a TPDO maps an entry that is not readable");
    }
    if (mapped.bit_length != bit_length(entry->type)) {
      return mapping_error(kAbortNotMappable, "PDO mapping: the bit length is not the mapped object's");
    }
  }
  if (map.size() > kPdoMaxEntries || map.total_bits() > kPdoMaxBits) {
    return mapping_error(kAbortPdoLength, "PDO mapping: more than 64 bits");
  }
  return {};
}

Result<PdoDirection> pdo_direction_of(std::uint16_t index) noexcept {
  if (index >= 0x1400 && index <= 0x17FF) return success(PdoDirection::kReceive);
  if (index >= 0x1800 && index <= 0x1BFF) return success(PdoDirection::kTransmit);
  return fail_with<PdoDirection>(Error::kInvalidValue, "PDO: index is not a PDO communication or mapping object");
}

Result<PdoMap> read_pdo_map(const ObjectDictionary& dictionary, std::uint16_t mapping_index) noexcept {
  const bool is_mapping =
      (mapping_index >= 0x1600 && mapping_index <= 0x17FF) || (mapping_index >= 0x1A00 && mapping_index <= 0x1BFF);
  if (!is_mapping) return fail_with<PdoMap>(Error::kInvalidValue, "PDO: index is not a PDO mapping object");
  const PdoDirection direction = pdo_direction_of(mapping_index).value;
  const Entry* count = dictionary.find(mapping_index, 0);
  if (count == nullptr) {
    return fail_with<PdoMap>(Error::kAccessRefused, "PDO mapping: the mapping object does not exist",
                             dictionary.locate(mapping_index, 0));
  }
  if (count->value < 0 || count->value > static_cast<std::int64_t>(kPdoMaxEntries)) {
    return fail_with<PdoMap>(Error::kPdoMapping, "PDO mapping: more than 8 entries", kAbortPdoLength);
  }
  Result<PdoMap> result;
  for (std::int64_t sub = 1; sub <= count->value; ++sub) {
    const Entry* mapping = dictionary.find(mapping_index, static_cast<std::uint8_t>(sub));
    if (mapping == nullptr) {
      return fail_with<PdoMap>(Error::kAccessRefused, "PDO mapping: a mapping entry does not exist",
                               kAbortSubindexMissing);
    }
    const std::uint32_t code = result.value.add(decode_pdo_mapping(static_cast<std::uint32_t>(mapping->value)));
    if (code != kAbortNone) {
      return fail_with<PdoMap>(
          Error::kPdoMapping,
          code == kAbortPdoLength ? "PDO mapping: more than 64 bits" : "PDO mapping: bit length must be 8, 16 or 32",
          code);
    }
  }
  const Status valid = validate_pdo_map(result.value, dictionary, direction);
  if (!valid) {
    Result<PdoMap> failed;
    static_cast<Status&>(failed) = valid;
    return failed;
  }
  return result;
}

Result<PdoCommunication> read_pdo_communication(const ObjectDictionary& dictionary,
                                                std::uint16_t communication_index) noexcept {
  const bool is_communication = (communication_index >= 0x1400 && communication_index <= 0x15FF) ||
                                (communication_index >= 0x1800 && communication_index <= 0x19FF);
  if (!is_communication) {
    return fail_with<PdoCommunication>(Error::kInvalidValue, "PDO: index is not a PDO communication object");
  }
  const Entry* cob = dictionary.find(communication_index, 1);
  const Entry* type = dictionary.find(communication_index, 2);
  if (cob == nullptr || type == nullptr) {
    return fail_with<PdoCommunication>(Error::kAccessRefused, "PDO communication: sub-index 1 or 2 missing",
                                       dictionary.locate(communication_index, cob == nullptr ? 1 : 2));
  }
  const auto raw = static_cast<std::uint32_t>(cob->value);
  if ((raw & kPdoCobIdExtended) != 0) {
    return fail_with<PdoCommunication>(Error::kExtendedFrame, "PDO communication: 29-bit COB-IDs are not supported");
  }
  PdoCommunication comm;
  comm.cob_id = raw & kCanMaxStandardId;
  comm.valid = (raw & kPdoCobIdInvalid) == 0;
  comm.transmission_type = static_cast<std::uint8_t>(type->value);
  return success(comm);
}

Result<CanFrame> pack_pdo(const PdoMap& map, const ObjectDictionary& dictionary, std::uint32_t cob_id) noexcept {
  if (cob_id == 0 || cob_id > kCanMaxStandardId) {
    return fail_with<CanFrame>(Error::kWrongCobId, "PDO: COB-ID must be an 11-bit id other than 0");
  }
  CanFrame frame = make_frame(cob_id, map.byte_length());
  std::size_t at = 0;
  for (const PdoMapEntry& mapped : map) {
    const Entry* entry = dictionary.find(mapped.index, mapped.subindex);
    if (entry == nullptr) {
      return fail_with<CanFrame>(Error::kPdoMapping, "PDO pack: a mapped entry does not exist",
                                 dictionary.locate(mapped.index, mapped.subindex));
    }
    const std::uint8_t bytes = size_of(entry->type);
    if (mapped.bit_length != 8U * bytes || at + bytes > 8) {
      return fail_with<CanFrame>(Error::kPdoMapping, "PDO pack: the bit length is not the mapped object's",
                                 kAbortNotMappable);
    }
    const std::uint32_t raw = to_raw(entry->type, entry->value);
    for (std::uint8_t i = 0; i < bytes; ++i) frame.data[at + i] = static_cast<std::uint8_t>((raw >> (8U * i)) & 0xFFU);
    at += bytes;
  }
  return success(frame);
}

Status unpack_pdo(const PdoMap& map, ObjectDictionary& dictionary, const CanFrame& frame) noexcept {
  if (const Status s = detail::check_standard_data_frame(frame); !s) return s;
  if (frame.dlc != map.byte_length()) {
    return fail(Error::kWrongDlc, frame.dlc < map.byte_length() ? "PDO unpack: DLC shorter than the mapping"
                                                                : "PDO unpack: DLC longer than the mapping");
  }
  // Decode and check every value first; write only when all pass.
  std::array<std::int64_t, kPdoMaxEntries> values{};
  std::array<const Entry*, kPdoMaxEntries> entries{};
  std::size_t at = 0;
  for (std::size_t k = 0; k < map.size(); ++k) {
    const PdoMapEntry& mapped = map[k];
    const Entry* entry = dictionary.find(mapped.index, mapped.subindex);
    if (entry == nullptr) {
      return fail(Error::kPdoMapping, "PDO unpack: a mapped entry does not exist",
                  dictionary.locate(mapped.index, mapped.subindex));
    }
    if (!entry->pdo_mappable || !writable(entry->access)) {
      return fail(Error::kPdoMapping, "PDO unpack: a mapped entry is not a writable, mappable one", kAbortNotMappable);
    }
    const std::uint8_t bytes = size_of(entry->type);
    if (mapped.bit_length != 8U * bytes || at + bytes > 8) {
      return fail(Error::kPdoMapping, "PDO unpack: the bit length is not the mapped object's", kAbortNotMappable);
    }
    std::uint32_t raw = 0;
    for (std::uint8_t i = 0; i < bytes; ++i) raw |= static_cast<std::uint32_t>(frame.data[at + i]) << (8U * i);
    at += bytes;
    const std::int64_t value = from_raw(entry->type, raw);
    const std::uint32_t code = dictionary.check_value(*entry, value);
    if (code != kAbortNone) {
      return fail(Error::kAccessRefused,
                  code == kAbortValueTooHigh  ? "PDO unpack: a value is above its entry's maximum"
                  : code == kAbortValueTooLow ? "PDO unpack: a value is below its entry's minimum"
                                              : "PDO unpack: a value is not allowed for its entry",
                  code);
    }
    values[k] = value;
    entries[k] = entry;
  }
  for (std::size_t k = 0; k < map.size(); ++k) dictionary.store(*entries[k], values[k]);
  return {};
}

}  // namespace pmlsm::canopen

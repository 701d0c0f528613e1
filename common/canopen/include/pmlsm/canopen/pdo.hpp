// PDOs (CiA 301 process data objects): up to 8 bytes of mapped object values in one frame, no
// protocol overhead. A mapping lists (index, sub-index, bit length) entries; the values are
// packed in that order, little endian, from bit 0 of byte 0.
//
// Mapping parameter entries (objects 0x1600.. RPDO, 0x1A00.. TPDO, sub-index 1..8, UNSIGNED32):
//   bits 31-16 index, bits 15-8 sub-index, bits 7-0 bit length. Sub-index 0: number of entries.
// Communication parameter (0x1400.. RPDO, 0x1800.. TPDO):
//   sub 1 COB-ID: bit 31 = 1 PDO not valid (disabled), bit 30 = 1 no RTR allowed, bit 29 = 1
//         29-bit id (not supported), bits 10-0 the id;
//   sub 2 transmission type: 0 synchronous acyclic, 1..240 synchronous every n-th SYNC,
//         254/255 event driven (here: RPDO 0..240 = applied at the next SYNC; TPDO 1..240).
//
// Supported: whole objects of 8, 16 or 32 bits (no bit-level or dummy mapping), at most 8
// entries and 64 bits. pack/unpack are noexcept and allocation-free.
#pragma once

#include <array>
#include <cstdint>

#include "pmlsm/canopen/frame.hpp"
#include "pmlsm/canopen/object_dictionary.hpp"
#include "pmlsm/canopen/result.hpp"

namespace pmlsm::canopen {

inline constexpr std::size_t kPdoMaxEntries = 8;
inline constexpr std::uint32_t kPdoMaxBits = 64;

inline constexpr std::uint32_t kPdoCobIdInvalid = 1U << 31;
inline constexpr std::uint32_t kPdoCobIdNoRtr = 1U << 30;
inline constexpr std::uint32_t kPdoCobIdExtended = 1U << 29;
inline constexpr std::uint8_t kPdoTransmissionSyncAcyclic = 0;
inline constexpr std::uint8_t kPdoTransmissionSyncEvery = 1;  // 1..240: every n-th SYNC
inline constexpr std::uint8_t kPdoTransmissionSyncMax = 240;

inline constexpr std::uint16_t kRpdoCommunicationFirst = 0x1400;
inline constexpr std::uint16_t kRpdoMappingFirst = 0x1600;
inline constexpr std::uint16_t kTpdoCommunicationFirst = 0x1800;
inline constexpr std::uint16_t kTpdoMappingFirst = 0x1A00;
/// communication index + 0x200 = mapping index.
inline constexpr std::uint16_t kPdoMappingOffset = 0x200;

enum class PdoDirection : std::uint8_t {
  kReceive,   // RPDO: the master writes the mapped objects (they must be writable)
  kTransmit,  // TPDO: the node sends the mapped objects (they must be readable)
};

struct PdoMapEntry {
  std::uint16_t index = 0;
  std::uint8_t subindex = 0;
  std::uint8_t bit_length = 0;

  friend constexpr bool operator==(const PdoMapEntry& a, const PdoMapEntry& b) noexcept {
    return a.index == b.index && a.subindex == b.subindex && a.bit_length == b.bit_length;
  }
};

constexpr std::uint32_t encode_pdo_mapping(const PdoMapEntry& entry) noexcept {
  return (static_cast<std::uint32_t>(entry.index) << 16) | (static_cast<std::uint32_t>(entry.subindex) << 8) |
         entry.bit_length;
}
constexpr PdoMapEntry decode_pdo_mapping(std::uint32_t value) noexcept {
  return PdoMapEntry{static_cast<std::uint16_t>(value >> 16), static_cast<std::uint8_t>((value >> 8) & 0xFFU),
                     static_cast<std::uint8_t>(value & 0xFFU)};
}

/// A PDO's mapping: up to 8 entries. Holds no check against a dictionary (validate_pdo_map).
class PdoMap {
 public:
  /// Appends an entry. 0x06040042 (PDO length exceeded) when 8 entries are there or the bits
  /// would exceed 64; 0x06040041 for a bit length that is not 8, 16 or 32; 0 when added.
  std::uint32_t add(PdoMapEntry entry) noexcept;
  void clear() noexcept {
    count_ = 0;
    bits_ = 0;
  }

  std::size_t size() const noexcept { return count_; }
  bool empty() const noexcept { return count_ == 0; }
  const PdoMapEntry& operator[](std::size_t i) const noexcept { return entries_[i]; }
  const PdoMapEntry* begin() const noexcept { return entries_.data(); }
  const PdoMapEntry* end() const noexcept { return entries_.data() + count_; }
  std::uint32_t total_bits() const noexcept { return bits_; }
  /// The DLC of the PDO: total_bits / 8.
  std::uint8_t byte_length() const noexcept { return static_cast<std::uint8_t>(bits_ / 8); }

 private:
  std::array<PdoMapEntry, kPdoMaxEntries> entries_{};
  std::size_t count_ = 0;
  std::uint32_t bits_ = 0;
};

/// Each entry against the dictionary, in order: object (0x06020000) and sub-index
/// (0x06090011) exist; pdo_mappable and, for an RPDO, writable / for a TPDO, readable
/// (0x06040041); the bit length is the object's (0x06040041: no partial objects).
/// Failure: kPdoMapping with the abort code and a detail naming the check.
Status validate_pdo_map(const PdoMap& map, const ObjectDictionary& dictionary, PdoDirection direction) noexcept;

/// The direction of a communication (0x1400-0x15FF, 0x1800-0x19FF) or mapping (0x1600-0x17FF,
/// 0x1A00-0x1BFF) index; error kInvalidValue for another index.
Result<PdoDirection> pdo_direction_of(std::uint16_t index) noexcept;

/// The mapping held in a mapping object (0x1600.. / 0x1A00..): sub 0 entries from sub 1..n,
/// validated. Errors: not a mapping index (kInvalidValue), a missing object / sub-index
/// (kAccessRefused), or validate_pdo_map's.
Result<PdoMap> read_pdo_map(const ObjectDictionary& dictionary, std::uint16_t mapping_index) noexcept;

struct PdoCommunication {
  std::uint32_t cob_id = 0;  // bits 10-0 of sub 1
  bool valid = false;        // bit 31 clear
  std::uint8_t transmission_type = 0;
};

/// Sub 1 and 2 of a communication object (0x1400.. / 0x1800..). Errors: not a communication
/// index (kInvalidValue), missing entries (kAccessRefused), a 29-bit COB-ID (kExtendedFrame).
Result<PdoCommunication> read_pdo_communication(const ObjectDictionary& dictionary,
                                                std::uint16_t communication_index) noexcept;

/// The frame (id cob_id, DLC map.byte_length()) with the mapped values, read from the
/// dictionary. Errors: cob_id not an 11-bit id or 0 (kWrongCobId), an entry missing or of
/// another size than mapped (kPdoMapping with the abort code): validate the map first.
Result<CanFrame> pack_pdo(const PdoMap& map, const ObjectDictionary& dictionary, std::uint32_t cob_id) noexcept;

/// Writes the frame's values into the dictionary. The DLC must be map.byte_length()
/// (kWrongDlc: CiA 301 answers a short PDO with EMCY 0x8210, a long one with 0x8220); RTR /
/// extended frames are refused. Every value passes check_value() (range, entry check:
/// kAccessRefused with the abort code) before any is written: on any error nothing is
/// written. The frame's id is not checked (the caller routes by COB-ID).
Status unpack_pdo(const PdoMap& map, ObjectDictionary& dictionary, const CanFrame& frame) noexcept;

}  // namespace pmlsm::canopen

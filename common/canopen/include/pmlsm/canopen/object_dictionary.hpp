// A slave's object dictionary (CiA 301): entries addressed by index and sub-index, each with a
// data type, an access type, a value, a value range and whether it may be mapped into a PDO;
// the SDO semantics of reading and writing them (with CiA 301's abort codes) and the
// application's own access.
//
// Construction and add() may allocate and throw; everything after that is noexcept and
// allocation-free: the entries live in a vector reserved to the capacity given to the
// constructor and kept sorted by (index, sub-index), found by binary search.
//
// Values are held as std::int64_t, which represents every supported type exactly; on the bus
// they are 1, 2 or 4 bytes little endian, two's complement for the signed types. Texts (a
// device's name and versions, VISIBLE_STRING) are a table of their own beside the entries:
// read-only, longer than an expedited SDO carries.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "pmlsm/canopen/result.hpp"
#include "pmlsm/canopen/sdo.hpp"

namespace pmlsm::canopen {

enum class DataType : std::uint8_t { kU8, kU16, kU32, kI8, kI16, kI32 };

/// CiA 301's names: "UNSIGNED8", "UNSIGNED16", "UNSIGNED32", "INTEGER8", "INTEGER16",
/// "INTEGER32" ("unknown").
const char* to_string(DataType type) noexcept;

constexpr std::uint8_t size_of(DataType type) noexcept {
  switch (type) {
    case DataType::kU8:
    case DataType::kI8: return 1;
    case DataType::kU16:
    case DataType::kI16: return 2;
    case DataType::kU32:
    case DataType::kI32: return 4;
  }
  return 0;
}
constexpr std::uint8_t bit_length(DataType type) noexcept { return static_cast<std::uint8_t>(8 * size_of(type)); }
constexpr bool is_signed(DataType type) noexcept {
  return type == DataType::kI8 || type == DataType::kI16 || type == DataType::kI32;
}
constexpr std::int64_t type_min(DataType type) noexcept {
  return is_signed(type) ? -(std::int64_t{1} << (bit_length(type) - 1)) : 0;
}
constexpr std::int64_t type_max(DataType type) noexcept {
  return is_signed(type) ? (std::int64_t{1} << (bit_length(type) - 1)) - 1 : (std::int64_t{1} << bit_length(type)) - 1;
}

/// The value's bus coding (LE bytes as an integer, two's complement truncated to the size).
constexpr std::uint32_t to_raw(DataType type, std::int64_t value) noexcept {
  const std::uint64_t mask = (std::uint64_t{1} << bit_length(type)) - 1;
  return static_cast<std::uint32_t>(static_cast<std::uint64_t>(value) & mask);
}
/// The value of a bus coding (bits above the type's size ignored; sign-extended when signed).
constexpr std::int64_t from_raw(DataType type, std::uint32_t raw) noexcept {
  const int bits = bit_length(type);
  const std::uint64_t masked = raw & ((std::uint64_t{1} << bits) - 1);
  if (is_signed(type) && (masked >> (bits - 1)) != 0) {
    return static_cast<std::int64_t>(masked) - (std::int64_t{1} << bits);
  }
  return static_cast<std::int64_t>(masked);
}

enum class Access : std::uint8_t {
  kRo,     // read only (the application may change it: actual values, statusword)
  kWo,     // write only
  kRw,     // read and write
  kConst,  // read only, never changes
};

/// "ro", "wo", "rw", "const" ("unknown").
const char* to_string(Access access) noexcept;
constexpr bool readable(Access access) noexcept { return access != Access::kWo; }
constexpr bool writable(Access access) noexcept { return access == Access::kWo || access == Access::kRw; }

class ObjectDictionary;
struct Entry;

/// An entry's extra check of a value written over SDO or an RPDO (after the range check):
/// 0 to accept, else the abort code (e.g. 0x06090030). It may look at other entries (a PDO
/// mapping at its COB-ID). Must not throw or allocate.
using ValueCheck = std::uint32_t (*)(const ObjectDictionary& dictionary, const Entry& entry,
                                     std::int64_t value) noexcept;

inline constexpr std::int64_t kNoMin = std::numeric_limits<std::int64_t>::min();
inline constexpr std::int64_t kNoMax = std::numeric_limits<std::int64_t>::max();

struct Entry {
  std::uint16_t index = 0;
  std::uint8_t subindex = 0;
  const char* name = "";  // static text
  DataType type = DataType::kU8;
  Access access = Access::kRo;
  std::int64_t value = 0;
  /// The range a master may write; add() narrows kNoMin / kNoMax to the type's range.
  std::int64_t min = kNoMin;
  std::int64_t max = kNoMax;
  bool pdo_mappable = false;
  ValueCheck check = nullptr;
};

/// A VISIBLE_STRING object (CiA 301 data type 0x0009): read-only text such as 0x1008, the
/// device's name. More than 4 bytes go by a normal or segmented upload: CoE serves them
/// (ethercat::CoeSdoServer); CANopen's server here is expedited only and refuses them (0x06010000).
struct TextEntry {
  std::uint16_t index = 0;
  std::uint8_t subindex = 0;
  const char* name = "";  // static text
  std::string text;
};

class ObjectDictionary {
 public:
  /// @throws std::invalid_argument when capacity is 0.
  explicit ObjectDictionary(std::size_t capacity = 128);

  /// Adds an entry. @throws std::invalid_argument naming the entry ("object 0x6040 sub 0
  /// (controlword): ...") when: the dictionary is full, the (index, sub-index) exists already,
  /// the name is null or empty, min > max, min or max lie outside the type's range (after
  /// kNoMin / kNoMax are narrowed), or the value is outside [min, max].
  void add(Entry entry);

  std::size_t size() const noexcept { return entries_.size(); }
  std::size_t capacity() const noexcept { return entries_.capacity(); }
  const Entry* begin() const noexcept { return entries_.data(); }
  const Entry* end() const noexcept { return entries_.data() + entries_.size(); }

  /// Adds a text. @throws std::invalid_argument naming it when its name is empty or its
  /// (index, sub-index) is taken (by an entry or a text).
  void add_text(TextEntry text);
  const std::vector<TextEntry>& texts() const noexcept { return texts_; }

  /// The entry, or nullptr (also for a text). The pointer stays valid until the next add().
  const Entry* find(std::uint16_t index, std::uint8_t subindex) const noexcept;
  /// The text, or nullptr.
  const TextEntry* find_text(std::uint16_t index, std::uint8_t subindex) const noexcept;
  /// Some sub-index of `index` exists (an entry or a text).
  bool contains(std::uint16_t index) const noexcept;
  /// 0 when the entry or text exists, else 0x06020000 (no such index) or 0x06090011 (the index
  /// exists, the sub-index does not).
  std::uint32_t locate(std::uint16_t index, std::uint8_t subindex) const noexcept;

  // ---- SDO semantics (a master's access) -------------------------------------------------------

  /// Upload: the value's bus coding and size. Refused (kAccessRefused with abort_code) for a
  /// missing object (0x06020000) or sub-index (0x06090011), a write-only entry (0x06010001), or a
  /// text (0x06010000: not in 4 bytes; find_text() gives it to a server that segments).
  Result<SdoData> read(std::uint16_t index, std::uint8_t subindex) const noexcept;

  /// Download. Checks, in this order: object (0x06020000), sub-index (0x06090011), access
  /// (0x06010002 for ro / const and for a text), size (0x06070010 when indicated and not the type's; a size
  /// not indicated takes the type's low bytes), range (0x06090031 above max, 0x06090032 below
  /// min), the entry's check (its code). Nothing is written unless all pass.
  Status write(std::uint16_t index, std::uint8_t subindex, SdoData data) noexcept;

  /// The value checks of write() (range, then the entry's check) for `value`: 0 or the code.
  std::uint32_t check_value(const Entry& entry, std::int64_t value) const noexcept;

  // ---- the application's access ----------------------------------------------------------------

  /// The value, nullopt when the entry does not exist. Any access type.
  std::optional<std::int64_t> get(std::uint16_t index, std::uint8_t subindex) const noexcept;
  /// get(), or `fallback`.
  std::int64_t get_or(std::uint16_t index, std::uint8_t subindex, std::int64_t fallback) const noexcept;

  /// Sets a value whatever the access type (the application updates its read-only statusword
  /// and actual values), checking only the data type's range (not min / max or the entry's
  /// check): refused with 0x06020000 / 0x06090011 for a missing entry, 0x06090031 /
  /// 0x06090032 outside the type's range, 0x06010002 for a text.
  Status set(std::uint16_t index, std::uint8_t subindex, std::int64_t value) noexcept;

  /// Stores an already-checked value into the entry with `entry`'s index and sub-index (PDO
  /// unpack, after checking every value); nothing when there is none. No checks at all.
  void store(const Entry& entry, std::int64_t value) noexcept;

 private:
  Entry* find_mutable(std::uint16_t index, std::uint8_t subindex) noexcept;
  /// A write to no entry: read-only for a text, else locate()'s code.
  Status refuse_missing(std::uint16_t index, std::uint8_t subindex) const noexcept;

  std::vector<Entry> entries_;
  std::vector<TextEntry> texts_;  // a handful, in the order added
};

}  // namespace pmlsm::canopen

// The object dictionary; see object_dictionary.hpp.
#include "pmlsm/canopen/object_dictionary.hpp"

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace pmlsm::canopen {
namespace {

constexpr std::uint32_t key_of(std::uint16_t index, std::uint8_t subindex) noexcept {
  return (static_cast<std::uint32_t>(index) << 8) | subindex;
}
constexpr std::uint32_t key_of(const Entry& entry) noexcept { return key_of(entry.index, entry.subindex); }

std::string entry_label(const Entry& entry) {
  char buffer[48];
  std::snprintf(buffer, sizeof buffer, "object 0x%04X sub %u", static_cast<unsigned>(entry.index),
                static_cast<unsigned>(entry.subindex));
  std::string label(buffer);
  if (entry.name != nullptr && entry.name[0] != '\0') label += std::string(" (") + entry.name + ")";
  return label;
}

Status refuse(std::uint32_t abort_code, const char* detail) noexcept {
  return fail(Error::kAccessRefused, detail, abort_code);
}

const char* detail_of(std::uint32_t abort_code) noexcept {
  switch (abort_code) {
    case kAbortObjectMissing: return "object dictionary: no such index";
    case kAbortSubindexMissing: return "object dictionary: no such sub-index";
    case kAbortValueTooHigh: return "object dictionary: value above the entry's maximum";
    case kAbortValueTooLow: return "object dictionary: value below the entry's minimum";
    case kAbortValueRange: return "object dictionary: value not allowed for this entry";
    default: break;
  }
  return describe(abort_code);
}

}  // namespace

const char* to_string(DataType type) noexcept {
  switch (type) {
    case DataType::kU8: return "UNSIGNED8";
    case DataType::kU16: return "UNSIGNED16";
    case DataType::kU32: return "UNSIGNED32";
    case DataType::kI8: return "INTEGER8";
    case DataType::kI16: return "INTEGER16";
    case DataType::kI32: return "INTEGER32";
  }
  return "unknown";
}

const char* to_string(Access access) noexcept {
  switch (access) {
    case Access::kRo: return "ro";
    case Access::kWo: return "wo";
    case Access::kRw: return "rw";
    case Access::kConst: return "const";
  }
  return "unknown";
}

ObjectDictionary::ObjectDictionary(std::size_t capacity) {
  if (capacity == 0) throw std::invalid_argument("object dictionary capacity: must be >= 1, got 0");
  entries_.reserve(capacity);
}

void ObjectDictionary::add(Entry entry) {
  if (entry.name == nullptr || entry.name[0] == '\0') {
    throw std::invalid_argument(entry_label(entry) + ": name must not be empty");
  }
  if (size_of(entry.type) == 0) throw std::invalid_argument(entry_label(entry) + ": unknown data type");
  if (entries_.size() == entries_.capacity()) {
    throw std::invalid_argument(entry_label(entry) + ": object dictionary full (capacity " +
                                std::to_string(entries_.capacity()) + ")");
  }
  if (entry.min == kNoMin) entry.min = type_min(entry.type);
  if (entry.max == kNoMax) entry.max = type_max(entry.type);
  if (entry.min < type_min(entry.type) || entry.max > type_max(entry.type)) {
    throw std::invalid_argument(entry_label(entry) + ": min/max outside the range of " + to_string(entry.type) +
                                ", got [" + std::to_string(entry.min) + ", " + std::to_string(entry.max) + "]");
  }
  if (entry.min > entry.max) {
    throw std::invalid_argument(entry_label(entry) + ": min must be <= max, got [" + std::to_string(entry.min) + ", " +
                                std::to_string(entry.max) + "]");
  }
  if (entry.value < entry.min || entry.value > entry.max) {
    throw std::invalid_argument(entry_label(entry) + ": value must be in [" + std::to_string(entry.min) + ", " +
                                std::to_string(entry.max) + "], got " + std::to_string(entry.value));
  }
  const auto at = std::lower_bound(entries_.begin(), entries_.end(), key_of(entry),
                                   [](const Entry& e, std::uint32_t key) { return key_of(e) < key; });
  if ((at != entries_.end() && key_of(*at) == key_of(entry)) || find_text(entry.index, entry.subindex) != nullptr) {
    throw std::invalid_argument(entry_label(entry) + ": already in the dictionary");
  }
  entries_.insert(at, entry);  // within the reserved capacity: no reallocation
}

void ObjectDictionary::add_text(TextEntry text) {
  Entry label;
  label.index = text.index;
  label.subindex = text.subindex;
  label.name = text.name;
  if (text.name == nullptr || text.name[0] == '\0') {
    throw std::invalid_argument(entry_label(label) + ": name must not be empty");
  }
  if (find(text.index, text.subindex) != nullptr || find_text(text.index, text.subindex) != nullptr) {
    throw std::invalid_argument(entry_label(label) + ": already in the dictionary");
  }
  texts_.push_back(std::move(text));
}

const TextEntry* ObjectDictionary::find_text(std::uint16_t index, std::uint8_t subindex) const noexcept {
  const auto at = std::find_if(texts_.begin(), texts_.end(),
                               [&](const TextEntry& t) { return t.index == index && t.subindex == subindex; });
  return at == texts_.end() ? nullptr : &*at;
}

const Entry* ObjectDictionary::find(std::uint16_t index, std::uint8_t subindex) const noexcept {
  const std::uint32_t key = key_of(index, subindex);
  const auto at = std::lower_bound(entries_.begin(), entries_.end(), key,
                                   [](const Entry& e, std::uint32_t k) { return key_of(e) < k; });
  return (at != entries_.end() && key_of(*at) == key) ? &*at : nullptr;
}

Entry* ObjectDictionary::find_mutable(std::uint16_t index, std::uint8_t subindex) noexcept {
  return const_cast<Entry*>(static_cast<const ObjectDictionary*>(this)->find(index, subindex));
}

bool ObjectDictionary::contains(std::uint16_t index) const noexcept {
  const std::uint32_t key = key_of(index, 0);
  const auto at = std::lower_bound(entries_.begin(), entries_.end(), key,
                                   [](const Entry& e, std::uint32_t k) { return key_of(e) < k; });
  return (at != entries_.end() && at->index == index) ||
         std::any_of(texts_.begin(), texts_.end(), [&](const TextEntry& t) { return t.index == index; });
}

std::uint32_t ObjectDictionary::locate(std::uint16_t index, std::uint8_t subindex) const noexcept {
  if (find(index, subindex) != nullptr || find_text(index, subindex) != nullptr) return kAbortNone;
  return contains(index) ? kAbortSubindexMissing : kAbortObjectMissing;
}

Result<SdoData> ObjectDictionary::read(std::uint16_t index, std::uint8_t subindex) const noexcept {
  const Entry* entry = find(index, subindex);
  if (entry == nullptr && find_text(index, subindex) != nullptr) {
    return fail_with<SdoData>(Error::kAccessRefused, "object dictionary: a text, read by a segmented upload",
                              kAbortUnsupportedAccess);
  }
  if (entry == nullptr) {
    const std::uint32_t code = locate(index, subindex);
    Result<SdoData> r;
    static_cast<Status&>(r) = refuse(code, detail_of(code));
    return r;
  }
  if (!readable(entry->access)) {
    return fail_with<SdoData>(Error::kAccessRefused, "object dictionary: the entry is write-only", kAbortReadWriteOnly);
  }
  return success(SdoData{to_raw(entry->type, entry->value), size_of(entry->type)});
}

std::uint32_t ObjectDictionary::check_value(const Entry& entry, std::int64_t value) const noexcept {
  if (value > entry.max) return kAbortValueTooHigh;
  if (value < entry.min) return kAbortValueTooLow;
  if (entry.check != nullptr) return entry.check(*this, entry, value);
  return kAbortNone;
}

Status ObjectDictionary::write(std::uint16_t index, std::uint8_t subindex, SdoData data) noexcept {
  Entry* entry = find_mutable(index, subindex);
  if (entry == nullptr) return refuse_missing(index, subindex);
  if (!writable(entry->access)) {
    return refuse(kAbortWriteReadOnly, "object dictionary: the entry is read-only");
  }
  if (data.size != 0 && data.size != size_of(entry->type)) {
    return refuse(kAbortLengthMismatch, "object dictionary: the data's size is not the entry's data type's");
  }
  const std::int64_t value = from_raw(entry->type, data.data);
  if (data.size != 0 && to_raw(entry->type, value) != data.data) {
    return refuse(kAbortLengthMismatch, "object dictionary: data bits beyond the entry's size");
  }
  const std::uint32_t code = check_value(*entry, value);
  if (code != kAbortNone) return refuse(code, detail_of(code));
  entry->value = value;
  return {};
}

std::optional<std::int64_t> ObjectDictionary::get(std::uint16_t index, std::uint8_t subindex) const noexcept {
  const Entry* entry = find(index, subindex);
  if (entry == nullptr) return std::nullopt;
  return entry->value;
}

std::int64_t ObjectDictionary::get_or(std::uint16_t index, std::uint8_t subindex,
                                      std::int64_t fallback) const noexcept {
  const Entry* entry = find(index, subindex);
  return entry == nullptr ? fallback : entry->value;
}

Status ObjectDictionary::set(std::uint16_t index, std::uint8_t subindex, std::int64_t value) noexcept {
  Entry* entry = find_mutable(index, subindex);
  if (entry == nullptr) return refuse_missing(index, subindex);
  if (value > type_max(entry->type)) {
    return refuse(kAbortValueTooHigh, "object dictionary: value above the data type's range");
  }
  if (value < type_min(entry->type)) {
    return refuse(kAbortValueTooLow, "object dictionary: value below the data type's range");
  }
  entry->value = value;
  return {};
}

Status ObjectDictionary::refuse_missing(std::uint16_t index, std::uint8_t subindex) const noexcept {
  if (find_text(index, subindex) != nullptr)
    return refuse(kAbortWriteReadOnly, "object dictionary: a text is read-only");
  const std::uint32_t code = locate(index, subindex);
  return refuse(code, detail_of(code));
}

void ObjectDictionary::store(const Entry& entry, std::int64_t value) noexcept {
  Entry* ours = find_mutable(entry.index, entry.subindex);
  if (ours != nullptr) ours->value = value;
}

}  // namespace pmlsm::canopen

#include "pmlsm/ethercat/sii.hpp"

#include <fstream>
#include <iterator>
#include <stdexcept>

#include "pmlsm/util/validate.hpp"

namespace pmlsm::ethercat {

namespace {

std::uint32_t long_at(const std::vector<std::uint16_t>& w, std::size_t at) {
  return static_cast<std::uint32_t>(w[at]) | (static_cast<std::uint32_t>(w[at + 1]) << 16);
}

/// The category's data as bytes (words little-endian).
std::vector<std::uint8_t> bytes_of(const std::vector<std::uint16_t>& w, std::size_t at, std::size_t words) {
  std::vector<std::uint8_t> b;
  b.reserve(2 * words);
  for (std::size_t i = 0; i < words; ++i) {
    b.push_back(static_cast<std::uint8_t>(w[at + i] & 0xFFU));
    b.push_back(static_cast<std::uint8_t>(w[at + i] >> 8));
  }
  return b;
}

std::vector<std::string> parse_strings(const std::vector<std::uint8_t>& b, std::size_t at_word) {
  std::vector<std::string> strings;
  if (b.empty()) return strings;
  std::size_t p = 1;
  for (std::size_t i = 0; i < b[0]; ++i) {
    if (p >= b.size() || p + 1 + b[p] > b.size()) {
      throw std::invalid_argument("SII strings category at word " + format_hex(static_cast<std::uint32_t>(at_word), 4) +
                                  ": string " + std::to_string(i + 1) + " runs past the category");
    }
    strings.emplace_back(reinterpret_cast<const char*>(b.data() + p + 1), b[p]);
    p += 1 + b[p];
  }
  return strings;
}

std::string string_at(const std::vector<std::string>& strings, std::uint8_t index, const char* what) {
  if (index == 0) return "";
  if (index > strings.size()) {
    throw std::invalid_argument(std::string("SII general category: ") + what + " is string " + std::to_string(index) +
                                " of " + std::to_string(strings.size()));
  }
  return strings[index - 1U];
}

void put_long(std::vector<std::uint16_t>& w, std::size_t at, std::uint32_t v) {
  w[at] = static_cast<std::uint16_t>(v & 0xFFFFU);
  w[at + 1] = static_cast<std::uint16_t>(v >> 16);
}

void append_category(std::vector<std::uint16_t>& w, std::uint16_t type, std::vector<std::uint8_t> bytes) {
  if (bytes.size() % 2 != 0) bytes.push_back(0);
  w.push_back(type);
  w.push_back(static_cast<std::uint16_t>(bytes.size() / 2));
  for (std::size_t i = 0; i < bytes.size(); i += 2) {
    w.push_back(static_cast<std::uint16_t>(bytes[i] | (bytes[i + 1] << 8)));
  }
}

}  // namespace

SiiInfo parse_sii(const std::vector<std::uint16_t>& w) {
  if (w.size() < sii::kFirstCategory + 2U) {
    throw std::invalid_argument("SII: at least " + std::to_string(sii::kFirstCategory + 2) + " words, got " +
                                std::to_string(w.size()));
  }
  SiiInfo info;
  info.vendor_id = long_at(w, sii::kVendorId);
  info.product_code = long_at(w, sii::kProductCode);
  info.revision = long_at(w, sii::kRevision);
  info.serial = long_at(w, sii::kSerial);
  info.mailbox_receive_offset = w[sii::kMailboxReceiveOffset];
  info.mailbox_receive_size = w[sii::kMailboxReceiveSize];
  info.mailbox_send_offset = w[sii::kMailboxSendOffset];
  info.mailbox_send_size = w[sii::kMailboxSendSize];
  info.mailbox_protocols = w[sii::kMailboxProtocols];
  std::vector<std::uint8_t> general;
  for (std::size_t at = sii::kFirstCategory; at + 1 < w.size();) {
    const std::uint16_t type = w[at];
    if (type == sii_category::kEnd) break;
    const std::size_t size = w[at + 1];
    if (at + 2 + size > w.size()) {
      throw std::invalid_argument("SII category " + std::to_string(type) + " at word " +
                                  format_hex(static_cast<std::uint32_t>(at), 4) + ": " + std::to_string(size) +
                                  " words run past the image's " + std::to_string(w.size()));
    }
    const std::vector<std::uint8_t> data = bytes_of(w, at + 2, size);
    if (type == sii_category::kStrings) info.strings = parse_strings(data, at);
    if (type == sii_category::kGeneral) general = data;
    if (type == sii_category::kSyncManager) {
      for (std::size_t i = 0; i + 8 <= data.size(); i += 8) {
        info.sync_managers.push_back({static_cast<std::uint16_t>(data[i] | (data[i + 1] << 8)),
                                      static_cast<std::uint16_t>(data[i + 2] | (data[i + 3] << 8)), data[i + 4],
                                      data[i + 6], data[i + 7]});
      }
    }
    at += 2 + size;
  }
  if (general.size() >= 4) {
    info.group = string_at(info.strings, general[0], "the group");
    info.order = string_at(info.strings, general[2], "the order code");
    info.name = string_at(info.strings, general[3], "the name");
    if (general.size() >= 6) info.coe_details = general[5];
  }
  return info;
}

std::vector<std::uint16_t> build_sii(const SiiInfo& info) {
  std::vector<std::uint16_t> w(sii::kFirstCategory, 0);
  put_long(w, sii::kVendorId, info.vendor_id);
  put_long(w, sii::kProductCode, info.product_code);
  put_long(w, sii::kRevision, info.revision);
  put_long(w, sii::kSerial, info.serial);
  w[sii::kMailboxReceiveOffset] = info.mailbox_receive_offset;
  w[sii::kMailboxReceiveSize] = info.mailbox_receive_size;
  w[sii::kMailboxSendOffset] = info.mailbox_send_offset;
  w[sii::kMailboxSendSize] = info.mailbox_send_size;
  w[sii::kMailboxProtocols] = info.mailbox_protocols;
  w[0x003E] = 0x000F;  // 16 Kibit
  w[0x003F] = 0x0001;  // SII version 1
  // Strings: the name first (SOEM and other masters take string 1 as the name, whatever the general
  // category says), the order code, the group.
  std::vector<std::uint8_t> strings{3};
  for (const std::string* s : {&info.name, &info.order, &info.group}) {
    if (s->size() > 255) throw std::invalid_argument("SII: a string of at most 255 bytes, got " + *s);
    strings.push_back(static_cast<std::uint8_t>(s->size()));
    strings.insert(strings.end(), s->begin(), s->end());
  }
  append_category(w, sii_category::kStrings, strings);
  std::vector<std::uint8_t> general(32, 0);
  general[0] = 3;  // group
  general[2] = 2;  // order
  general[3] = 1;  // name
  general[5] = static_cast<std::uint8_t>(info.coe_details | ((info.mailbox_protocols & 0x0004) != 0 ? 0x01 : 0x00));
  append_category(w, sii_category::kGeneral, general);
  std::vector<std::uint8_t> sync_managers;
  for (const SiiSyncManager& sm : info.sync_managers) {
    const std::uint8_t bytes[8] = {static_cast<std::uint8_t>(sm.start & 0xFFU),
                                   static_cast<std::uint8_t>(sm.start >> 8),
                                   static_cast<std::uint8_t>(sm.length & 0xFFU),
                                   static_cast<std::uint8_t>(sm.length >> 8),
                                   sm.control,
                                   0,
                                   sm.enable,
                                   sm.type};
    sync_managers.insert(sync_managers.end(), bytes, bytes + 8);
  }
  if (!sync_managers.empty()) append_category(w, sii_category::kSyncManager, sync_managers);
  w.push_back(sii_category::kEnd);
  w.push_back(0xFFFF);
  return w;
}

std::vector<std::uint16_t> read_sii_image(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open " + path);
  const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() % 2 != 0 || bytes.size() < 2 * sii::kMinWords) {
    throw std::runtime_error(path + ": an SII image is whole words, at least " + std::to_string(2 * sii::kMinWords) +
                             " bytes; got " + std::to_string(bytes.size()));
  }
  std::vector<std::uint16_t> words;
  words.reserve(bytes.size() / 2);
  for (std::size_t i = 0; i < bytes.size(); i += 2) {
    words.push_back(static_cast<std::uint16_t>(static_cast<std::uint8_t>(bytes[i]) |
                                               (static_cast<std::uint8_t>(bytes[i + 1]) << 8)));
  }
  return words;
}

}  // namespace pmlsm::ethercat

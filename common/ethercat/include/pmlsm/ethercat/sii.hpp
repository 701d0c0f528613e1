// A slave's SII (Slave Information Interface, its EEPROM; ETG.1000.6 and ETG.2010): a fixed part of
// 64 words (identity, mailbox layout, supported mailbox protocols) and then categories, each a
// type word, a size in words and its data, up to an end category (0xFFFF):
//
//   10 strings        a count, then length-prefixed strings (indices from 1)
//   30 general        group, image, order and name as string indices, CoE and other details
//   41 sync managers  8 bytes each: start, length, control, status, enable, type (1 mailbox out,
//                     2 mailbox in, 3 outputs, 4 inputs)
//
// parse_sii reads an image (as a master reads it from a slave, or from a drive's dump); build_sii
// writes one for a virtual slave.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace pmlsm::ethercat {

/// SII word addresses (ETG.1000.6 Table 17, ETG.2010).
namespace sii {
inline constexpr std::uint16_t kStationAlias = 0x0004;
inline constexpr std::uint16_t kVendorId = 0x0008;
inline constexpr std::uint16_t kProductCode = 0x000A;
inline constexpr std::uint16_t kRevision = 0x000C;
inline constexpr std::uint16_t kSerial = 0x000E;
inline constexpr std::uint16_t kMailboxReceiveOffset = 0x0018;  ///< the master's writes: SM0
inline constexpr std::uint16_t kMailboxReceiveSize = 0x0019;
inline constexpr std::uint16_t kMailboxSendOffset = 0x001A;  ///< the slave's answers: SM1
inline constexpr std::uint16_t kMailboxSendSize = 0x001B;
inline constexpr std::uint16_t kMailboxProtocols = 0x001C;
inline constexpr std::uint16_t kFirstCategory = 0x0040;
inline constexpr std::uint16_t kMinWords = 0x0042;  ///< the fixed part and an end category
}  // namespace sii

namespace sii_category {
inline constexpr std::uint16_t kStrings = 10;
inline constexpr std::uint16_t kGeneral = 30;
inline constexpr std::uint16_t kFmmu = 40;
inline constexpr std::uint16_t kSyncManager = 41;
inline constexpr std::uint16_t kTxPdo = 50;
inline constexpr std::uint16_t kRxPdo = 51;
inline constexpr std::uint16_t kEnd = 0xFFFF;
}  // namespace sii_category

/// The most words a walk of the categories reads (a 64 Kibit EEPROM).
inline constexpr std::size_t kSiiMaxWords = 4096;

struct SiiSyncManager {
  std::uint16_t start = 0;
  std::uint16_t length = 0;
  std::uint8_t control = 0;
  std::uint8_t enable = 0;
  std::uint8_t type = 0;  ///< 1 mailbox out (master to slave), 2 mailbox in, 3 outputs, 4 inputs
  bool operator==(const SiiSyncManager& o) const {
    return start == o.start && length == o.length && control == o.control && enable == o.enable && type == o.type;
  }
};

/// SiiInfo::coe_details: SDO complete access offered.
inline constexpr std::uint8_t kCoeDetailsCompleteAccess = 0x20;

struct SiiInfo {
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision = 0;
  std::uint32_t serial = 0;
  std::uint16_t mailbox_receive_offset = 0;
  std::uint16_t mailbox_receive_size = 0;
  std::uint16_t mailbox_send_offset = 0;
  std::uint16_t mailbox_send_size = 0;
  std::uint16_t mailbox_protocols = 0;  ///< bit 2: CoE
  /// The general category's CoE details: bit 0 SDO, bit 5 SDO complete access (a master may read
  /// and write a whole record at once). Built with bit 0 set whenever the mailbox speaks CoE.
  std::uint8_t coe_details = 0;
  std::vector<std::string> strings;  ///< index 1 is strings[0]
  std::string name;                  ///< from the general category ("" without one)
  std::string order;
  std::string group;
  std::vector<SiiSyncManager> sync_managers;
};

/// The image's fixed part and its categories, up to the end category or the image's end.
/// @throws std::invalid_argument naming what is wrong: fewer than 0x42 words, a category running
/// past the image, a string past its category, a string index past the strings.
SiiInfo parse_sii(const std::vector<std::uint16_t>& words);

/// An image holding `info`'s identity, mailbox layout, strings (name, order, group) and sync
/// managers, with the end category.
std::vector<std::uint16_t> build_sii(const SiiInfo& info);

/// An image from a file of its raw words, little-endian, as a drive's EEPROM dump holds it.
/// @throws std::runtime_error naming the path when it cannot be read, is not whole words or is
/// shorter than the fixed part and an end category (kMinWords).
std::vector<std::uint16_t> read_sii_image(const std::string& path);

}  // namespace pmlsm::ethercat

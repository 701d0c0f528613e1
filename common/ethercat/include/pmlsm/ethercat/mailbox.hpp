// The EtherCAT mailbox and CoE (ETG.1000.6, ETG.1000.5): acyclic messages a master writes into a
// slave's receive mailbox (SM0) and reads from its send mailbox (SM1). Each starts with a 6-byte
// header
//
//   length (2, of what follows the header) | address (2) | channel, priority (1) | type, counter (1)
//
// (type 3: CoE); a CoE message then has a 2-byte header (service in the top 4 bits: 2 SDO request,
// 3 SDO response, 1 emergency) and, for SDO, the same 8 bytes as a CANopen SDO frame (CiA 301):
// command, index, sub-index, 4 data bytes. So the CANopen SDO server and its object dictionary
// answer CoE too (CoeSdoServer): one CiA 402 dictionary for both buses.
//
// What does not fit in 4 bytes (a text such as 0x1008) goes as CoE carries it (ETG.1000.6
// 5.6.2): a normal upload answers the initiate request with 0x41, the complete size in the 4 data
// bytes and as much of the value as the send mailbox holds after them; the rest in upload segments
// (CiA 301's: the master asks with 0x60 | toggle << 4, the slave answers with toggle << 4,
// c = 1 on the last), each as long as its mailbox message (at least 7 data bytes, n of them unused
// when fewer are left). A normal download (0x21, the size, the data after it) is taken for an
// object of up to 4 bytes, and for a record written whole (complete access) of any length: what
// the receive mailbox does not hold follows in download segments (the master's toggle << 4 | n << 1
// | c, the slave answering 0x20 | toggle << 4), the record written when the last is in. The slave
// has nothing else writable that is longer than 4 bytes.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "pmlsm/canopen/object_dictionary.hpp"
#include "pmlsm/canopen/sdo_server.hpp"

namespace pmlsm::ethercat {

inline constexpr std::size_t kMailboxHeaderBytes = 6;
inline constexpr std::size_t kCoeHeaderBytes = 2;
inline constexpr std::size_t kSdoBytes = 8;
inline constexpr std::uint8_t kMailboxTypeCoe = 3;
inline constexpr std::uint8_t kCoeServiceEmergency = 1;
inline constexpr std::uint8_t kCoeServiceSdoRequest = 2;
inline constexpr std::uint8_t kCoeServiceSdoResponse = 3;

struct MailboxHeader {
  std::uint16_t length = 0;  ///< bytes after the header
  std::uint16_t address = 0;
  std::uint8_t channel = 0;
  std::uint8_t priority = 0;
  std::uint8_t type = 0;     ///< 3: CoE
  std::uint8_t counter = 0;  ///< 1..7, 0 only before the first
};

enum class MailboxError : std::uint8_t { kNone, kShort, kLengthBeyondMailbox, kNotCoe, kNotSdo };
const char* to_string(MailboxError error);

using SdoBytes = std::array<std::uint8_t, kSdoBytes>;

/// A CoE SDO message (`service`: request or response) into `out` (at least
/// kMailboxHeaderBytes + kCoeHeaderBytes + kSdoBytes = 16 bytes), `more_bytes` of `more` after
/// the 8 (a normal transfer's or a segment's further data). Returns the bytes written.
std::size_t write_coe_sdo(std::uint8_t* out, std::uint8_t counter, std::uint8_t service, const SdoBytes& sdo,
                          const std::uint8_t* more = nullptr, std::size_t more_bytes = 0);
/// Where the bytes after the 8 SDO bytes start in a mailbox message, and how many there are (its
/// length past 10).
inline constexpr std::size_t kCoeSdoMoreAt = kMailboxHeaderBytes + kCoeHeaderBytes + kSdoBytes;
inline std::size_t coe_sdo_more_bytes(const MailboxHeader& header) {
  return header.length > kCoeHeaderBytes + kSdoBytes ? header.length - kCoeHeaderBytes - kSdoBytes : 0;
}

/// A mailbox holding a CoE SDO message: its header, its service and the 8 SDO bytes (an emergency
/// (service 1) has 8 bytes too: error code, error register, 5 of the maker's). Never throws.
MailboxError parse_coe_sdo(const std::uint8_t* mailbox, std::size_t size, MailboxHeader& header, std::uint8_t& service,
                           SdoBytes& sdo);

/// What a slave does with a message the master put into its receive mailbox.
class MailboxHandler {
 public:
  virtual ~MailboxHandler() = default;
  /// `request` (size bytes) in; the answer into `response` (capacity bytes). Returns its size
  /// (0: no answer).
  virtual std::size_t handle(const std::uint8_t* request, std::size_t size, std::uint8_t* response,
                             std::size_t capacity) = 0;
};

/// SDO over CoE answered by the CANopen SDO server on an object dictionary (expedited transfers,
/// CiA 301's abort codes); the dictionary's texts by normal and segmented upload, a normal download
/// of up to 4 bytes, a record's by normal and segmented download, as above; and complete access (command bit 4, what
/// SOEM uses to read a slave's PDO assignment and mapping whole when the SII's CoE details offer it): a record read or
/// written whole, sub-index 0 padded to 16 bits. Anything else in the mailbox is answered with
/// nothing.
class CoeSdoServer final : public MailboxHandler {
 public:
  /// What an upload usually needs (texts and records grow it, outside a cycle); a download too.
  static constexpr std::size_t kReservedUploadBytes = 512;
  /// The longest record a segmented download takes (a record of 255 entries of 32 bits, and more).
  static constexpr std::size_t kMaxDownloadBytes = 2048;
  /// `dictionary` outlives the server; `node` only addresses the CANopen server inside.
  CoeSdoServer(canopen::ObjectDictionary& dictionary, canopen::NodeId node)
      : dictionary_(dictionary), server_(dictionary, node) {
    upload_data_.reserve(kReservedUploadBytes);
    download_data_.reserve(kReservedUploadBytes);
  }
  std::size_t handle(const std::uint8_t* request, std::size_t size, std::uint8_t* response,
                     std::size_t capacity) override;
  std::uint64_t requests() const { return requests_; }
  /// A CoE emergency (ETG.1000.6: error code, error register, 5 bytes of the maker's) into `out`
  /// (16 bytes), with the next mailbox counter. Returns the bytes written.
  std::size_t write_emergency(std::uint8_t* out, std::uint16_t error_code, std::uint8_t error_register);

  /// Segments answered (upload and download segment responses), a count for tests and reports.
  std::uint64_t segments() const { return segments_; }

 private:
  /// A normal upload of upload_data_: its size and first bytes (0x41, with the complete-access bit
  /// when asked so), the transfer kept for the segments.
  std::size_t start_upload(std::uint16_t index, std::uint8_t subindex, bool complete_access, std::uint8_t* response,
                           std::size_t capacity);
  std::size_t upload_segment(std::uint8_t command, std::uint8_t* response, std::size_t capacity);
  /// A download segment of the record under way (`sdo` its 8 bytes, `more` what follows them).
  std::size_t download_segment(const SdoBytes& sdo, const std::uint8_t* more, std::size_t more_bytes,
                               std::uint8_t* response);
  /// A normal download: the size (bytes 4-7) and the data after the 8 bytes.
  std::size_t normal_download(const SdoBytes& sdo, const std::uint8_t* more, std::size_t more_bytes,
                              std::uint8_t* response);
  /// Complete access (ETG.1000.6): a record from sub-index 0 (itself as 16 bits) or 1 on, each
  /// present entry up to sub-index 0's value in its size, into upload_data_. 0 or the abort code.
  std::uint32_t read_record(std::uint16_t index, std::uint8_t first_subindex);
  /// The same laid out in `data` written: the length checked first, sub-index 0 (when written and
  /// writable) set to 0 before the entries and to its value after them, each entry's checks kept.
  std::uint32_t write_record(std::uint16_t index, std::uint8_t first_subindex, const std::uint8_t* data,
                             std::size_t size);
  /// The record's sub-index 0 when `index` is a record (an unsigned 8-bit sub-index 0 and more
  /// entries), else nullptr with the abort code in `code`.
  const canopen::Entry* record_count(std::uint16_t index, std::uint32_t& code) const;
  std::size_t respond(std::uint8_t* response, const SdoBytes& sdo, const std::uint8_t* more = nullptr,
                      std::size_t more_bytes = 0);
  std::size_t abort(std::uint8_t* response, std::uint16_t index, std::uint8_t subindex, std::uint32_t code);
  /// The initiate download response (0x60): written.
  std::size_t downloaded(std::uint8_t* response, std::uint16_t index, std::uint8_t subindex);

  /// A normal upload under way: its multiplexer, the bytes sent so far, the next toggle.
  struct Upload {
    bool active = false;
    std::uint16_t index = 0;
    std::uint8_t subindex = 0;
    std::size_t sent = 0;
    std::uint8_t toggle = 0;
  };

  /// A segmented download of a record under way: its multiplexer, its size, the next toggle (the
  /// bytes so far in download_data_).
  struct Download {
    bool active = false;
    std::uint16_t index = 0;
    std::uint8_t subindex = 0;
    std::size_t total = 0;
    std::uint8_t toggle = 0;
  };

  canopen::ObjectDictionary& dictionary_;
  canopen::SdoServer server_;
  Upload upload_;
  Download download_;
  std::vector<std::uint8_t> upload_data_;    ///< what the upload under way sends
  std::vector<std::uint8_t> download_data_;  ///< what the download under way brought
  std::uint8_t counter_ = 0;
  std::uint64_t requests_ = 0;
  std::uint64_t segments_ = 0;
};

}  // namespace pmlsm::ethercat

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
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

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
/// kMailboxHeaderBytes + kCoeHeaderBytes + kSdoBytes = 16 bytes). Returns the bytes written.
std::size_t write_coe_sdo(std::uint8_t* out, std::uint8_t counter, std::uint8_t service, const SdoBytes& sdo);

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
/// CiA 301's abort codes). Anything else in the mailbox is answered with nothing.
class CoeSdoServer final : public MailboxHandler {
 public:
  /// `dictionary` outlives the server; `node` only addresses the CANopen server inside.
  CoeSdoServer(canopen::ObjectDictionary& dictionary, canopen::NodeId node) : server_(dictionary, node) {}
  std::size_t handle(const std::uint8_t* request, std::size_t size, std::uint8_t* response,
                     std::size_t capacity) override;
  std::uint64_t requests() const { return requests_; }
  /// A CoE emergency (ETG.1000.6: error code, error register, 5 bytes of the maker's) into `out`
  /// (16 bytes), with the next mailbox counter. Returns the bytes written.
  std::size_t write_emergency(std::uint8_t* out, std::uint16_t error_code, std::uint8_t error_register);

 private:
  canopen::SdoServer server_;
  std::uint8_t counter_ = 0;
  std::uint64_t requests_ = 0;
};

}  // namespace pmlsm::ethercat

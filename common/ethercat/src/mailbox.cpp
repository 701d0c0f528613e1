#include "pmlsm/ethercat/mailbox.hpp"

#include <algorithm>

#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/util/little_endian.hpp"

namespace pmlsm::ethercat {

const char* to_string(MailboxError error) {
  switch (error) {
    case MailboxError::kNone: return "none";
    case MailboxError::kShort: return "shorter than its headers";
    case MailboxError::kLengthBeyondMailbox: return "a length past the mailbox";
    case MailboxError::kNotCoe: return "not CoE";
    case MailboxError::kNotSdo: return "a CoE service other than SDO";
  }
  return "?";
}

std::size_t write_coe_sdo(std::uint8_t* out, std::uint8_t counter, std::uint8_t service, const SdoBytes& sdo) {
  put_le16(out, static_cast<std::uint16_t>(kCoeHeaderBytes + kSdoBytes));
  put_le16(out + 2, 0);  // address: the master
  out[4] = 0;            // channel 0, priority 0
  out[5] = static_cast<std::uint8_t>(kMailboxTypeCoe | ((counter & 0x07U) << 4));
  put_le16(out + kMailboxHeaderBytes, static_cast<std::uint16_t>(service << 12));
  std::copy(sdo.begin(), sdo.end(), out + kMailboxHeaderBytes + kCoeHeaderBytes);
  return kMailboxHeaderBytes + kCoeHeaderBytes + kSdoBytes;
}

MailboxError parse_coe_sdo(const std::uint8_t* mailbox, std::size_t size, MailboxHeader& header, std::uint8_t& service,
                           SdoBytes& sdo) {
  if (size < kMailboxHeaderBytes) return MailboxError::kShort;
  header.length = get_le16(mailbox);
  header.address = get_le16(mailbox + 2);
  header.channel = static_cast<std::uint8_t>(mailbox[4] & 0x3FU);
  header.priority = static_cast<std::uint8_t>(mailbox[4] >> 6);
  header.type = static_cast<std::uint8_t>(mailbox[5] & 0x0FU);
  header.counter = static_cast<std::uint8_t>((mailbox[5] >> 4) & 0x07U);
  if (kMailboxHeaderBytes + header.length > size) return MailboxError::kLengthBeyondMailbox;
  if (header.type != kMailboxTypeCoe) return MailboxError::kNotCoe;
  if (header.length < kCoeHeaderBytes + kSdoBytes) return MailboxError::kShort;
  service = static_cast<std::uint8_t>(get_le16(mailbox + kMailboxHeaderBytes) >> 12);
  if (service != kCoeServiceSdoRequest && service != kCoeServiceSdoResponse) return MailboxError::kNotSdo;
  std::copy(mailbox + kMailboxHeaderBytes + kCoeHeaderBytes,
            mailbox + kMailboxHeaderBytes + kCoeHeaderBytes + kSdoBytes, sdo.begin());
  return MailboxError::kNone;
}

std::size_t CoeSdoServer::handle(const std::uint8_t* request, std::size_t size, std::uint8_t* response,
                                 std::size_t capacity) {
  MailboxHeader header;
  std::uint8_t service = 0;
  SdoBytes sdo{};
  if (parse_coe_sdo(request, size, header, service, sdo) != MailboxError::kNone || service != kCoeServiceSdoRequest ||
      capacity < kMailboxHeaderBytes + kCoeHeaderBytes + kSdoBytes) {
    return 0;
  }
  ++requests_;
  // The CANopen server's request frame: its own COB-ID, the 8 bytes as they came.
  canopen::CanFrame frame{};
  frame.id = canopen::sdo_rx_cob_id(server_.node());
  frame.dlc = 8;
  std::copy(sdo.begin(), sdo.end(), frame.data.begin());
  const canopen::SdoServerResult r = server_.handle(frame);
  if (!r.respond) return 0;  // the client's abort: nothing to answer
  SdoBytes answer{};
  std::copy(r.response.data.begin(), r.response.data.end(), answer.begin());
  counter_ = static_cast<std::uint8_t>(counter_ % 7 + 1);
  return write_coe_sdo(response, counter_, kCoeServiceSdoResponse, answer);
}

std::size_t CoeSdoServer::write_emergency(std::uint8_t* out, std::uint16_t error_code, std::uint8_t error_register) {
  SdoBytes body{};
  body[0] = static_cast<std::uint8_t>(error_code & 0xFFU);
  body[1] = static_cast<std::uint8_t>(error_code >> 8);
  body[2] = error_register;
  counter_ = static_cast<std::uint8_t>(counter_ % 7 + 1);
  return write_coe_sdo(out, counter_, kCoeServiceEmergency, body);
}

}  // namespace pmlsm::ethercat

// What a capture of an EtherCAT bus holds, as our parsers read it: every frame parsed (the
// malformed ones named), the datagrams counted by command, and the CoE SDO messages found in the
// mailboxes, decoded as CANopen SDO (the same 8 bytes; canopen/sdo.hpp). `pmlsm ethercat pcap`
// prints it; the tests check it against what tshark reads from a real drive's captures.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "pmlsm/ethercat/frame.hpp"
#include "pmlsm/ethercat/mailbox.hpp"
#include "pmlsm/ethercat/pcapng.hpp"

namespace pmlsm::ethercat {

/// A CoE SDO message seen in a datagram: a configured-address write into a slave's receive
/// mailbox (a request) or read of its send mailbox (a response).
struct SeenSdo {
  std::uint16_t station = 0;
  std::uint16_t mailbox_address = 0;  ///< where the mailbox is in the slave's memory
  std::uint8_t service = 0;           ///< kCoeServiceSdoRequest or kCoeServiceSdoResponse
  MailboxHeader header;
  SdoBytes sdo{};
};

/// Whether `datagram` carries one: FPWR (a request) or FPRD (a response) that its slave counted
/// (working counter 1: a write taken, a read of a full mailbox), at an address in the process RAM
/// (0x1000 and up, where the mailboxes are), holding a well-formed CoE SDO message. Never throws.
bool find_coe_sdo(const DatagramView& datagram, SeenSdo& out);

/// The message in words: "upload request 0x1C00:00", "upload response 0x1C00:00 = 0x04 (1 byte)",
/// "abort 0x6061:00: 0x06020000 (object does not exist)", or why it is not decoded.
std::string describe(const SeenSdo& sdo);

/// For a response: the expedited upload's value and size (false for any other message).
bool upload_value(const SeenSdo& sdo, std::uint16_t& index, std::uint8_t& subindex, std::uint32_t& value,
                  std::uint8_t& size);

struct CaptureDecode {
  std::uint64_t frames = 0;           ///< packets in the capture
  std::uint64_t ethercat_frames = 0;  ///< EtherCAT frames: EtherType 0x88A4, or over UDP to port 34980
  std::uint64_t over_udp = 0;         ///< of them, over UDP
  std::uint64_t other_types = 0;      ///< of them, of another EtherCAT type than datagrams (network variables...)
  std::uint64_t other_frames = 0;     ///< not EtherCAT
  std::uint64_t malformed_frames = 0;
  std::uint64_t first_malformed = 0;  ///< its packet number (0: none)
  FrameError first_error = FrameError::kNone;
  std::array<std::uint64_t, kCommandCount> datagrams{};  ///< by command
  struct Sdo {
    std::uint64_t frame = 0;  ///< the packet number
    SeenSdo seen;
  };
  std::vector<Sdo> sdos;
};

/// Every packet of `reader` (from where it is). @throws std::runtime_error for a malformed file
/// (PcapngReader::next); a malformed frame is counted, not thrown.
CaptureDecode decode_capture(PcapngReader& reader);

}  // namespace pmlsm::ethercat

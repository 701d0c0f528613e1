// EtherCAT frames and datagrams (ETG.1000.4, IEC 61158-4-12): what a master sends and the slaves
// pass on. An Ethernet frame of EtherType 0x88A4 carries a 2-byte EtherCAT header (11 bits of
// length, type 1: datagrams) and one or more datagrams, each
//
//   command (1) | index (1) | address (4) | length (11 bits), circulating, more | IRQ (2) | data | working counter (2)
//
// all little-endian. The address is a slave's position (ADP, auto increment: 0, -1, -2, ... a
// slave answers at 0 and adds 1 on the way), its station address (ADP, configured) with a register
// offset (ADO), or a 32-bit logical address (the FMMUs map it onto slaves' memory). Every slave
// that does what a datagram asks adds to its working counter, so the master knows how many did.
// EtherCAT over UDP (port 34980) carries the same bytes from the EtherCAT header on.
//
// The builder writes into a fixed buffer and the parser reads views into the caller's bytes:
// nothing is allocated per frame. The parser takes bytes from outside (a network, a capture)
// and never throws: a frame it refuses is named by its FrameError.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace pmlsm::ethercat {

inline constexpr std::uint16_t kEtherType = 0x88A4;
inline constexpr std::uint16_t kUdpPort = 34980;  ///< EtherCAT over UDP (ETG.1000.4, 5.3.3)
inline constexpr std::size_t kEthernetHeaderBytes = 14;
inline constexpr std::size_t kMinEthernetFrameBytes = 60;    ///< without the FCS: shorter ones are padded
inline constexpr std::size_t kMaxEthernetFrameBytes = 1514;  ///< without the FCS
inline constexpr std::size_t kFrameHeaderBytes = 2;
inline constexpr std::size_t kDatagramHeaderBytes = 10;
inline constexpr std::size_t kWorkingCounterBytes = 2;
/// The datagrams of one frame: 1498 bytes.
inline constexpr std::size_t kMaxDatagramsBytes = kMaxEthernetFrameBytes - kEthernetHeaderBytes - kFrameHeaderBytes;
/// The data of one datagram alone in a frame: 1486 bytes.
inline constexpr std::size_t kMaxDatagramDataBytes = kMaxDatagramsBytes - kDatagramHeaderBytes - kWorkingCounterBytes;
/// Datagrams one frame may hold here (a full frame of empty ones would hold 124).
inline constexpr std::size_t kMaxDatagramsPerFrame = 64;

enum class Command : std::uint8_t {
  kNop = 0,
  kAprd = 1,  ///< auto increment physical read
  kApwr = 2,
  kAprw = 3,
  kFprd = 4,  ///< configured address physical read
  kFpwr = 5,
  kFprw = 6,
  kBrd = 7,  ///< broadcast read (the slaves' data OR-ed)
  kBwr = 8,
  kBrw = 9,
  kLrd = 10,  ///< logical read
  kLwr = 11,
  kLrw = 12,
  kArmw = 13,  ///< auto increment read, multiple write (the addressed slave's data written to the others)
  kFrmw = 14,  ///< configured address read, multiple write (distributed clocks: the reference clock's time)
};
inline constexpr std::uint8_t kCommandCount = 15;

/// "APRD", ... as ETG.1000.4 and Wireshark name them; "?" for none of them.
const char* to_string(Command command);
bool is_logical(Command command);
/// APRD, APWR, APRW, ARMW: addressed by position, the ADP counted up by every slave on the way.
bool is_auto_increment(Command command);

/// What each slave that does what `command` asks adds to the working counter: 1 for a read or a
/// write, 3 for a read-write (1 read + 2 written), 1 for ARMW and FRMW (read at the addressed
/// slave, written at the others), 0 for NOP.
std::uint16_t working_counter_per_slave(Command command);
/// The working counter a datagram comes back with when `slaves` slaves all did what it asked.
std::uint16_t expected_working_counter(Command command, std::uint16_t slaves);

/// ADP and ADO as the 32-bit address field holds them (ADP in the low half).
constexpr std::uint32_t physical_address(std::uint16_t adp, std::uint16_t ado) {
  return static_cast<std::uint32_t>(adp) | (static_cast<std::uint32_t>(ado) << 16);
}
/// The ADP that reaches the slave at `position` (0 first) by auto increment: -position.
constexpr std::uint16_t auto_increment_adp(std::uint16_t position) {
  return static_cast<std::uint16_t>(0x10000U - position);
}

struct DatagramHeader {
  Command command = Command::kNop;
  std::uint8_t index = 0;     ///< the master's, to match the reply
  std::uint32_t address = 0;  ///< physical_address(ADP, ADO), or the logical address
  std::uint16_t length = 0;   ///< data bytes, at most kMaxDatagramDataBytes
  bool circulating = false;   ///< set by a slave that closed the ring (a frame going round again)
  bool more = false;          ///< another datagram follows in the frame
  std::uint16_t irq = 0;      ///< the slaves' event requests OR-ed
  std::uint16_t adp() const { return static_cast<std::uint16_t>(address & 0xFFFFU); }
  std::uint16_t ado() const { return static_cast<std::uint16_t>(address >> 16); }
};

using MacAddress = std::array<std::uint8_t, 6>;
/// A locally administered unicast address: what a master without one of its own sends from.
inline constexpr MacAddress kDefaultMasterMac{0x02, 0x00, 0x00, 0x00, 0x00, 0x01};
inline constexpr MacAddress kBroadcastMac{0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};

/// A view of bytes the caller keeps.
struct Bytes {
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
};

/// One frame being written: datagrams appended in order into a fixed Ethernet frame buffer.
class FrameBuilder {
 public:
  explicit FrameBuilder(const MacAddress& source = kDefaultMasterMac, const MacAddress& destination = kBroadcastMac);
  /// Empties the frame (the addresses stay).
  void clear();
  /// Appends a datagram with `length` data bytes copied from `data` (nullptr: zeros) and the
  /// working counter `working_counter` (a master sends 0). Sets the previous datagram's more bit.
  /// @return false, appending nothing, when it does not fit in the frame (or the frame holds
  /// kMaxDatagramsPerFrame already).
  bool add(Command command, std::uint8_t index, std::uint32_t address, const std::uint8_t* data, std::uint16_t length,
           std::uint16_t working_counter = 0, std::uint16_t irq = 0);
  std::size_t datagram_count() const { return count_; }
  /// Bytes the datagrams take, headers and working counters included.
  std::size_t datagrams_bytes() const { return end_ - kEthernetHeaderBytes - kFrameHeaderBytes; }
  /// Whether a datagram of `length` data bytes still fits.
  bool fits(std::uint16_t length) const;
  /// The Ethernet frame, padded to kMinEthernetFrameBytes: for a raw socket and a capture.
  Bytes ethernet() const;
  /// The EtherCAT frame alone (its header and the datagrams): EtherCAT over UDP's payload.
  Bytes udp_payload() const;

 private:
  std::array<std::uint8_t, kMaxEthernetFrameBytes> bytes_{};
  std::array<std::uint16_t, kMaxDatagramsPerFrame> header_at_{};
  std::size_t count_ = 0;
  std::size_t end_ = kEthernetHeaderBytes + kFrameHeaderBytes;
};

enum class FrameError : std::uint8_t {
  kNone,
  kShort,                ///< fewer bytes than an Ethernet and an EtherCAT header
  kNoDatagram,           ///< an EtherCAT header of length 0
  kNotEtherCat,          ///< another EtherType
  kNotDatagrams,         ///< an EtherCAT header of another type than 1 (datagrams)
  kLengthBeyondFrame,    ///< the header's length runs past the bytes received
  kDatagramBeyondFrame,  ///< a datagram's header, data or working counter runs past the length
  kUnknownCommand,       ///< a command above FRMW
  kMoreWithoutNext,      ///< the more bit set on a datagram that ends the frame
  kBytesAfterLast,       ///< the last datagram (more clear) ends before the header's length
  kTooManyDatagrams,     ///< more than kMaxDatagramsPerFrame
};
const char* to_string(FrameError error);

/// One datagram of a parsed frame; data points into the parsed bytes.
struct DatagramView {
  DatagramHeader header;
  const std::uint8_t* data = nullptr;
  std::uint16_t working_counter = 0;
};

struct ParsedFrame {
  MacAddress source{};       ///< Ethernet frames only
  MacAddress destination{};  ///< Ethernet frames only
  std::array<DatagramView, kMaxDatagramsPerFrame> datagrams{};
  std::size_t count = 0;
};

/// An Ethernet frame (from a raw socket or a capture; padding after the datagrams is allowed).
FrameError parse_ethernet_frame(const std::uint8_t* bytes, std::size_t size, ParsedFrame& out);
/// An EtherCAT frame from its header on (EtherCAT over UDP's payload).
FrameError parse_ethercat_frame(const std::uint8_t* bytes, std::size_t size, ParsedFrame& out);

}  // namespace pmlsm::ethercat

#include "pmlsm/ethercat/frame.hpp"

#include <algorithm>
#include <cstring>

#include "pmlsm/util/little_endian.hpp"

namespace pmlsm::ethercat {

namespace {

constexpr std::uint16_t kLengthMask = 0x07FF;
constexpr std::uint16_t kCirculatingBit = 0x4000;
constexpr std::uint16_t kMoreBit = 0x8000;
constexpr std::uint16_t kTypeDatagrams = 1;

}  // namespace

const char* to_string(Command command) {
  static constexpr const char* kNames[kCommandCount] = {"NOP", "APRD", "APWR", "APRW", "FPRD", "FPWR", "FPRW", "BRD",
                                                        "BWR", "BRW",  "LRD",  "LWR",  "LRW",  "ARMW", "FRMW"};
  const auto i = static_cast<std::uint8_t>(command);
  return i < kCommandCount ? kNames[i] : "?";
}

bool is_logical(Command command) {
  return command == Command::kLrd || command == Command::kLwr || command == Command::kLrw;
}

bool is_auto_increment(Command command) {
  return command == Command::kAprd || command == Command::kApwr || command == Command::kAprw ||
         command == Command::kArmw;
}

std::uint16_t working_counter_per_slave(Command command) {
  switch (command) {
    case Command::kNop: return 0;
    case Command::kAprw:
    case Command::kFprw:
    case Command::kBrw:
    case Command::kLrw: return 3;
    default: return 1;
  }
}

std::uint16_t expected_working_counter(Command command, std::uint16_t slaves) {
  return static_cast<std::uint16_t>(working_counter_per_slave(command) * slaves);
}

FrameBuilder::FrameBuilder(const MacAddress& source, const MacAddress& destination) {
  std::copy(destination.begin(), destination.end(), bytes_.begin());
  std::copy(source.begin(), source.end(), bytes_.begin() + 6);
  bytes_[12] = static_cast<std::uint8_t>(kEtherType >> 8);  // the EtherType is big-endian on the wire
  bytes_[13] = static_cast<std::uint8_t>(kEtherType & 0xFFU);
  clear();
}

void FrameBuilder::clear() {
  // Bytes past the end stay zero: they are the padding of a short frame.
  std::fill(bytes_.begin() + static_cast<std::ptrdiff_t>(kEthernetHeaderBytes),
            bytes_.begin() + static_cast<std::ptrdiff_t>(end_), 0);
  count_ = 0;
  end_ = kEthernetHeaderBytes + kFrameHeaderBytes;
  put_le16(bytes_.data() + kEthernetHeaderBytes, static_cast<std::uint16_t>(kTypeDatagrams << 12));
}

bool FrameBuilder::fits(std::uint16_t length) const {
  return count_ < kMaxDatagramsPerFrame &&
         end_ + kDatagramHeaderBytes + length + kWorkingCounterBytes <= kMaxEthernetFrameBytes;
}

bool FrameBuilder::add(Command command, std::uint8_t index, std::uint32_t address, const std::uint8_t* data,
                       std::uint16_t length, std::uint16_t working_counter, std::uint16_t irq) {
  if (length > kMaxDatagramDataBytes || !fits(length)) return false;
  if (count_ > 0) {  // the one before is no longer the last
    std::uint8_t* previous = bytes_.data() + header_at_[count_ - 1] + 6;
    put_le16(previous, static_cast<std::uint16_t>(get_le16(previous) | kMoreBit));
  }
  std::uint8_t* h = bytes_.data() + end_;
  h[0] = static_cast<std::uint8_t>(command);
  h[1] = index;
  put_le32(h + 2, address);
  put_le16(h + 6, length);
  put_le16(h + 8, irq);
  std::uint8_t* d = h + kDatagramHeaderBytes;
  if (data != nullptr) {
    std::memcpy(d, data, length);
  } else {
    std::memset(d, 0, length);
  }
  put_le16(d + length, working_counter);
  header_at_[count_++] = static_cast<std::uint16_t>(end_);
  end_ += kDatagramHeaderBytes + length + kWorkingCounterBytes;
  put_le16(bytes_.data() + kEthernetHeaderBytes,
           static_cast<std::uint16_t>((kTypeDatagrams << 12) | (datagrams_bytes() & kLengthMask)));
  return true;
}

Bytes FrameBuilder::ethernet() const { return {bytes_.data(), std::max(end_, kMinEthernetFrameBytes)}; }

Bytes FrameBuilder::udp_payload() const { return {bytes_.data() + kEthernetHeaderBytes, end_ - kEthernetHeaderBytes}; }

const char* to_string(FrameError error) {
  switch (error) {
    case FrameError::kNone: return "none";
    case FrameError::kShort: return "shorter than its headers";
    case FrameError::kNoDatagram: return "no datagram (an EtherCAT header of length 0)";
    case FrameError::kNotEtherCat: return "not EtherType 0x88A4";
    case FrameError::kNotDatagrams: return "an EtherCAT header of another type than datagrams (1)";
    case FrameError::kLengthBeyondFrame: return "the EtherCAT header's length runs past the frame";
    case FrameError::kDatagramBeyondFrame: return "a datagram runs past the EtherCAT header's length";
    case FrameError::kUnknownCommand: return "an unknown command";
    case FrameError::kMoreWithoutNext: return "the more bit set on the last datagram";
    case FrameError::kBytesAfterLast: return "bytes after the last datagram within the length";
    case FrameError::kTooManyDatagrams: return "more datagrams than a frame may hold here";
  }
  return "?";
}

FrameError parse_ethercat_frame(const std::uint8_t* bytes, std::size_t size, ParsedFrame& out) {
  out.count = 0;
  if (size < kFrameHeaderBytes) return FrameError::kShort;
  const std::uint16_t header = get_le16(bytes);
  if ((header >> 12) != kTypeDatagrams) return FrameError::kNotDatagrams;
  const std::size_t length = header & kLengthMask;
  if (kFrameHeaderBytes + length > size) return FrameError::kLengthBeyondFrame;
  if (length == 0) return FrameError::kNoDatagram;
  const std::uint8_t* p = bytes + kFrameHeaderBytes;
  std::size_t at = 0;
  while (at < length) {
    if (out.count == kMaxDatagramsPerFrame) return FrameError::kTooManyDatagrams;
    if (length - at < kDatagramHeaderBytes + kWorkingCounterBytes) return FrameError::kDatagramBeyondFrame;
    const std::uint8_t* h = p + at;
    if (h[0] >= kCommandCount) return FrameError::kUnknownCommand;
    DatagramView& d = out.datagrams[out.count];
    d.header.command = static_cast<Command>(h[0]);
    d.header.index = h[1];
    d.header.address = get_le32(h + 2);
    const std::uint16_t length_field = get_le16(h + 6);
    d.header.length = static_cast<std::uint16_t>(length_field & kLengthMask);
    d.header.circulating = (length_field & kCirculatingBit) != 0;
    d.header.more = (length_field & kMoreBit) != 0;
    d.header.irq = get_le16(h + 8);
    const std::size_t datagram_bytes = kDatagramHeaderBytes + d.header.length + kWorkingCounterBytes;
    if (datagram_bytes > length - at) return FrameError::kDatagramBeyondFrame;
    d.data = h + kDatagramHeaderBytes;
    d.working_counter = get_le16(d.data + d.header.length);
    ++out.count;
    at += datagram_bytes;
    if (!d.header.more) {
      // TwinCAT rounds the header's length up to an even count: one byte of padding after an odd
      // last datagram (a real drive's capture, twincat-akd-nc-mode.pcapng, has such frames;
      // tshark reads them as pad bytes). More than that is refused.
      const bool rounded_to_even = at + 1 == length && length % 2 == 0;
      return at == length || rounded_to_even ? FrameError::kNone : FrameError::kBytesAfterLast;
    }
  }
  return FrameError::kMoreWithoutNext;
}

FrameError parse_ethernet_frame(const std::uint8_t* bytes, std::size_t size, ParsedFrame& out) {
  out.count = 0;
  if (size < kEthernetHeaderBytes + kFrameHeaderBytes) return FrameError::kShort;
  if (((bytes[12] << 8) | bytes[13]) != kEtherType) return FrameError::kNotEtherCat;
  std::copy(bytes, bytes + 6, out.destination.begin());
  std::copy(bytes + 6, bytes + 12, out.source.begin());
  return parse_ethercat_frame(bytes + kEthernetHeaderBytes, size - kEthernetHeaderBytes, out);
}

}  // namespace pmlsm::ethercat

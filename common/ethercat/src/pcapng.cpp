#include "pmlsm/ethercat/pcapng.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <utility>

namespace pmlsm::ethercat {

namespace {

// pcapng (draft-ietf-opsawg-pcapng): blocks of type, total length, body, total length again,
// each a multiple of 4 bytes, in the writer's byte order (the section header's magic says which).
constexpr std::uint32_t kSectionHeaderBlock = 0x0A0D0D0A;
constexpr std::uint32_t kByteOrderMagic = 0x1A2B3C4D;
constexpr std::uint32_t kInterfaceDescriptionBlock = 1;
constexpr std::uint32_t kEnhancedPacketBlock = 6;
constexpr std::uint32_t kSimplePacketBlock = 3;
constexpr std::uint16_t kOptionTimestampResolution = 9;  ///< if_tsresol: 9 = nanoseconds
constexpr std::uint16_t kOptionEnd = 0;

std::size_t padded4(std::size_t n) { return (n + 3U) & ~std::size_t{3U}; }

}  // namespace

PcapngWriter::PcapngWriter(const std::string& path) : path_(path), file_(std::fopen(path.c_str(), "wb")) {
  if (!file_) throw std::runtime_error("cannot write " + path);
  // Section header: no options; the section's length is not given (-1).
  const std::uint32_t shb_length = 28;
  const std::uint16_t version[2] = {1, 0};
  const std::int64_t section_length = -1;
  put(&kSectionHeaderBlock, 4);
  put(&shb_length, 4);
  put(&kByteOrderMagic, 4);
  put(version, 4);
  put(&section_length, 8);
  put(&shb_length, 4);
  // Interface: Ethernet, no snap length, timestamps in nanoseconds (if_tsresol 9, then end of options).
  const std::uint32_t idb_length = 32;
  const std::uint16_t link[2] = {kLinkTypeEthernet, 0};
  const std::uint32_t snap_length = 0;
  const std::uint16_t resolution_option[2] = {kOptionTimestampResolution, 1};
  const std::array<std::uint8_t, 4> resolution{9, 0, 0, 0};
  const std::uint32_t end_of_options = 0;
  put(&kInterfaceDescriptionBlock, 4);
  put(&idb_length, 4);
  put(link, 4);
  put(&snap_length, 4);
  put(resolution_option, 4);
  put(resolution.data(), 4);
  put(&end_of_options, 4);
  put(&idb_length, 4);
}

void PcapngWriter::put(const void* bytes, std::size_t size) {
  if (std::fwrite(bytes, 1, size, file_.get()) != size) throw std::runtime_error("cannot write " + path_);
}

void PcapngWriter::write(Bytes ethernet_frame, std::int64_t time_ns) {
  const std::size_t body = padded4(ethernet_frame.size);
  const auto total = static_cast<std::uint32_t>(32 + body);
  const std::uint32_t interface_id = 0;
  const auto time = static_cast<std::uint64_t>(time_ns);
  const auto time_high = static_cast<std::uint32_t>(time >> 32);
  const auto time_low = static_cast<std::uint32_t>(time & 0xFFFFFFFFU);
  const auto captured = static_cast<std::uint32_t>(ethernet_frame.size);
  put(&kEnhancedPacketBlock, 4);
  put(&total, 4);
  put(&interface_id, 4);
  put(&time_high, 4);
  put(&time_low, 4);
  put(&captured, 4);
  put(&captured, 4);  // the original length: nothing is cut
  put(ethernet_frame.data, ethernet_frame.size);
  const std::array<std::uint8_t, 3> zeros{};
  put(zeros.data(), body - ethernet_frame.size);
  put(&total, 4);
  ++frames_;
}

void PcapngWriter::flush() {
  if (std::fflush(file_.get()) != 0) throw std::runtime_error("cannot write " + path_);
}

// ---- reading -----------------------------------------------------------------------------------

PcapngReader::PcapngReader(const std::string& path) : path_(path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  bytes_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  if (in.bad()) throw std::runtime_error("cannot read " + path);
  check_start();
}

PcapngReader::PcapngReader(std::vector<std::uint8_t> bytes, std::string name)
    : path_(std::move(name)), bytes_(std::move(bytes)) {
  check_start();
}

void PcapngReader::check_start() const {
  if (bytes_.size() < 28 || u32(0) != kSectionHeaderBlock) {
    throw std::runtime_error(path_ + ": not a pcapng capture (no section header block at its start)");
  }
}

std::uint32_t PcapngReader::u32(std::size_t at) const {
  std::uint32_t v = 0;
  std::memcpy(&v, bytes_.data() + at, 4);
  return swapped_ ? __builtin_bswap32(v) : v;
}

std::uint16_t PcapngReader::u16(std::size_t at) const {
  std::uint16_t v = 0;
  std::memcpy(&v, bytes_.data() + at, 2);
  return swapped_ ? __builtin_bswap16(v) : v;
}

void PcapngReader::malformed(std::size_t at, const std::string& what) const {
  throw std::runtime_error(path_ + ": malformed block at byte " + std::to_string(at) + ": " + what);
}

void PcapngReader::read_section_header(std::size_t at, std::size_t length) {
  if (length < 28) malformed(at, "a section header of " + std::to_string(length) + " bytes (at least 28)");
  std::uint32_t magic = 0;
  std::memcpy(&magic, bytes_.data() + at + 8, 4);
  if (magic == kByteOrderMagic) {
    swapped_ = false;
  } else if (magic == __builtin_bswap32(kByteOrderMagic)) {
    swapped_ = true;
  } else {
    malformed(at, "a section header without the byte-order magic 0x1A2B3C4D");
  }
  if (u16(at + 12) != 1) malformed(at, "pcapng major version " + std::to_string(u16(at + 12)) + " (1 is read)");
  interfaces_.clear();  // interface ids count from 0 again in each section
}

void PcapngReader::read_interface(std::size_t at, std::size_t length) {
  if (length < 20) malformed(at, "an interface description of " + std::to_string(length) + " bytes (at least 20)");
  Interface interface;
  interface.link_type = u16(at + 8);
  interface.snap_length = u32(at + 12);
  // Options up to the trailing length: code, length, value padded to 4 bytes.
  for (std::size_t option = at + 16; option + 4 <= at + length - 4;) {
    const std::uint16_t code = u16(option);
    const std::uint16_t size = u16(option + 2);
    if (code == kOptionEnd) break;
    if (option + 4 + size > at + length - 4) malformed(at, "an interface option past the block");
    if (code == kOptionTimestampResolution && size >= 1) {
      const std::uint8_t resolution = bytes_[option + 4];
      interface.binary = (resolution & 0x80U) != 0;
      interface.exponent = static_cast<std::uint8_t>(resolution & 0x7FU);
    }
    option += 4 + padded4(size);
  }
  interfaces_.push_back(interface);
}

std::int64_t PcapngReader::to_ns(const Interface& interface, std::uint64_t units) const {
  const auto large = static_cast<long double>(units);
  long double ns = 0;
  if (interface.binary) {
    ns = large * 1e9L / static_cast<long double>(std::uint64_t{1} << std::min<int>(interface.exponent, 63));
  } else {
    long double scale = 1e9L;
    for (int i = 0; i < interface.exponent; ++i) scale /= 10.0L;
    ns = large * scale;
  }
  if (ns > static_cast<long double>(std::numeric_limits<std::int64_t>::max())) {
    return std::numeric_limits<std::int64_t>::max();
  }
  return static_cast<std::int64_t>(ns);
}

bool PcapngReader::next(CapturedFrame& frame) {
  while (offset_ + 12 <= bytes_.size()) {
    const std::size_t at = offset_;
    const std::uint32_t type = u32(at);
    if (type == kSectionHeaderBlock) {
      // Its length is in its own byte order: read the magic first.
      std::uint32_t magic = 0;
      std::memcpy(&magic, bytes_.data() + at + 8, 4);
      swapped_ = magic == __builtin_bswap32(kByteOrderMagic);
    }
    const std::size_t length = u32(at + 4);
    if (length < 12 || length % 4 != 0 || length > bytes_.size() - at) {
      malformed(at, "a block length of " + std::to_string(length) + " (a multiple of 4, at least 12, within the " +
                        std::to_string(bytes_.size()) + " bytes of the file)");
    }
    if (u32(at + length - 4) != length) malformed(at, "its trailing length differs from its leading one");
    offset_ = at + length;
    if (type == kSectionHeaderBlock) {
      read_section_header(at, length);
    } else if (type == kInterfaceDescriptionBlock) {
      read_interface(at, length);
    } else if (type == kEnhancedPacketBlock || type == kSimplePacketBlock) {
      const bool enhanced = type == kEnhancedPacketBlock;
      const std::size_t header = enhanced ? 28 : 12;
      if (length < header + 4) malformed(at, "a packet block of " + std::to_string(length) + " bytes");
      const std::uint32_t interface_id = enhanced ? u32(at + 8) : 0;
      if (interface_id >= interfaces_.size()) {
        malformed(at, "a packet on interface " + std::to_string(interface_id) + ", which no block described");
      }
      const Interface& interface = interfaces_[interface_id];
      std::size_t captured = 0;
      frame.original_bytes = enhanced ? u32(at + 24) : u32(at + 8);
      if (enhanced) {
        captured = u32(at + 20);
        const std::uint64_t units = (static_cast<std::uint64_t>(u32(at + 12)) << 32) | u32(at + 16);
        frame.time_ns = to_ns(interface, units);
      } else {
        // A simple packet holds as much of the packet as the block does (no timestamp).
        captured = std::min<std::size_t>(frame.original_bytes, length - header - 4);
        if (interface.snap_length > 0) captured = std::min<std::size_t>(captured, interface.snap_length);
        frame.time_ns = 0;
      }
      if (header + captured + 4 > length) {
        malformed(at, "a packet of " + std::to_string(captured) + " bytes in a block of " + std::to_string(length));
      }
      frame.number = ++packets_;
      frame.link_type = interface.link_type;
      frame.data = {bytes_.data() + at + header, captured};
      return true;
    }
    // Other blocks (name resolution, statistics, custom): not needed here.
  }
  if (offset_ != bytes_.size()) malformed(offset_, "the file ends inside a block header");
  return false;
}

}  // namespace pmlsm::ethercat

#include "pmlsm/ethercat/pcapng.hpp"

#include <array>
#include <cstring>
#include <stdexcept>

namespace pmlsm::ethercat {

namespace {

// pcapng (draft-ietf-opsawg-pcapng): blocks of type, total length, body, total length again,
// each a multiple of 4 bytes, in the writer's byte order (the section header's magic says which).
constexpr std::uint32_t kSectionHeaderBlock = 0x0A0D0D0A;
constexpr std::uint32_t kByteOrderMagic = 0x1A2B3C4D;
constexpr std::uint32_t kInterfaceDescriptionBlock = 1;
constexpr std::uint32_t kEnhancedPacketBlock = 6;
constexpr std::uint16_t kLinkTypeEthernet = 1;
constexpr std::uint16_t kOptionTimestampResolution = 9;  ///< if_tsresol: 9 = nanoseconds

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

}  // namespace pmlsm::ethercat

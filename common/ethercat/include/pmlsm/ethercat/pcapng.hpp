// Frames as a pcapng capture, as Wireshark and tshark read it: written (one Ethernet interface,
// nanosecond timestamps; what `--capture` writes and the tests hand to tshark) and read (any
// capture of either byte order, several sections and interfaces: what `pmlsm ethercat pcap`
// decodes, a real drive's captures among them).
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "pmlsm/ethercat/frame.hpp"

namespace pmlsm::ethercat {

class PcapngWriter {
 public:
  /// Creates (truncates) `path` and writes the section and interface headers.
  /// @throws std::runtime_error naming the path when it cannot be written.
  explicit PcapngWriter(const std::string& path);
  /// One Ethernet frame, at `time_ns` (since the epoch, or any origin).
  /// @throws std::runtime_error when the write fails.
  void write(Bytes ethernet_frame, std::int64_t time_ns);
  /// Flushes what is written. @throws std::runtime_error when it fails.
  void flush();
  std::uint64_t frames() const { return frames_; }

 private:
  struct FileCloser {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  void put(const void* bytes, std::size_t size);
  std::string path_;
  std::unique_ptr<std::FILE, FileCloser> file_;
  std::uint64_t frames_ = 0;
};

/// A packet of a capture; `data` points into the reader's copy of the file.
struct CapturedFrame {
  std::uint64_t number = 0;          ///< 1 for the first packet, as Wireshark counts
  std::int64_t time_ns = 0;          ///< since the epoch (the interface's resolution, in ns)
  std::uint16_t link_type = 0;       ///< 1: Ethernet
  std::uint32_t original_bytes = 0;  ///< on the wire (data may be cut at the snap length)
  Bytes data;
};

inline constexpr std::uint16_t kLinkTypeEthernet = 1;

class PcapngReader {
 public:
  /// Reads `path` whole (captures are small) and checks its first section header.
  /// @throws std::runtime_error naming the path when it cannot be read or is no pcapng capture.
  explicit PcapngReader(const std::string& path);
  /// The same over bytes in memory; `name` stands for the path in messages.
  PcapngReader(std::vector<std::uint8_t> bytes, std::string name);
  /// The next packet (enhanced or simple packet block; others skipped); false at the end.
  /// @throws std::runtime_error naming the path and the block's offset when a block is malformed
  /// (a length past the end or not a multiple of 4, a packet on an interface not described).
  bool next(CapturedFrame& frame);

 private:
  struct Interface {
    std::uint16_t link_type = 0;
    std::uint32_t snap_length = 0;
    /// Timestamp units: 10^-exponent s, or 2^-exponent s when binary.
    std::uint8_t exponent = 6;
    bool binary = false;
  };
  void check_start() const;
  std::uint32_t u32(std::size_t at) const;
  std::uint16_t u16(std::size_t at) const;
  [[noreturn]] void malformed(std::size_t at, const std::string& what) const;
  void read_section_header(std::size_t at, std::size_t length);
  void read_interface(std::size_t at, std::size_t length);
  std::int64_t to_ns(const Interface& interface, std::uint64_t units) const;

  std::string path_;
  std::vector<std::uint8_t> bytes_;
  std::size_t offset_ = 0;
  bool swapped_ = false;  ///< the section was written in the other byte order
  std::vector<Interface> interfaces_;
  std::uint64_t packets_ = 0;
};

}  // namespace pmlsm::ethercat

// Frames written as a pcapng capture (one Ethernet interface, nanosecond timestamps), as Wireshark
// and tshark read it: what `pmlsm ethercat pcap` writes and what the tests hand to tshark.
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

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

}  // namespace pmlsm::ethercat

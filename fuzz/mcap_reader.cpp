// The MCAP reader (mcap::read, behind `pmlsm play` and `plot`). It reads a path with pread, so
// the input goes into an in-memory file (memfd) read through /proc/self/fd. Content never throws
// (problems go into the report); the callbacks touch every byte they are given.
#include <sys/mman.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>

#include "fuzz_support.hpp"
#include "pmlsm/mcap/mcap.hpp"

namespace pmlsm::fuzz::mcap_reader {

namespace {

class MemoryFile {
 public:
  MemoryFile() : fd_(::memfd_create("fuzz_mcap", MFD_CLOEXEC)) {
    if (fd_ < 0) {
      std::perror("memfd_create");
      std::abort();
    }
    path_ = "/proc/self/fd/" + std::to_string(fd_);
  }
  ~MemoryFile() { ::close(fd_); }
  MemoryFile(const MemoryFile&) = delete;
  MemoryFile& operator=(const MemoryFile&) = delete;

  const std::string& hold(const std::uint8_t* data, std::size_t size) {
    if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, data, size, 0) != static_cast<ssize_t>(size)) {
      std::perror("fuzz_mcap write");
      std::abort();
    }
    return path_;
  }

 private:
  int fd_;
  std::string path_;
};

}  // namespace

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  static MemoryFile file;
  std::uint64_t sum = 0;
  mcap::ReadCallbacks callbacks;
  callbacks.on_schema = [&](const mcap::Schema& schema) { sum += schema.data.size() + schema.name.size(); };
  callbacks.on_channel = [&](const mcap::Channel& channel) { sum += channel.topic.size() + channel.metadata.size(); };
  callbacks.on_message = [&](const mcap::Message& message) {
    for (std::size_t i = 0; i < message.size; ++i) sum += message.data[i];
  };
  const mcap::ReadReport report = mcap::read(file.hold(data, size), callbacks);
  sum += report.messages + report.problems.size();
  // An empty asm that takes `sum` keeps it, and so the reads behind it, from being optimised away.
  __asm__ volatile("" : : "r"(sum) : "memory");
  return 0;
}

}  // namespace pmlsm::fuzz::mcap_reader

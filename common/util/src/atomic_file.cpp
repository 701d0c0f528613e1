#include "pmlsm/util/atomic_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

namespace pmlsm {
namespace {

[[noreturn]] void fail(const std::string& what, int error) {
  throw AtomicWriteError(what + ": " + std::strerror(error));
}

/// Removes the temporary file and fails with the errno of the step that failed.
[[noreturn]] void fail_and_remove(const std::string& temporary, const std::string& what) {
  const int error = errno;
  ::unlink(temporary.c_str());
  fail(what, error);
}

}  // namespace

void write_file_atomically(const std::string& path, std::string_view contents, unsigned mode) {
  const std::string temporary = path + ".tmp";
  // A temporary file left by a crash would keep its old mode through O_CREAT: start afresh, so a
  // private key's file is 0600 from its first byte.
  ::unlink(temporary.c_str());
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, static_cast<mode_t>(mode));
  if (fd < 0) fail("cannot create '" + temporary + "'", errno);
  const char* data = contents.data();
  std::size_t left = contents.size();
  while (left > 0) {
    const ssize_t written = ::write(fd, data, left);
    if (written < 0 && errno == EINTR) continue;
    if (written <= 0) {
      const int error = written < 0 ? errno : EIO;
      ::close(fd);
      errno = error;
      fail_and_remove(temporary, "cannot write '" + temporary + "'");
    }
    data += written;
    left -= static_cast<std::size_t>(written);
  }
  if (::fsync(fd) != 0) {
    const int error = errno;
    ::close(fd);
    errno = error;
    fail_and_remove(temporary, "cannot flush '" + temporary + "'");
  }
  if (::close(fd) != 0) fail_and_remove(temporary, "cannot close '" + temporary + "'");
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    fail_and_remove(temporary, "cannot rename '" + temporary + "' over '" + path + "'");
  }
  const auto slash = path.find_last_of('/');
  const std::string directory = slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
  const int dir_fd = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir_fd >= 0) {
    (void)::fsync(dir_fd);
    ::close(dir_fd);
  }
}

std::string missing_folder_of(const std::string& path) {
  std::error_code ec;
  const std::filesystem::path folder = std::filesystem::absolute(path, ec).parent_path();
  if (!ec && std::filesystem::is_directory(folder, ec)) return "";
  return "no folder " + folder.string() + " to write it in";
}

}  // namespace pmlsm

// Writing a file so that a crash leaves either the old or the new contents,
// never a mix: the one copy used by checkpoints, weights files and traces.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>

namespace pmlsm {

/// Why write_file_atomically failed: "cannot create '<path>.tmp'", "cannot write ...",
/// "cannot flush ...", "cannot rename ..." followed by ": <strerror>". The target is unchanged.
class AtomicWriteError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Writes path + ".tmp", fsyncs it, renames it over `path` and fsyncs the
/// directory (best effort: some file systems refuse that), so that `path`
/// holds the old or the new contents after a crash or power cut. Without the
/// fsync before the rename a crash may leave the new name on empty contents.
/// The temporary file is removed on every failure. Mode `mode` (0644 by default, before umask;
/// a private key's 0600 is set on the temporary file before anything is written to it).
/// @throws AtomicWriteError naming what failed, the file and errno's text.
void write_file_atomically(const std::string& path, std::string_view contents, unsigned mode = 0644);

/// Checked before a long run or a measurement that ends by writing `path`: "" when its folder is
/// there, else "no folder <folder> to write it in" (the caller names the option and throws its own
/// kind of error).
std::string missing_folder_of(const std::string& path);

}  // namespace pmlsm

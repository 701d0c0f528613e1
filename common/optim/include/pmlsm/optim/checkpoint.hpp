// Checkpoint plumbing shared by differential_evolution.cpp and
// pagmo_optimisers.cpp; not an API.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace pmlsm {
namespace detail {

/// First line of every checkpoint file: "<tag> <version>".
inline constexpr const char* kCheckpointTag = "pmlsm-optimiser-checkpoint";
inline constexpr std::uint64_t kCheckpointVersion = 1;

/// Writes the file with pmlsm::write_file_atomically (path + ".tmp", fsync, rename
/// over path, fsync of the directory), so that path holds either the old or the
/// new contents after a crash.
/// @throws std::runtime_error "checkpoint '<path>': <what failed>: <strerror>".
void write_checkpoint_atomically(const std::string& path, const std::string& contents);

/// 17 significant digits ("%.17g"): reads back (strtod) to the same double; "inf", "nan" for non-finite.
std::string format_exact(double value);

/// Line-oriented reader of a checkpoint text file. Every error is a
/// std::runtime_error "checkpoint '<path>': <what> (line N)".
class CheckpointReader {
 public:
  /// Reads the whole file. @throws if it cannot be opened or read.
  explicit CheckpointReader(std::string path);

  /// First two lines: "pmlsm-optimiser-checkpoint 1" and "optimiser <name>"; throws unless name == optimiser.
  void expect_header(const std::string& optimiser);
  /// Next line "<key> <tokens...>": the tokens after the key.
  std::vector<std::string> fields(const std::string& key);
  /// Next line "<key> <text>": everything after "<key> ".
  std::string text(const std::string& key);
  std::uint64_t count(const std::string& key);  // one unsigned decimal integer
  /// count(key), which must equal the optimiser's own value (population size, dimension).
  std::uint64_t matching_count(const std::string& key, std::uint64_t expected);
  double number(const std::string& key);  // one double
  /// Next line "member <index> <cost> <dimension components>", index checked; the cost is
  /// returned for the caller to check, the components go to `member`.
  double member(std::size_t index, std::size_t dimension, std::vector<double>& member);
  /// Next line "<key> <n doubles>".
  std::vector<double> numbers(const std::string& key, std::size_t n);
  /// Exactly n raw characters followed by a newline.
  std::string raw(std::size_t n);
  /// The line "end" and nothing after it.
  void expect_end();

  std::uint64_t parse_count(const std::string& token) const;
  double parse_number(const std::string& token) const;
  [[noreturn]] void fail(const std::string& what) const;
  const std::string& path() const { return path_; }

 private:
  std::string next_line(const std::string& expected);

  std::string path_;
  std::string contents_;
  std::size_t offset_ = 0;
  std::size_t line_number_ = 0;  // of the line last read
};

}  // namespace detail
}  // namespace pmlsm

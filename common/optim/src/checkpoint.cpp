#include "pmlsm/optim/checkpoint.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <ios>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "pmlsm/util/atomic_file.hpp"

namespace pmlsm {
namespace {

std::string checkpoint_prefix(const std::string& path) { return "checkpoint '" + path + "': "; }

[[noreturn]] void throw_system_error(const std::string& path, const std::string& what) {
  const int error = errno;
  throw std::runtime_error(checkpoint_prefix(path) + what + ": " + std::strerror(error));
}

}  // namespace

namespace detail {

void write_checkpoint_atomically(const std::string& path, const std::string& contents) {
  try {
    pmlsm::write_file_atomically(path, contents);
  } catch (const AtomicWriteError& e) {
    throw std::runtime_error(checkpoint_prefix(path) + e.what());
  }
}

std::string format_exact(double value) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.17g", value);
  return buffer;
}

CheckpointReader::CheckpointReader(std::string path) : path_(std::move(path)) {
  std::ifstream file(path_, std::ios::binary);
  if (!file) throw_system_error(path_, "cannot open");
  std::ostringstream contents;
  contents << file.rdbuf();
  if (file.bad()) throw_system_error(path_, "cannot read");
  contents_ = contents.str();
}

void CheckpointReader::fail(const std::string& what) const {
  throw std::runtime_error(checkpoint_prefix(path_) + what + " (line " + std::to_string(line_number_) + ")");
}

std::string CheckpointReader::next_line(const std::string& expected) {
  ++line_number_;
  const auto newline = contents_.find('\n', offset_);
  // Every line we write ends in '\n': a missing one means the file was cut short.
  if (newline == std::string::npos) fail("truncated: expected '" + expected + "'");
  std::string line = contents_.substr(offset_, newline - offset_);
  offset_ = newline + 1;
  return line;
}

void CheckpointReader::expect_header(const std::string& optimiser) {
  {
    std::istringstream line(next_line(kCheckpointTag));
    std::string tag, version, extra;
    line >> tag >> version;
    if (tag != kCheckpointTag || line.fail() || (line >> extra)) {
      fail(std::string("not an optimiser checkpoint (first line must be '") + kCheckpointTag + " " +
           std::to_string(kCheckpointVersion) + "')");
    }
    if (version != std::to_string(kCheckpointVersion)) fail("unsupported format version " + version);
  }
  const std::string written_by = text("optimiser");
  if (written_by != optimiser) fail("written by " + written_by + ", not by " + optimiser);
}

std::string CheckpointReader::text(const std::string& key) {
  const std::string line = next_line(key);
  if (line.compare(0, key.size() + 1, key + " ") != 0) {
    fail("corrupt: expected '" + key + "', got '" + line.substr(0, 40) + "'");
  }
  return line.substr(key.size() + 1);
}

std::vector<std::string> CheckpointReader::fields(const std::string& key) {
  std::istringstream line(text(key));
  std::vector<std::string> tokens;
  for (std::string token; line >> token;) tokens.push_back(token);
  return tokens;
}

std::uint64_t CheckpointReader::parse_count(const std::string& token) const {
  if (token.empty() || token.find_first_not_of("0123456789") != std::string::npos) {
    fail("corrupt: '" + token + "' is not an unsigned integer");
  }
  errno = 0;
  const unsigned long long value = std::strtoull(token.c_str(), nullptr, 10);
  if (errno == ERANGE) fail("corrupt: '" + token + "' is out of range");
  return value;
}

double CheckpointReader::parse_number(const std::string& token) const {
  char* end = nullptr;
  const double value = std::strtod(token.c_str(), &end);
  if (token.empty() || end != token.c_str() + token.size()) fail("corrupt: '" + token + "' is not a number");
  return value;
}

std::uint64_t CheckpointReader::count(const std::string& key) {
  const auto tokens = fields(key);
  if (tokens.size() != 1) fail("corrupt: expected one value after '" + key + "'");
  return parse_count(tokens[0]);
}

std::uint64_t CheckpointReader::matching_count(const std::string& key, std::uint64_t expected) {
  const std::uint64_t value = count(key);
  if (value != expected) {
    fail(key + " " + std::to_string(value) + " does not match the optimiser's " + std::to_string(expected));
  }
  return value;
}

double CheckpointReader::number(const std::string& key) {
  const auto tokens = fields(key);
  if (tokens.size() != 1) fail("corrupt: expected one value after '" + key + "'");
  return parse_number(tokens[0]);
}

double CheckpointReader::member(std::size_t index, std::size_t dimension, std::vector<double>& member) {
  const auto tokens = fields("member");
  if (tokens.size() != dimension + 2) {
    fail("member line has " + std::to_string(tokens.size()) + " fields, expected index, cost and " +
         std::to_string(dimension) + " components");
  }
  if (parse_count(tokens[0]) != index) fail("expected member " + std::to_string(index));
  member.resize(dimension);
  for (std::size_t j = 0; j < dimension; ++j) member[j] = parse_number(tokens[j + 2]);
  return parse_number(tokens[1]);
}

std::vector<double> CheckpointReader::numbers(const std::string& key, std::size_t n) {
  const auto tokens = fields(key);
  if (tokens.size() != n) {
    fail("corrupt: expected " + std::to_string(n) + " values after '" + key + "', got " +
         std::to_string(tokens.size()));
  }
  std::vector<double> values;
  values.reserve(n);
  for (const auto& token : tokens) values.push_back(parse_number(token));
  return values;
}

std::string CheckpointReader::raw(std::size_t n) {
  ++line_number_;
  if (contents_.size() - offset_ < n + 1) fail("truncated inside a block of " + std::to_string(n) + " characters");
  if (contents_[offset_ + n] != '\n') fail("corrupt: block of " + std::to_string(n) + " characters not terminated");
  std::string block = contents_.substr(offset_, n);
  line_number_ += static_cast<std::size_t>(std::count(block.begin(), block.end(), '\n'));
  offset_ += n + 1;
  return block;
}

void CheckpointReader::expect_end() {
  const std::string line = next_line("end");
  if (line != "end") fail("corrupt: expected 'end', got '" + line.substr(0, 40) + "'");
  if (offset_ != contents_.size()) fail("corrupt: data after 'end'");
}

}  // namespace detail
}  // namespace pmlsm

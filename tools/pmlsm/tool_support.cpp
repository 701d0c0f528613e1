#include "tool_support.hpp"

#include <spawn.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <stdexcept>

extern char** environ;

namespace pmlsm::tools {

std::uint64_t SequenceTracker::observe(const std::string& writer_key, std::uint64_t sequence_number) {
  auto [it, first] = last_.try_emplace(writer_key, sequence_number);
  if (first) {
    if (sequence_number > 1) missed_before_join_ += sequence_number - 1;
    return 0;
  }
  const std::uint64_t expected = it->second + 1;
  if (sequence_number < expected) {
    ++out_of_order_;  // a repeat or an old one: not a loss, and the high-water mark stays
    return 0;
  }
  const std::uint64_t gap = sequence_number - expected;
  lost_ += gap;
  it->second = sequence_number;
  return gap;
}

RollingWindow::RollingWindow(std::size_t capacity) : capacity_(capacity) {
  if (capacity == 0) throw std::invalid_argument("RollingWindow: capacity 0");
  values_.reserve(capacity);
}

void RollingWindow::add(double value) {
  if (values_.size() < capacity_) {
    values_.push_back(value);
    return;
  }
  values_[next_slot_] = value;
  next_slot_ = (next_slot_ + 1) % capacity_;
}

Summary summarize(std::vector<double> values) {
  Summary s;
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  s.count = values.size();
  s.min = values.front();
  s.max = values.back();
  s.mean = std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(s.count);
  double sq = 0.0;
  for (double v : values) sq += (v - s.mean) * (v - s.mean);
  s.stddev = std::sqrt(sq / static_cast<double>(s.count));
  // Nearest rank: the smallest value with at least p of the samples at or below it.
  const auto rank = [&](double p) {
    const auto r = static_cast<std::size_t>(std::ceil(p * static_cast<double>(s.count)));
    return values[std::min(s.count, std::max<std::size_t>(r, 1)) - 1];
  };
  s.p50 = rank(0.50);
  s.p99 = rank(0.99);
  return s;
}

std::string human_bytes(double bytes) {
  const char* units[] = {"B", "kB", "MB", "GB", "TB"};
  int unit = 0;
  while (bytes >= 1000.0 && unit < 4) {
    bytes /= 1000.0;
    ++unit;
  }
  char text[32];
  std::snprintf(text, sizeof text, unit == 0 ? "%.0f %s" : "%.2f %s", bytes, units[unit]);
  return text;
}

std::optional<std::uint64_t> stamp_run_id(const std::vector<std::uint8_t>& cdr) {
  constexpr std::size_t kHeader = 4, kOffset = kHeader + 24;
  if (cdr.size() < kOffset + 8 || cdr[0] != 0x00 || cdr[1] > 0x01) return std::nullopt;  // CDR_BE 0x0000, CDR_LE 0x0001
  const bool little_endian = cdr[1] == 0x01;
  std::uint64_t value = 0;
  for (std::size_t i = 0; i < 8; ++i) {
    const std::uint64_t byte = cdr[kOffset + (little_endian ? i : 7 - i)];
    value |= byte << (8 * i);
  }
  return value;
}

int run_gnuplot(const std::filesystem::path& script) {
  const std::string gnuplot = "gnuplot";
  const std::string script_path = script.string();
  char* argv[] = {const_cast<char*>(gnuplot.c_str()), const_cast<char*>(script_path.c_str()), nullptr};
  pid_t pid = 0;
  if (posix_spawnp(&pid, "gnuplot", nullptr, nullptr, argv, environ) != 0) {
    throw std::runtime_error("cannot run gnuplot (Debian package gnuplot-nox)");
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 1;
}

}  // namespace pmlsm::tools

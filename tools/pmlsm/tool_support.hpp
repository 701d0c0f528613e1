// Pure helpers of the `pmlsm` tool (no DDS): loss accounting by writer sequence numbers, and
// summary statistics of intervals and latencies. Tested in tests/tools.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace pmlsm::tools {

/// Counts samples lost between a writer and us from the writer's sequence numbers (1, 2, ...
/// per writer in DDS). A reliable writer delivers every sequence number unless our reader's
/// history overflowed, so each gap is a loss. A writer first seen above sequence 1 was already
/// publishing when we joined: those are counted apart, as before the recording, not as lost.
class SequenceTracker {
 public:
  /// @return how many samples this one shows lost (0 for the next expected or a first one).
  std::uint64_t observe(const std::string& writer_key, std::uint64_t sequence_number);
  std::uint64_t lost() const { return lost_; }
  std::uint64_t missed_before_join() const { return missed_before_join_; }
  std::uint64_t out_of_order() const { return out_of_order_; }
  std::size_t writers() const { return last_.size(); }

 private:
  std::map<std::string, std::uint64_t> last_;
  std::uint64_t lost_ = 0;
  std::uint64_t missed_before_join_ = 0;
  std::uint64_t out_of_order_ = 0;
};

struct Summary {
  std::size_t count = 0;
  double mean = 0.0;
  double stddev = 0.0;  // population standard deviation
  double min = 0.0;
  double max = 0.0;
  double p50 = 0.0;
  double p99 = 0.0;
};

/// The last `capacity` values added (oldest overwritten): the window of hz and delay.
class RollingWindow {
 public:
  /// @throws std::invalid_argument for a capacity of 0.
  explicit RollingWindow(std::size_t capacity);
  void add(double value);
  /// In no particular order once full (the statistics do not need it).
  const std::vector<double>& values() const { return values_; }

 private:
  std::size_t capacity_;
  std::size_t next_slot_ = 0;
  std::vector<double> values_;
};

/// Summary of `values` (nearest-rank percentiles); all zero when empty.
Summary summarize(std::vector<double> values);

/// Stamp.run_id of a serialized project message (every type starts with its Stamp: tick,
/// sim_time_ns, source_time_ns, run_id, 8 bytes each after the 4-byte encapsulation header, in
/// the header's byte order); nullopt for a sample too short or not plain CDR.
std::optional<std::uint64_t> stamp_run_id(const std::vector<std::uint8_t>& cdr);

/// "12.3 kB", "4.56 MB": sizes as people read them.
std::string human_bytes(double bytes);

/// Runs `gnuplot SCRIPT` and returns its exit code.
/// @throws std::runtime_error when gnuplot cannot be started (Debian package gnuplot-nox).
int run_gnuplot(const std::filesystem::path& script);

}  // namespace pmlsm::tools

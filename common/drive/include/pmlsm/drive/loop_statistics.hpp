// What a drive loop measures about itself: chain latency (feedback published -> its command
// received) percentiles, the tick period as a least-squares fit of tick start times against
// the tick index (absolute-time pacing must show no drift; single late ticks barely move it),
// deadline misses. Pure; storage reserved up front, so record_*() never allocates.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace pmlsm::drive {

struct LatencySummary {
  std::size_t count = 0;
  double p50_us = 0, p99_us = 0, max_us = 0;
};

class LoopStatistics {
 public:
  /// Room for `expected_ticks` latencies (more are counted but not kept).
  explicit LoopStatistics(std::size_t expected_ticks);

  /// Tick k started at `start_ns` (any monotonic origin).
  void record_tick_start(std::uint64_t tick, std::int64_t start_ns);
  void record_latency_ns(std::int64_t latency_ns);
  void record_deadline_miss() { ++deadline_misses_; }

  /// Percentiles over the kept latencies (sorts them: call at the end, not in the loop).
  LatencySummary latency();
  /// The least-squares slope of start time against tick index [s]; 0 with fewer than 2 ticks.
  double mean_period_s() const;
  std::uint64_t ticks() const { return ticks_; }
  std::uint64_t deadline_misses() const { return deadline_misses_; }
  std::uint64_t latencies_dropped() const { return latencies_dropped_; }

 private:
  std::vector<double> latency_us_;
  std::uint64_t latencies_dropped_ = 0;
  std::uint64_t ticks_ = 0;
  std::uint64_t deadline_misses_ = 0;
  bool any_start_ = false;
  std::int64_t first_start_ns_ = 0;
  double sum_k_ = 0, sum_t_ = 0, sum_kk_ = 0, sum_kt_ = 0;
};

}  // namespace pmlsm::drive

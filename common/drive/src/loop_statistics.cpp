#include "pmlsm/drive/loop_statistics.hpp"

#include <algorithm>

namespace pmlsm::drive {

LoopStatistics::LoopStatistics(std::size_t expected_ticks) { latency_us_.reserve(expected_ticks); }

void LoopStatistics::record_tick_start(std::uint64_t tick, std::int64_t start_ns) {
  if (!any_start_) {
    any_start_ = true;
    first_start_ns_ = start_ns;
  }
  const double k = static_cast<double>(tick);
  const double t = static_cast<double>(start_ns - first_start_ns_) * 1e-9;
  sum_k_ += k;
  sum_t_ += t;
  sum_kk_ += k * k;
  sum_kt_ += k * t;
  ++ticks_;
}

void LoopStatistics::record_latency_ns(std::int64_t latency_ns) {
  if (latency_us_.size() == latency_us_.capacity()) {
    ++latencies_dropped_;
    return;
  }
  latency_us_.push_back(static_cast<double>(latency_ns) * 1e-3);
}

LatencySummary LoopStatistics::latency() {
  LatencySummary s;
  s.count = latency_us_.size();
  if (latency_us_.empty()) return s;
  std::sort(latency_us_.begin(), latency_us_.end());
  const auto at = [&](double q) {
    return latency_us_[static_cast<std::size_t>(q * static_cast<double>(latency_us_.size() - 1))];
  };
  s.p50_us = at(0.5);
  s.p99_us = at(0.99);
  s.max_us = latency_us_.back();
  return s;
}

double LoopStatistics::mean_period_s() const {
  if (ticks_ < 2) return 0.0;
  const double n = static_cast<double>(ticks_);
  const double den = n * sum_kk_ - sum_k_ * sum_k_;
  return den == 0.0 ? 0.0 : (n * sum_kt_ - sum_k_ * sum_t_) / den;
}

}  // namespace pmlsm::drive

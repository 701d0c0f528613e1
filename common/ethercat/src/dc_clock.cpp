#include "pmlsm/ethercat/dc_clock.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace pmlsm::ethercat {

namespace {
constexpr double kMaxCorrection = 1000e-6;
constexpr std::int64_t kStepBeyondNs = 1'000'000;
constexpr double kProportionalPerPeriod = 0.1;
constexpr double kIntegralPerPeriod = 0.005;
}  // namespace

void DcClockParams::validate() const {
  if (!(std::fabs(drift_ppm) <= 1000.0)) {
    throw std::invalid_argument("drift_ppm: within +-1000, got " + std::to_string(drift_ppm));
  }
  if (write_period_ns <= 0) {
    throw std::invalid_argument("write_period_ns: must be > 0, got " + std::to_string(write_period_ns));
  }
}

DcClock::DcClock(DcClockParams params) : params_((params.validate(), params)), local_ns_(params.start_local_ns) {}

void DcClock::set_drift_ppm(double drift_ppm) {
  DcClockParams p = params_;
  p.drift_ppm = drift_ppm;
  p.validate();
  params_ = p;
}

void DcClock::advance_to(std::int64_t now_ns) noexcept {
  if (!started_) {
    started_ = true;
    last_now_ns_ = now_ns;
    return;
  }
  if (now_ns <= last_now_ns_) return;
  const double rate = 1.0 + params_.drift_ppm * 1e-6 + correction_;
  const double passed = static_cast<double>(now_ns - last_now_ns_) * rate + fraction_ns_;
  const double whole = std::floor(passed);
  local_ns_ += static_cast<std::uint64_t>(whole);
  fraction_ns_ = passed - whole;
  last_now_ns_ = now_ns;
}

void DcClock::on_system_time_written(std::uint64_t received_ns) noexcept {
  ++writes_;
  const auto error = static_cast<std::int64_t>(received_ns + delay_ns_ - system_time_ns());
  if (error > kStepBeyondNs || error < -kStepBeyondNs) {
    // Another time base: taken at once (the offset moves), the loop starts again from there.
    offset_ns_ += static_cast<std::uint64_t>(error);
    integral_ = 0.0;
    correction_ = 0.0;
    difference_ns_ = 0;
    return;
  }
  // The filter of 0x092C: a mean over about 16 writes.
  difference_ns_ += (error - difference_ns_) / 16;
  const double period = static_cast<double>(params_.write_period_ns);
  const auto filtered = static_cast<double>(difference_ns_);
  integral_ = std::clamp(integral_ + kIntegralPerPeriod * filtered / period, -kMaxCorrection, kMaxCorrection);
  correction_ = std::clamp(integral_ + kProportionalPerPeriod * filtered / period, -kMaxCorrection, kMaxCorrection);
}

}  // namespace pmlsm::ethercat

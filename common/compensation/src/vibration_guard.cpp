#include "pmlsm/compensation/vibration_guard.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

void VibrationGuardParams::validate() const {
  require_positive("control_period_s", control_period_s);
  require_positive("highpass_hz", highpass_hz);
  if (!(highpass_hz < 0.5 / control_period_s)) {
    throw std::invalid_argument("highpass_hz: must be below the Nyquist frequency " +
                                format_value(0.5 / control_period_s) + " Hz, got " + format_value(highpass_hz));
  }
  require_positive("window_s", window_s);
  if (window_s < 2.0 * control_period_s) {
    throw std::invalid_argument("window_s: must be at least two periods (" + format_value(2.0 * control_period_s) +
                                " s), got " + format_value(window_s));
  }
  require_positive("min_oscillation_mps", min_oscillation_mps);
  require_finite("growth_ratio", growth_ratio);
  if (!(growth_ratio > 1.0)) {
    throw std::invalid_argument("growth_ratio: must be > 1, got " + format_value(growth_ratio));
  }
  require_finite("min_decay", min_decay);
  if (!(min_decay > 0.0 && min_decay < 1.0)) {
    throw std::invalid_argument("min_decay: must be in (0, 1), got " + format_value(min_decay));
  }
  if (windows_to_trip < 1) throw std::invalid_argument("windows_to_trip: must be >= 1, got 0");
  require_non_negative("fade_s", fade_s);
}

const char* to_string(VibrationGuardTrip trip) noexcept {
  switch (trip) {
    case VibrationGuardTrip::kNone: return "none";
    case VibrationGuardTrip::kSustained: return "the oscillation did not decay (a limit cycle)";
    case VibrationGuardTrip::kGrowing: return "the oscillation grew";
  }
  return "unknown";
}

namespace {
const VibrationGuardParams& validated(const VibrationGuardParams& p) {
  p.validate();
  return p;
}
}  // namespace

VibrationGuard::VibrationGuard(const VibrationGuardParams& params)
    : params_(validated(params)),
      // y_k = a (y_{k-1} + x_k - x_{k-1}), a = RC / (RC + T), RC = 1 / (2 pi f_c): a first-order high-pass section.
      alpha_(1.0 / (1.0 + 2.0 * M_PI * params.highpass_hz * params.control_period_s)),
      window_steps_(static_cast<std::uint32_t>(std::lround(params.window_s / params.control_period_s))),
      fade_steps_(static_cast<std::uint32_t>(std::lround(params.fade_s / params.control_period_s))) {}

void VibrationGuard::reset() noexcept {
  const VibrationGuardCounters kept = counters_;
  *this = VibrationGuard(params_);
  counters_.steps = kept.steps;
  counters_.rejected_inputs = kept.rejected_inputs;
  counters_.windows = kept.windows;
}

VibrationGuardOutput VibrationGuard::step(double motor_velocity_mps, double compensation_force_n) noexcept {
  ++counters_.steps;
  if (!std::isfinite(motor_velocity_mps) || !std::isfinite(compensation_force_n)) {
    ++counters_.rejected_inputs;
    motor_velocity_mps = std::isfinite(motor_velocity_mps) ? motor_velocity_mps : v_prev_;
    compensation_force_n = std::isfinite(compensation_force_n) ? compensation_force_n : f_prev_;
  }
  if (!primed_) {
    primed_ = true;
    v_prev_ = motor_velocity_mps;
    f_prev_ = compensation_force_n;
  }
  // Two first-order sections: 40 dB a decade below f_c, so tracking motion (a few Hz at most)
  // stays out of the window while the load's resonance (5-25 Hz here) passes.
  const double v1 = alpha_ * (v_hp1_ + motor_velocity_mps - v_prev_);
  const double f1 = alpha_ * (f_hp1_ + compensation_force_n - f_prev_);
  v_hp_ = alpha_ * (v_hp_ + v1 - v_hp1_);
  f_hp_ = alpha_ * (f_hp_ + f1 - f_hp1_);
  v_hp1_ = v1;
  f_hp1_ = f1;
  v_prev_ = motor_velocity_mps;
  f_prev_ = compensation_force_n;

  sum_v2_ += v_hp_ * v_hp_;
  sum_f2_ += f_hp_ * f_hp_;
  if (++in_window_ >= window_steps_) {
    const double n = static_cast<double>(in_window_);
    const double amplitude = std::sqrt(sum_v2_ / n);
    ++counters_.windows;
    counters_.last_amplitude_mps = amplitude;
    counters_.last_force_rms_n = std::sqrt(sum_f2_ / n);
    // Only a window in which some compensation acted can blame it (PI alone is not guarded).
    const bool oscillating = amplitude > params_.min_oscillation_mps && counters_.last_force_rms_n > 0.0;
    sustained_run_ = oscillating && previous_amplitude_ > 0.0 && amplitude > (1.0 - params_.min_decay) * previous_amplitude_
                         ? sustained_run_ + 1
                         : 0;
    growing_run_ = oscillating && previous_amplitude_ > 0.0 && amplitude > params_.growth_ratio * previous_amplitude_
                       ? growing_run_ + 1
                       : 0;
    previous_amplitude_ = amplitude;
    in_window_ = 0;
    sum_v2_ = sum_f2_ = 0;
    if (!out_.tripped && (sustained_run_ >= params_.windows_to_trip || growing_run_ >= params_.windows_to_trip)) {
      out_.tripped = true;
      out_.reason = growing_run_ >= params_.windows_to_trip ? VibrationGuardTrip::kGrowing : VibrationGuardTrip::kSustained;
      counters_.trip_tick = counters_.steps;
    }
  }
  if (out_.tripped) {
    if (faded_ < fade_steps_) ++faded_;
    out_.scale = fade_steps_ == 0 ? 0.0 : std::max(0.0, 1.0 - static_cast<double>(faded_) / fade_steps_);
  }
  return out_;
}

}  // namespace pmlsm

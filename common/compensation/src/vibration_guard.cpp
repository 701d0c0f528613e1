#include "pmlsm/compensation/vibration_guard.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

void VibrationGuardParams::validate() const {
  check_declared_ranges(*this);
  require_positive("control_period_s", control_period_s);
  if (!(highpass_hz < 0.5 / control_period_s)) {
    throw std::invalid_argument("highpass_hz: must be below the Nyquist frequency " +
                                format_value(0.5 / control_period_s) + " Hz, got " + format_value(highpass_hz));
  }
  require_window("window_s", window_s, control_period_s);
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
      fade_steps_(static_cast<std::uint32_t>(std::lround(params.fade_s / params.control_period_s))),
      lag_steps_(std::clamp<std::size_t>(
          static_cast<std::size_t>(std::lround(kQuadratureLag_s / params.control_period_s)), 1, kMaxLagSteps)) {}

void VibrationGuard::reset() noexcept {
  const VibrationGuardCounters kept = counters_;
  *this = VibrationGuard(params_);
  counters_.steps = kept.steps;
  counters_.rejected_inputs = kept.rejected_inputs;
  counters_.windows = kept.windows;
}

double VibrationGuard::unforced_amplitude_mps(double n) const noexcept {
  // e~'e~ less the part the fit explains, (b0, b1) . (e~'r~, e~'r~_lag), from the 2 x 2 normal
  // equations; copies too alike to tell apart (a reference at rest, or one lag's worth of a
  // very slow one) leave one regressor, no reference none.
  double explained = 0;
  const double det = sum_rr_ * sum_ll_ - sum_rl_ * sum_rl_;
  if (det > 1e-9 * sum_rr_ * sum_ll_ && det > 0.0) {
    const double b0 = (sum_ll_ * sum_er_ - sum_rl_ * sum_el_) / det;
    const double b1 = (sum_rr_ * sum_el_ - sum_rl_ * sum_er_) / det;
    explained = b0 * sum_er_ + b1 * sum_el_;
  } else if (sum_rr_ > 0.0) {
    explained = sum_er_ * sum_er_ / sum_rr_;
  }
  const double left = std::isfinite(explained) ? std::clamp(sum_e2_ - explained, 0.0, sum_e2_) : sum_e2_;
  return std::sqrt(left / n);
}

double VibrationGuard::HighPass::step(double x, double alpha) noexcept {
  // Two first-order sections: 40 dB a decade below f_c, so tracking motion (a few Hz at most)
  // stays out of the window while the load's resonance (5-25 Hz here) passes.
  const double y1_new = alpha * (y1 + x - x_prev);
  y2 = alpha * (y2 + y1_new - y1);
  y1 = y1_new;
  x_prev = x;
  return y2;
}

VibrationGuardOutput VibrationGuard::step(const VibrationGuardInput& in) noexcept {
  ++counters_.steps;
  double error_mps = in.motor_velocity_mps - in.reference_velocity_mps;
  double reference_mps = in.reference_velocity_mps;
  double force_n = in.compensation_force_n;
  if (!std::isfinite(error_mps) || !std::isfinite(reference_mps) || !std::isfinite(force_n) ||
      !std::isfinite(in.compensation_output_share)) {
    ++counters_.rejected_inputs;
    error_mps = std::isfinite(error_mps) ? error_mps : e_prev_;
    reference_mps = std::isfinite(reference_mps) ? reference_mps : r_prev_;
    force_n = std::isfinite(force_n) ? force_n : f_prev_;
  }
  if (!primed_) {
    primed_ = true;
    error_hp_.x_prev = error_mps;
    reference_hp_.x_prev = reference_mps;
    force_hp_.x_prev = force_n;
  }
  e_prev_ = error_mps;
  r_prev_ = reference_mps;
  f_prev_ = force_n;
  const double e_hp = error_hp_.step(error_mps, alpha_);
  const double r_hp = reference_hp_.step(reference_mps, alpha_);
  const double f_hp = force_hp_.step(force_n, alpha_);

  // A non-finite share counts as not saturated: the window is then judged, never excused.
  if (std::fabs(in.compensation_output_share) >= params_.saturated_output_share) ++saturated_in_window_;
  sum_e2_ += e_hp * e_hp;
  sum_r2_ += r_hp * r_hp;
  sum_f2_ += f_hp * f_hp;
  const double r_lag = reference_lagged_[lag_at_];
  reference_lagged_[lag_at_] = r_hp;
  lag_at_ = (lag_at_ + 1) % lag_steps_;
  sum_rr_ += r_hp * r_hp;
  sum_rl_ += r_hp * r_lag;
  sum_ll_ += r_lag * r_lag;
  sum_er_ += e_hp * r_hp;
  sum_el_ += e_hp * r_lag;
  if (++in_window_ >= window_steps_) {
    const double n = static_cast<double>(in_window_);
    const double amplitude = std::sqrt(sum_e2_ / n);
    counters_.last_unforced_mps = unforced_amplitude_mps(n);
    ++counters_.windows;
    counters_.last_amplitude_mps = amplitude;
    counters_.last_reference_mps = std::sqrt(sum_r2_ / n);
    counters_.last_force_rms_n = std::sqrt(sum_f2_ / n);
    // Only a window in which some compensation acted can blame it (PI alone is not guarded), and
    // only one the reference's own motion does not explain.
    const bool oscillating = amplitude > params_.min_oscillation_mps && counters_.last_force_rms_n > 0.0 &&
                             counters_.last_unforced_mps > params_.max_reference_share * counters_.last_reference_mps;
    const bool saturated = static_cast<double>(saturated_in_window_) > params_.max_saturated_share * n;
    sustained_run_ = oscillating && !saturated && previous_amplitude_ > 0.0 &&
                             amplitude > (1.0 - params_.min_decay) * previous_amplitude_
                         ? sustained_run_ + 1
                         : 0;
    growing_run_ = oscillating && previous_amplitude_ > 0.0 && amplitude > params_.growth_ratio * previous_amplitude_
                       ? growing_run_ + 1
                       : 0;
    previous_amplitude_ = amplitude;
    in_window_ = 0;
    sum_e2_ = sum_r2_ = sum_f2_ = 0;
    sum_rr_ = sum_rl_ = sum_ll_ = sum_er_ = sum_el_ = 0;
    saturated_in_window_ = 0;
    if (!out_.tripped && (sustained_run_ >= params_.windows_to_trip || growing_run_ >= params_.windows_to_trip)) {
      out_.tripped = true;
      out_.reason =
          growing_run_ >= params_.windows_to_trip ? VibrationGuardTrip::kGrowing : VibrationGuardTrip::kSustained;
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

#include "pmlsm/compensation/standstill_gate.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

void StandstillGateParams::validate() const {
  check_declared_ranges(*this);
  require_positive("control_period_s", control_period_s);
  require_window("window_s", window_s, control_period_s);
  if (!(wake_velocity_mps > quiet_velocity_mps)) {
    throw std::invalid_argument("wake_velocity_mps: must be above quiet_velocity_mps (" +
                                format_value(quiet_velocity_mps) + " m/s), got " + format_value(wake_velocity_mps));
  }
  if (!(wake_load_swing_m > quiet_load_swing_m)) {
    throw std::invalid_argument("wake_load_swing_m: must be above quiet_load_swing_m (" +
                                format_value(quiet_load_swing_m) + " m), got " + format_value(wake_load_swing_m));
  }
  if (!(wake_accel_swing_m > quiet_accel_swing_m)) {
    throw std::invalid_argument("wake_accel_swing_m: must be above quiet_accel_swing_m (" +
                                format_value(quiet_accel_swing_m) + " m), got " + format_value(wake_accel_swing_m));
  }
  if ((stretch_gain_n_per_m > 0 || accel_stretch_gain_n_per_m > 0) &&
      !(load_period_s >= 2.0 * control_period_s && load_period_s <= StandstillGateParams::kMaxLoadPeriodS)) {
    throw std::invalid_argument(
        "load_period_s: the load's mode's period (the filter's model) must be two control "
        "periods to " +
        format_value(StandstillGateParams::kMaxLoadPeriodS) + " s for the push after the stretch, got " +
        format_value(load_period_s));
  }
}

StandstillGate::StandstillGate(const StandstillGateParams& params)
    : params_((params.validate(), params)),
      settle_steps_(static_cast<std::uint64_t>(std::llround(params.settle_s / params.control_period_s))),
      load_settle_steps_(static_cast<std::uint64_t>(std::llround(params.load_settle_s / params.control_period_s))),
      window_steps_(static_cast<std::uint32_t>(std::llround(params.window_s / params.control_period_s))),
      fade_per_step_(params.fade_s > 0 ? params.control_period_s / params.fade_s : 1.0),
      centre_ring_(params.stretch_gain_n_per_m > 0 || params.accel_stretch_gain_n_per_m > 0
                       ? static_cast<std::size_t>(std::llround(params.load_period_s / params.control_period_s))
                       : 0) {}

void StandstillGate::forget_stretch_centre() noexcept {
  centre_next_ = centre_filled_ = 0;
  centre_sum_m_ = 0;
}

double StandstillGate::stretch_push(const StandstillGateInput& in) noexcept {
  if (centre_ring_.empty()) return 0.0;
  if (in.stretch_from_accelerometer) {
    // The band-passed stretch has no offset: the ring only counts a whole period of readings.
    if (!std::isfinite(in.load_stretch_at_mode_m) || params_.accel_stretch_gain_n_per_m <= 0) {
      forget_stretch_centre();
      return 0.0;
    }
    centre_filled_ = std::min(centre_filled_ + 1, centre_ring_.size());
    if (centre_filled_ < centre_ring_.size() || !motor_held_) return 0.0;
    ++counters_.stretch_push_steps;
    return std::clamp(-params_.accel_stretch_gain_n_per_m * in.load_stretch_at_mode_m,
                      -params_.accel_stretch_force_max_n, params_.accel_stretch_force_max_n);
  }
  if (!std::isfinite(in.load_stretch_m) || params_.stretch_gain_n_per_m <= 0) {
    // The centre is a whole period of a load encoder's counts, or none.
    forget_stretch_centre();
    return 0.0;
  }
  if (centre_filled_ == centre_ring_.size()) centre_sum_m_ -= centre_ring_[centre_next_];
  centre_ring_[centre_next_] = in.load_stretch_m;
  centre_sum_m_ += in.load_stretch_m;
  centre_next_ = (centre_next_ + 1) % centre_ring_.size();
  centre_filled_ = std::min(centre_filled_ + 1, centre_ring_.size());
  if (centre_filled_ < centre_ring_.size() || !motor_held_) return 0.0;
  // load_stretch_m is x_M - x_L: the push is along x_L - x_M about the centre.
  const double centre_m = centre_sum_m_ / static_cast<double>(centre_ring_.size());
  ++counters_.stretch_push_steps;
  return std::clamp(params_.stretch_gain_n_per_m * (centre_m - in.load_stretch_m), -params_.stretch_force_max_n,
                    params_.stretch_force_max_n);
}

void StandstillGate::open(bool at_once) noexcept {
  if (out_.closed) ++counters_.openings;
  out_.closed = false;
  if (at_once) out_.scale = 1.0;
}

StandstillGateOutput StandstillGate::step(const StandstillGateInput& in) noexcept {
  ++counters_.steps;
  const bool finite = std::isfinite(in.command_mps) && std::isfinite(in.reference_velocity_mps) &&
                      std::isfinite(in.motor_velocity_mps) && std::isfinite(in.compensation_force_n);
  if (!finite) ++counters_.rejected_inputs;
  const bool reference_at_rest = finite && std::fabs(in.command_mps) <= params_.rest_velocity_mps &&
                                 std::fabs(in.reference_velocity_mps) <= params_.rest_velocity_mps;
  at_rest_steps_ = reference_at_rest ? at_rest_steps_ + 1 : 0;
  if (!reference_at_rest) {
    // A move (or a reading that cannot be trusted): the compensation from this tick on.
    open(true);
    in_window_ = closed_in_window_ = stretch_in_window_ = 0;
    sum_v2_ = sum_f2_ = 0;
    out_.stretch_force_n = 0;
    motor_held_ = false;
    forget_stretch_centre();
    return out_;
  }
  out_.stretch_force_n = stretch_push(in);
  sum_v2_ += in.motor_velocity_mps * in.motor_velocity_mps;
  if (std::isfinite(in.load_stretch_m)) {
    stretch_min_m_ = stretch_in_window_ == 0 ? in.load_stretch_m : std::min(stretch_min_m_, in.load_stretch_m);
    stretch_max_m_ = stretch_in_window_ == 0 ? in.load_stretch_m : std::max(stretch_max_m_, in.load_stretch_m);
    ++stretch_in_window_;
  }
  if (out_.closed && out_.scale == 0.0) {
    sum_f2_ += in.compensation_force_n * in.compensation_force_n;
    ++closed_in_window_;
  }
  if (++in_window_ >= window_steps_) {
    counters_.last_window_rms_mps = std::sqrt(sum_v2_ / static_cast<double>(in_window_));
    motor_held_ = counters_.last_window_rms_mps < params_.quiet_velocity_mps;
    const bool closed_window = closed_in_window_ == in_window_;
    if (closed_window) counters_.last_closed_force_n = std::sqrt(sum_f2_ / static_cast<double>(in_window_));
    // The load's own witness, when its sensor read every tick of the window.
    const bool load_seen = stretch_in_window_ == in_window_;
    if (load_seen) counters_.last_load_swing_m = 0.5 * (stretch_max_m_ - stretch_min_m_);
    const double quiet_swing_m =
        in.stretch_from_accelerometer ? params_.quiet_accel_swing_m : params_.quiet_load_swing_m;
    const double wake_swing_m = in.stretch_from_accelerometer ? params_.wake_accel_swing_m : params_.wake_load_swing_m;
    const bool load_quiet = !load_seen || counters_.last_load_swing_m <= quiet_swing_m;
    const bool load_moves = load_seen && counters_.last_load_swing_m > wake_swing_m;
    in_window_ = closed_in_window_ = stretch_in_window_ = 0;
    sum_v2_ = sum_f2_ = 0;
    if (counters_.last_window_rms_mps > params_.wake_velocity_mps || load_moves ||
        (params_.wake_on_request && closed_window && !load_seen &&
         counters_.last_closed_force_n > params_.wake_force_n)) {
      // Woken: open for settle_s at least, as after a move, so the swing is damped, not sampled.
      open(false);
      at_rest_steps_ = 0;
    } else if (!out_.closed && at_rest_steps_ >= (load_seen ? load_settle_steps_ : settle_steps_) &&
               counters_.last_window_rms_mps < params_.quiet_velocity_mps && load_quiet) {
      out_.closed = true;
      ++counters_.closings;
    }
  }
  const double target = out_.closed ? 0.0 : 1.0;
  out_.scale = out_.scale < target ? std::min(target, out_.scale + fade_per_step_)
                                   : std::max(target, out_.scale - fade_per_step_);
  return out_;
}

}  // namespace pmlsm

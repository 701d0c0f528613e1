#include "pmlsm/sim/system_params.hpp"

#include <algorithm>

#include <cfloat>
#include <cmath>
#include <stdexcept>
#include <string>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

void TimingParams::validate() const {
  require_in_range("control_period_s", control_period_s, 1e-5, 1.0);
  require_in_range("current_loop_period_s", current_loop_period_s, 1e-7, control_period_s);
  const double ratio = control_period_s / current_loop_period_s;
  if (std::abs(ratio - std::round(ratio)) > 1e-9 * ratio) {
    throw std::invalid_argument(
        "current_loop_period_s: must divide control_period_s into a whole number of steps, got " +
        format_value(current_loop_period_s));
  }
}

int TimingParams::current_steps_per_tick() const {
  return static_cast<int>(std::lround(control_period_s / current_loop_period_s));
}

void CurrentLoopTuning::validate() const {
  require_positive("kp_v_per_a", kp_v_per_a);
  require_non_negative("ki_v_per_a_s", ki_v_per_a_s);
  require_positive("current_limit_a", current_limit_a);
}

CurrentControllerParams SystemParams::current_controller_params() const {
  CurrentControllerParams p;
  p.kp_v_per_a = current_loop.kp_v_per_a;
  p.ki_v_per_a_s = current_loop.ki_v_per_a_s;
  p.period_s = timing.current_loop_period_s;
  p.current_limit_a = current_loop.current_limit_a;
  p.voltage_limit_v = plant.inverter.voltage_limit_v();
  p.motor_constant_n_per_a = plant.electrical.motor_constant_n_per_a;
  p.pole_pitch_m = plant.electrical.pole_pitch_m;
  p.armature_d_inductance_h = plant.electrical.armature_d_inductance_h;
  p.armature_q_inductance_h = plant.electrical.armature_q_inductance_h;
  p.permanent_magnet_flux_wb = plant.electrical.permanent_magnet_flux_wb();
  return p;
}

VelocityPiParams SystemParams::velocity_pi_params() const {
  return VelocityPiParams{velocity_loop.kp_n_s_per_m, velocity_loop.ki_n_per_m, timing.control_period_s,
                          velocity_loop.force_limit_n};
}

ReferenceModelParams SystemParams::reference_model_params() const {
  return ReferenceModelParams{reference_model.natural_frequency_rad_s, reference_model.damping_ratio,
                              timing.control_period_s};
}

KalmanParams SystemParams::kalman_params() const {
  KalmanParams p;
  p.motor_mass_kg = kalman.model.motor_mass_kg;
  p.load_mass_kg = kalman.model.load_mass_kg;
  p.spring_n_per_m = kalman.model.spring_n_per_m;
  p.period_s = timing.control_period_s;
  p.process_noise_diag = kalman.process_noise_diag;
  p.measurement_noise = kalman.measurement_noise;
  p.initial_covariance_diag = kalman.initial_covariance_diag;
  p.friction_input = kalman.friction_input;
  p.ripple_input = kalman.ripple_input;
  p.standstill_hold = kalman.standstill_hold;
  p.thrust_lag_s = kalman.thrust_lag_s;
  return p;
}

RnnCompensatorParams SystemParams::rnn_compensator_params(bool online_learning) const {
  RnnCompensatorParams p;
  p.layer_sizes = compensator.rnn_layer_sizes;
  p.input_scale_s2_per_m = compensator.rnn_input_scale_s2_per_m;
  p.on_reference_error = compensator.rnn_on_reference_error;
  p.gain_n = compensator.rnn_gain_n;
  p.output_scale = compensator_gain_scale();
  p.period_s = timing.control_period_s;
  p.online_learning = online_learning;
  p.learning_rate = compensator.rnn_learning_rate;
  p.momentum = compensator.rnn_momentum;
  p.tolerance_mps = compensator.rnn_tolerance_mps;
  p.kc_limit_mps = compensator.rnn_kc_limit_mps;
  p.du_deadband_per_s = compensator.rnn_du_deadband_per_s;
  return p;
}

VibrationGuardParams SystemParams::vibration_guard_params() const {
  VibrationGuardParams p = compensator.guard;
  p.control_period_s = timing.control_period_s;
  return p;
}

double SystemParams::compensator_gain_scale() const {
  return std::min(compensator.max_gain_scale, kalman.model.load_mass_kg / compensator.design_load_mass_kg);
}

AccelFeedbackParams SystemParams::accel_feedback_params() const {
  return AccelFeedbackParams{compensator.accel_feedback_gain_kg * compensator_gain_scale(), velocity_loop.force_limit_n,
                             compensator.accel_feedback_on_reference_error};
}

StateFeedbackParams SystemParams::state_feedback_params() const {
  StateFeedbackParams p;
  p.motor_mass_kg = compensator.state_model_motor_mass_kg;
  p.load_mass_kg = compensator.state_model_load_mass_kg;
  p.spring_n_per_m = compensator.state_model_spring_n_per_m;
  p.velocity_gain_n_s_per_m = velocity_loop.kp_n_s_per_m;
  p.model_frequency_ratio = compensator.state_model_frequency_ratio;
  p.model_damping_ratio = compensator.state_model_damping_ratio;
  p.correction_damping_ratio = compensator.state_correction_damping_ratio;
  p.max_correction_gain = compensator.state_max_correction_gain;
  p.reference_natural_frequency_rad_s = reference_model.natural_frequency_rad_s;
  p.reference_damping_ratio = reference_model.damping_ratio;
  p.period_s = timing.control_period_s;
  p.force_limit_n = velocity_loop.force_limit_n;
  return p;
}

namespace {

// Checks each value of the parameter table against its plausible range.
class RangeCheck {
 public:
  void real(const std::string& path, double value, const Plausible& range) const { check(path, value, range); }
  template <typename T>
  void integer(const std::string& path, T value, const Plausible& range) const {
    const double x = static_cast<double>(value);
    if (std::isfinite(x) && x != std::trunc(x)) {
      throw std::invalid_argument(path + ": must be a whole number (" + range.reason + "), got " + format_value(x));
    }
    check(path, x, range);
  }
  void flag(const std::string&, bool) const {}
  template <typename E, typename F>
  void choice(const std::string&, E, F) const {}
  void vector3(const std::string& path, const Eigen::Vector3d& value, const Plausible& range) const {
    for (int i = 0; i < 3; ++i) check(path + "[" + std::to_string(i) + "]", value(i), range);
  }
  void integer_list(const std::string& path, const std::vector<int>& value, const Plausible& range) const {
    for (std::size_t i = 0; i < value.size(); ++i) {
      check(path + "[" + std::to_string(i) + "]", value[i], range);
    }
  }

 private:
  static void check(const std::string& path, double value, const Plausible& range) {
    require_finite(path.c_str(), value);
    // A subnormal number (|x| < 2.2e-308, not 0) is no physical quantity; it only
    // overflows whatever divides by it.
    if (value != 0.0 && std::fabs(value) < DBL_MIN) {
      throw std::invalid_argument(path + ": must be 0 or at least 2.2e-308 in size (a subnormal number), got " +
                                  format_value(value));
    }
    if (!(value >= range.min && value <= range.max)) {
      throw std::invalid_argument(path + ": must be in [" + format_value(range.min) + ", " + format_value(range.max) +
                                  "] (" + range.reason + "), got " + format_value(value));
    }
  }
};

}  // namespace

namespace {

// Finds the real entry of the table with a key path.
class RealFinder {
 public:
  explicit RealFinder(const std::string& path) : path_(path) {}
  void real(const std::string& path, double& value, const Plausible& range) {
    if (path == path_) {
      found_ = &value;
      range_ = range;
    }
  }
  template <typename T>
  void integer(const std::string& path, T&, const Plausible&) {
    other(path);
  }
  void flag(const std::string& path, bool&) { other(path); }
  template <typename E, typename F>
  void choice(const std::string& path, E&, F) {
    other(path);
  }
  void vector3(const std::string& path, Eigen::Vector3d&, const Plausible&) { other(path); }
  void integer_list(const std::string& path, std::vector<int>&, const Plausible&) { other(path); }

  double* found_ = nullptr;
  Plausible range_{0, 0, ""};
  bool other_kind_ = false;

 private:
  void other(const std::string& path) { other_kind_ = other_kind_ || path == path_; }
  std::string path_;
};

}  // namespace

double& real_parameter(SystemParams& params, const std::string& key_path, Plausible* range) {
  RealFinder finder(key_path);
  visit_parameters(params, finder);
  if (finder.found_ == nullptr) {
    throw std::invalid_argument(key_path + (finder.other_kind_ ? ": not a real number parameter (a count, flag, "
                                                                 "choice or list)"
                                                               : ": no such parameter"));
  }
  if (range != nullptr) *range = finder.range_;
  return *finder.found_;
}

void SystemParams::validate() const {
  // The plausible ranges first: then the components' checks, which combine values (the
  // flux maps' L_md^2 < L_ad L_D, the loop's steps), only see plausible numbers.
  RangeCheck check;
  visit_parameters(*this, check);
  validate_section("timing", [&] { timing.validate(); });
  validate_section("plant", [&] { plant.validate(); });
  validate_section("current_loop", [&] { current_loop.validate(); });
  validate_section("current_loop", [&] { current_controller_params().validate(); });
  validate_section("velocity_loop", [&] { velocity_pi_params().validate(); });
  validate_section("reference_model", [&] { reference_model_params().validate(); });
  validate_section("kalman", [&] { kalman_params().validate(); });
  validate_section("compensator.rnn", [&] { rnn_compensator_params(true).validate(); });
  validate_section("compensator.acceleration_feedback", [&] { accel_feedback_params().validate(); });
  validate_section("compensator.state_feedback", [&] { state_feedback_params().validate(); });
  validate_section("compensator.guard", [&] { vibration_guard_params().validate(); });
  validate_section("plant", [&] { plant.check_step(); });
}

}  // namespace pmlsm

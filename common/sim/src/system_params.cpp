#include "pmlsm/sim/system_params.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>

#include "pmlsm/util/parameter_table.hpp"
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

// Each accessor takes its component's section whole and fills what the system derives.

CurrentControllerParams SystemParams::current_controller_params() const {
  CurrentControllerParams p = current_loop;
  p.period_s = timing.current_loop_period_s;
  p.voltage_limit_v = plant.inverter.voltage_limit_v();
  p.motor_constant_n_per_a = plant.electrical.motor_constant_n_per_a;
  p.pole_pitch_m = plant.electrical.pole_pitch_m;
  p.armature_d_inductance_h = plant.electrical.armature_d_inductance_h;
  p.armature_q_inductance_h = plant.electrical.armature_q_inductance_h;
  p.permanent_magnet_flux_wb = plant.electrical.permanent_magnet_flux_wb();
  return p;
}

VelocityPiParams SystemParams::velocity_pi_params() const {
  VelocityPiParams p = velocity_loop;
  p.period_s = timing.control_period_s;
  return p;
}

ReferenceModelParams SystemParams::reference_model_params() const {
  ReferenceModelParams p = reference_model;
  p.period_s = timing.control_period_s;
  return p;
}

KalmanParams SystemParams::kalman_params() const {
  KalmanParams p = kalman;
  p.period_s = timing.control_period_s;
  p.load_measurement = KalmanLoadMeasurement::of(load_sensor, timing.control_period_s, plant.encoder.resolution_m);
  return p;
}

RnnCompensatorParams SystemParams::rnn_compensator_params(bool online_learning) const {
  RnnCompensatorParams p = compensator.rnn;
  p.output_scale = compensator.rnn.output_scale * compensator_gain_scale();
  if (load_sensor.kind == LoadSensorKind::kEncoder) p.output_scale *= compensator.rnn_load_encoder_gain_scale;
  p.period_s = timing.control_period_s;
  p.rest_velocity_mps = compensator.standstill.rest_velocity_mps;
  p.online_learning = online_learning;
  return p;
}

VibrationGuardParams SystemParams::vibration_guard_params() const {
  VibrationGuardParams p = compensator.guard;
  p.control_period_s = timing.control_period_s;
  return p;
}

StandstillGateParams SystemParams::standstill_gate_params() const {
  StandstillGateParams p = compensator.standstill;
  p.control_period_s = timing.control_period_s;
  p.load_period_s = 2.0 * M_PI * std::sqrt(kalman.model.load_mass_kg / kalman.model.spring_n_per_m);
  // The push after the stretch reads a load encoder's count: without one it is off, and the
  // filter's model need not fit its ring.
  if (load_sensor.kind != LoadSensorKind::kEncoder) p.stretch_gain_n_per_m = 0.0;
  if (load_sensor.kind != LoadSensorKind::kAccelerometer) p.accel_stretch_gain_n_per_m = 0.0;
  return p;
}

VibrationMode SystemParams::loop_vibration_mode() const {
  const double m_m = kalman.model.motor_mass_kg;
  const double m_l = kalman.model.load_mass_kg;
  const double k = kalman.model.spring_n_per_m;
  const double kp = velocity_loop.kp_n_s_per_m;
  const double ki = velocity_loop.ki_n_per_m;
  // x = [x_M, v_M, x_L, v_L, z], z = integral of -v_M (the PI's state for V_ref = 0).
  Eigen::Matrix<double, 5, 5> a = Eigen::Matrix<double, 5, 5>::Zero();
  a(0, 1) = 1.0;
  a(1, 0) = -k / m_m;
  a(1, 1) = -kp / m_m;
  a(1, 2) = k / m_m;
  a(1, 4) = ki / m_m;
  a(2, 3) = 1.0;
  a(3, 0) = k / m_l;
  a(3, 2) = -k / m_l;
  a(4, 1) = -1.0;
  const Eigen::EigenSolver<Eigen::Matrix<double, 5, 5>> solver(a, false);
  VibrationMode least_damped{std::sqrt(k / m_l) / (2.0 * M_PI), 1.0};
  for (Eigen::Index i = 0; i < solver.eigenvalues().size(); ++i) {
    const std::complex<double> pole = solver.eigenvalues()(i);
    if (pole.imag() <= 0.0) continue;  // one of each conjugate pair; real poles do not ring
    const double w_n = std::abs(pole);
    const double zeta = -pole.real() / w_n;
    if (zeta < least_damped.damping_ratio) least_damped = {w_n / (2.0 * M_PI), zeta};
  }
  return least_damped;
}

namespace {
FilterChainParams at_period(FilterChainParams chain, double period_s) {
  for (BiquadParams& slot : chain.slots) slot.period_s = period_s;
  return chain;
}
}  // namespace

FilterChainParams SystemParams::force_command_filter_params() const {
  return at_period(force_command_filters, timing.control_period_s);
}

FilterChainParams SystemParams::compensation_filter_params() const {
  return at_period(compensation_filters, timing.control_period_s);
}

InputShaperParams SystemParams::input_shaper_params(ShaperKind kind) const {
  const VibrationMode mode = loop_vibration_mode();
  InputShaperParams p;
  p.kind = kind;
  p.frequency_hz = mode.frequency_hz;
  p.damping_ratio = std::clamp(mode.damping_ratio, 0.0, 0.5);
  p.vibration_tolerance = input_shaping.vibration_tolerance;
  p.period_s = timing.control_period_s;
  return p;
}

double SystemParams::compensator_gain_scale() const {
  return std::min(compensator.max_gain_scale, kalman.model.load_mass_kg / compensator.design_load_mass_kg);
}

AccelFeedbackParams SystemParams::accel_feedback_params() const {
  AccelFeedbackParams p = compensator.acceleration_feedback;
  p.gain_kg *= compensator_gain_scale();
  if (load_sensor.kind == LoadSensorKind::kEncoder) p.gain_kg *= compensator.accel_load_encoder_gain_scale;
  if (load_sensor.kind == LoadSensorKind::kAccelerometer) p.gain_kg *= compensator.accel_accelerometer_gain_scale;
  p.force_limit_n = velocity_loop.force_limit_n;
  return p;
}

StateFeedbackParams SystemParams::state_feedback_params() const {
  StateFeedbackParams p = compensator.state_feedback;
  p.velocity_gain_n_s_per_m = velocity_loop.kp_n_s_per_m;
  p.reference_natural_frequency_rad_s = reference_model.natural_frequency_rad_s;
  p.reference_damping_ratio = reference_model.damping_ratio;
  p.period_s = timing.control_period_s;
  p.force_limit_n = velocity_loop.force_limit_n;
  return p;
}

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
  void choice(const std::string& path, E&, F, const char* /*live_at*/ = nullptr) {
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

namespace {

// Collects the key paths a visit names.
struct KeyCollector {
  std::vector<std::string> keys;
  void real(const std::string& path, double& /*value*/, const Plausible& /*range*/) { keys.push_back(path); }
  template <typename Enum, typename Parse>
  void choice(const std::string& path, Enum& /*value*/, Parse /*parse*/, const char* /*live_at*/ = nullptr) {
    keys.push_back(path);
  }
};

}  // namespace

std::vector<std::string> filter_slot_keys(const std::string& at) {
  KeyCollector collector;
  BiquadParams slot;
  BiquadParams::declare(at, slot, collector);
  return collector.keys;
}

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
  validate_section("current_loop", [&] { current_controller_params().validate(); });
  validate_section("velocity_loop", [&] { velocity_pi_params().validate(); });
  validate_section("position_loop", [&] {
    position_loop.validate();
    if (position_loop.closes_on == PositionFeedback::kLoad && load_sensor.kind != LoadSensorKind::kEncoder) {
      throw std::invalid_argument(std::string("closes_on: load needs an encoder on the load (sensors.load.kind: "
                                              "encoder), got sensors.load.kind ") +
                                  to_string(load_sensor.kind));
    }
  });
  validate_section("reference_model", [&] { reference_model_params().validate(); });
  validate_section("kalman", [&] { kalman_params().validate(); });
  validate_section("compensator.rnn", [&] { rnn_compensator_params(true).validate(); });
  validate_section("compensator.acceleration_feedback", [&] { accel_feedback_params().validate(); });
  validate_section("compensator.state_feedback", [&] { state_feedback_params().validate(); });
  validate_section("compensator.guard", [&] { vibration_guard_params().validate(); });
  validate_section("compensator.standstill", [&] { standstill_gate_params().validate(); });
  validate_section("filters.force_command", [&] { force_command_filter_params().validate(); });
  validate_section("filters.compensation", [&] { compensation_filter_params().validate(); });
  validate_section("sensors.load", [&] { load_sensor.validate(); });
  validate_section("plant", [&] { plant.check_step(); });
  for (const ParameterSection& section : sections) {
    validate_section(section.at, [&] { section.validate(section, section_values); });
  }
}

}  // namespace pmlsm

#include "pmlsm/compensation/state_feedback.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "pmlsm/control/reference_model.hpp"
#include "pmlsm/util/discretize.hpp"
#include "pmlsm/util/validate.hpp"

namespace pmlsm {

BiquadParams filter_at_loop_period(const StateFeedbackParams& params) {
  BiquadParams filter = params.output_filter;
  filter.period_s = params.period_s;
  if (!params.output_filter_enabled) filter.kind = FilterKind::kNone;
  return filter;
}

void StateFeedbackParams::validate() const {
  // Its own entries; model_frequency_ratio >= 1 keeps c0 = r^2 - 1 >= 0: a load mode no slower
  // than the open one (a negative c0 would feed the load's velocity error forward, along the error).
  check_declared_ranges(*this);
  // What the system fills in: the velocity loop's gain and limit, the reference model, the period.
  require_positive("velocity_gain_n_s_per_m", velocity_gain_n_s_per_m);
  require_positive("reference_natural_frequency_rad_s", reference_natural_frequency_rad_s);
  require_positive("reference_damping_ratio", reference_damping_ratio);
  require_in_range("period_s", period_s, 1e-6, 1.0);
  require_positive("force_limit_n", force_limit_n);
  try {
    BiquadParams declared = output_filter;  // checked enabled or not: a declared filter is valid
    declared.period_s = period_s;
    declared.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("output_filter: ") + e.what());
  }
}

StateFeedback::StateFeedback(const StateFeedbackParams& params)
    : params_((params.validate(), params)), output_filter_(filter_at_loop_period(params_)) {
  const double m_m = params_.model.motor_mass_kg;
  const double m_l = params_.model.load_mass_kg;
  const double k = params_.model.spring_n_per_m;
  design();

  // The controller's reference model (25), for its one-tick look ahead.
  const ReferenceModel reference(
      {params_.reference_natural_frequency_rad_s, params_.reference_damping_ratio, params_.period_s});
  reference_phi_ = reference.phi();
  reference_gamma_ = reference.gamma();

  // x_m = [x_M, v_M, x_L, v_L]: m_M dv_M/dt = F - k (x_M - x_L), m_L dv_L/dt = k (x_M - x_L).
  Eigen::MatrixXd a_m(4, 4);
  a_m << 0.0, 1.0, 0.0, 0.0,        //
      -k / m_m, 0.0, k / m_m, 0.0,  //
      0.0, 0.0, 0.0, 1.0,           //
      k / m_l, 0.0, -k / m_l, 0.0;
  Eigen::MatrixXd b_m(4, 1);
  b_m << 0.0, 1.0 / m_m, 0.0, 0.0;
  const DiscreteModel model = discretize_zoh(a_m, b_m, params_.period_s);
  model_phi_ = model.phi;
  model_gamma_ = model.gamma;
}

void StateFeedback::design() {
  const double m_l = params_.model.load_mass_kg;
  const double k = params_.model.spring_n_per_m;
  const double r = params_.model_frequency_ratio;
  const double w = r * std::sqrt(k / m_l);
  c0_ = r * r - 1.0;
  c1_s_ = 2.0 * params_.model_damping_ratio * w * m_l / k;
  correction_gain_ =
      std::min(2.0 * params_.correction_damping_ratio * params_.velocity_gain_n_s_per_m / std::sqrt(k * m_l) - 1.0,
               params_.max_correction_gain);
}

void StateFeedback::set_params(const StateFeedbackParams& params) {
  params.validate();
  const StateFeedbackParams& now = params_;
  const bool same_base =
      params.model.motor_mass_kg == now.model.motor_mass_kg && params.model.load_mass_kg == now.model.load_mass_kg &&
      params.model.spring_n_per_m == now.model.spring_n_per_m &&
      params.reference_natural_frequency_rad_s == now.reference_natural_frequency_rad_s &&
      params.reference_damping_ratio == now.reference_damping_ratio && params.period_s == now.period_s &&
      params.force_limit_n == now.force_limit_n && filter_at_loop_period(params) == filter_at_loop_period(now);
  if (!same_base) {
    throw std::invalid_argument(
        "state feedback: only the design's ratios, the friction fed forward and the velocity loop's gain "
        "change live; the model, the period, the loop's limit and the output filter need a restart");
  }
  params_ = params;
  design();
}

double StateFeedback::model_spring_force_n() const {
  return params_.model.spring_n_per_m * (model_reported_(0) - model_reported_(2));
}

void StateFeedback::reset_model() {
  model_next_.setZero();
  model_at_tick_.setZero();
  model_reported_.setZero();
  model_motor_position_before_m_ = 0;
  last_a_ref_mps2_ = 0;
  ++counters_.model_resets;
}

double StateFeedback::step(const StateFeedbackInput& in) {
  ++counters_.steps;
  if (!std::isfinite(in.command_mps) || !std::isfinite(in.v_ref_mps) || !std::isfinite(in.a_ref_mps2) ||
      !std::isfinite(in.load_velocity_mps) || !std::isfinite(in.spring_force_n)) {
    ++counters_.rejected_inputs;
    return 0.0;
  }
  const StateFeedbackParams& p = params_;
  const double k = p.model.spring_n_per_m;
  const double limit = p.force_limit_n;

  // The reference when this force acts. Shaped by the model (25): one tick on, c held, its jerk
  // from (25). A profiled reference (the scenario bypasses the model: V_ref = c, dV_ref/dt its
  // backward difference) has no model to look ahead with: its own slope carries it a tick on,
  // the acceleration held, the jerk the acceleration's backward difference. (Taking the model
  // there reads a constant acceleration as a jerk of -2 zeta wn a: the model's load then lags
  // the profile, and every profiled move cost more than PI alone on some plant.)
  double v_ref = 0, a_ref = 0, j_ref = 0;
  if (in.v_ref_mps == in.command_mps) {
    v_ref = in.v_ref_mps + p.period_s * in.a_ref_mps2;
    a_ref = in.a_ref_mps2;
    j_ref = (in.a_ref_mps2 - last_a_ref_mps2_) / p.period_s;
  } else {
    const Eigen::Vector2d ref =
        reference_phi_ * Eigen::Vector2d(in.v_ref_mps, in.a_ref_mps2) + reference_gamma_ * in.command_mps;
    v_ref = ref(0);
    a_ref = ref(1);
    const double wn = p.reference_natural_frequency_rad_s;
    j_ref = wn * wn * (in.command_mps - v_ref) - 2.0 * p.reference_damping_ratio * wn * a_ref;
  }
  last_a_ref_mps2_ = in.a_ref_mps2;
  if (!std::isfinite(v_ref) || !std::isfinite(a_ref) || !std::isfinite(j_ref)) {
    reset_model();  // a reference at the edge of the doubles overflowed: restart at rest
    return 0.0;
  }

  // The law on the model's state at that tick, and the model's PI and drive limit.
  const Eigen::Vector4d& x = model_next_;
  const double model_spring_n = k * (x(0) - x(2));
  const double model_motor_velocity_mps = (x(0) - model_motor_position_before_m_) / p.period_s;  // encoder-like mean
  const double model_pi_n = p.velocity_gain_n_s_per_m * (v_ref - model_motor_velocity_mps);
  const double motor_offset_mps = (p.model.load_mass_kg / k) * j_ref +
                                  c1_s_ * (a_ref - model_spring_n / p.model.load_mass_kg) + c0_ * (v_ref - x(3));
  const double model_force_n = std::clamp(
      p.velocity_gain_n_s_per_m * motor_offset_mps + p.model.motor_mass_kg * a_ref + model_spring_n, -limit, limit);
  const double model_drive_n = std::clamp(model_pi_n + model_force_n, -limit, limit);

  // The plant pulled onto the model: the estimate against the model at the estimate's tick.
  model_reported_ = model_at_tick_;
  const double correction_n = correction_gain_ * (model_spring_force_n() - in.spring_force_n);
  // The bearings' friction on the model's motor velocity over the tick the force acts.
  const double model_motor_next_mps = x(1);
  const double u = std::clamp(model_motor_next_mps / p.friction_band_mps, -1.0, 1.0);
  const double friction_n =
      p.friction_coulomb_n * u * (1.5 - 0.5 * u * u) + p.friction_viscous_n_s_per_m * model_motor_next_mps;
  const double raw_force_n = model_force_n + correction_n + friction_n;

  model_motor_position_before_m_ = x(0);
  model_at_tick_ = model_next_;
  model_next_ = model_phi_ * model_next_ + model_gamma_ * model_drive_n;
  if (!model_next_.allFinite() || !std::isfinite(raw_force_n)) {
    reset_model();
    return 0.0;
  }
  // Limited, filtered, limited again: the filter softens what the limit leaves of a kick.
  if (std::abs(raw_force_n) > limit) ++counters_.saturated;
  const double force_n = output_filter_.step(std::clamp(raw_force_n, -limit, limit));
  return std::clamp(force_n, -limit, limit);
}

}  // namespace pmlsm

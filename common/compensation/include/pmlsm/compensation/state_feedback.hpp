// A model-based compensator beyond the paper: model-following state feedback.
// An internal copy of the nominal loop (two-mass model, velocity PI, force limit) is
// driven by state feedback with feedforward through the model's inverse, so the model's
// load follows V_ref as closely as the force limit allows; that force goes to the plant,
// and a correction on the estimated spring force pulls the plant onto the model.
// It takes the same inputs as the others (the Kalman estimate and V_ref), so it drops
// in on the same topics.
//
// Inverse model. The stiff velocity PI makes the motor a velocity source: a force
//   F_c = Kp (v_M* - V_ref) + m_M dV_ref/dt + F_s
// moves the motor to v_M* (the PI's own Kp (V_ref - v_M) completes Kp (v_M* - v_M);
// m_M dV_ref/dt carries the motor's inertia, F_s cancels the spring's pull on it).
// The load (m_L dv_L/dt = F_s, dF_s/dt = k (v_M - v_L)) then follows V_ref exactly when
//   v_M* = V_ref + (m_L / k) d^2V_ref/dt^2                         (the spring's inverse),
// and with state feedback on the load's error e = v_L - V_ref,
//   v_M* = V_ref + (m_L / k) d^2V_ref/dt^2 - c1 de/dt - c0 e,   de/dt = F_s / m_L - dV_ref/dt,
// the error obeys m_L e'' + k c1 e' + k (1 + c0) e = 0, a mode at w_d = r sqrt(k / m_L) (r times
// the open load mode, r >= 1) with damping zeta_d:
//   c0 = r^2 - 1,   c1 = 2 zeta_d w_d m_L / k.
// d^2V_ref/dt^2 = wn^2 (c - V_ref) - 2 zeta wn dV_ref/dt follows from the reference model
// (25) and the raw command c; a profiled reference that bypasses the model (V_ref = c, told by
// that equality) gives it as the backward difference of dV_ref/dt.
//
// Why an internal model: the inverse asks for kilonewtons at a command step (the jerk of
// V_ref jumps by wn^2 c), so the force limit clips it, and feedback on the Kalman estimate
// with the gain the design needs (about 340 kg of load-acceleration feedback) makes the
// motor jump at 150 Hz, which the filter reads as spring force (its measurement is the
// encoder's mean velocity over the tick): it oscillates. The law above therefore runs on
// the model's exact state x_m = [x_M, v_M, x_L, v_L] (ZOH-exact at the period, the PI fed
// the model's encoder-like mean velocity, its Ki of 0.01 N/m left out, the sum clipped at
// the force limit as in the drive), and only the difference between the plant and the model goes through the
// estimate, with a modest gain:
//   F_c = F_model + (2 zeta_c Kp / sqrt(k m_L) - 1) (F_s,model - F_s,est),
// the first factor load-acceleration feedback of damping zeta_c on the open load mode, the
// -1 putting the estimated spring pull in place of the model's.
//
// Beyond the model: the bearings' friction is fed forward on the model's motor velocity over the
// next tick, F_ff = F_c s(v_M,model / v_band) + F_v v_M,model (s: the plant's smoothed sign), so
// the loop, whose PI has almost no integral, does not run (F_c + F_v v) / Kp slow (2.6 mm/s at
// 0.2 m/s on the nominal plant); at rest the model's motor stands still and nothing is fed. The
// whole force, limited, then passes one biquad (output_filter) and the limit again: a broad notch
// above the loop's crossover softens what the limit leaves of the inverse's kicks at a command
// step, and the correction's chatter.
//
// Timing: the force of tick k acts from tick k+1, when the PI follows V_ref(k+1); the model
// runs one tick ahead of the estimate with the reference model's next output (c held), and
// the correction compares the estimate with the model's state of the same tick.
// The force is limited to +-force_limit_n.
#pragma once

#include <Eigen/Dense>
#include <cstdint>

#include "pmlsm/control/biquad.hpp"
#include "pmlsm/util/parameter_table.hpp"
#include "pmlsm/util/two_mass_model.hpp"

namespace pmlsm {

struct StateFeedbackParams {
  TwoMassModel model;                  ///< its own, like the Kalman filter's
  double velocity_gain_n_s_per_m = 0;  ///< the velocity PI's Kp the force passes through, > 0
  // Design.
  double model_frequency_ratio = 0;     ///< r = w_d / sqrt(k / m_L), >= 1 (c0 >= 0)
  double model_damping_ratio = 0;       ///< zeta_d, >= 0
  double correction_damping_ratio = 0;  ///< zeta_c, >= 0
  /// The correction's gain per newton of spring-force difference, 2 zeta_c Kp / sqrt(k m_L) - 1,
  /// stops here: on a light, soft load the design asks for twice the nominal's, and the estimate
  /// then oscillates as with a larger zeta_c (it reads the motor's own jumps as spring force), > 0.
  double max_correction_gain = 0;
  // The reference model (25) the controller runs, to form d^2V_ref/dt^2 and look ahead.
  double reference_natural_frequency_rad_s = 0;
  double reference_damping_ratio = 0;
  double period_s = 0;
  double force_limit_n = 0;
  // Beyond the loop's model (see above).
  double friction_coulomb_n = 0;          ///< F_c fed forward, >= 0 (0 and F_v 0: none)
  double friction_viscous_n_s_per_m = 0;  ///< F_v fed forward, >= 0
  double friction_band_mps = 0;           ///< v_band: the sign's smoothed band, > 0
  bool output_filter_enabled = false;     ///< false: output_filter declared, not used
  BiquadParams output_filter;             ///< on the whole force (run at period_s)
  void validate() const;
  /// Its own entries under `at` ("compensator.state_feedback"): the model with the plant's ranges,
  /// the design's ratios and the friction fed forward (taken live by `live_at`), the output
  /// filter; the loop's gain, the reference model, the period and the limit come from the
  /// system. Self: this, const or not.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v, const char* live_at) {
    TwoMassModel::declare(at + ".model", p.model, v);
    v.real(at + ".model_frequency_ratio", p.model_frequency_ratio,
           {1.0, 100.0, "the model's load mode 1 to 100 times the open one sqrt(k / m_L)", live_at});
    v.real(at + ".model_damping_ratio", p.model_damping_ratio,
           {0.0, 100.0, "from undamped to overdamped a hundred times", live_at});
    v.real(at + ".correction_damping_ratio", p.correction_damping_ratio,
           {0.0, 100.0, "from none to overdamped a hundred times", live_at});
    v.real(at + ".max_correction_gain", p.max_correction_gain,
           {1e-3, 1e4, "newtons of correction per newton of spring-force difference", live_at});
    v.real(at + ".friction_feedforward.coulomb_n", p.friction_coulomb_n, {0.0, 1e4, "0 (none) to 10 kN", live_at});
    v.real(at + ".friction_feedforward.viscous_n_s_per_m", p.friction_viscous_n_s_per_m,
           {0.0, 1e5, "0 (none) to 100 kN s/m", live_at});
    v.real(at + ".friction_feedforward.band_mps", p.friction_band_mps, {1e-6, 1.0, "1 um/s to 1 m/s", live_at});
    v.flag(at + ".output_filter.enabled", p.output_filter_enabled);
    BiquadParams::declare(at + ".output_filter", p.output_filter, v);
  }
};

/// The output filter at the loop's period (its own period_s is not read); kind none when it is
/// not enabled.
BiquadParams filter_at_loop_period(const StateFeedbackParams& params);

/// What the compensator sees of one tick: the reference and the Kalman estimate.
struct StateFeedbackInput {
  double command_mps = 0;        ///< raw command c(t_k)
  double v_ref_mps = 0;          ///< V_ref
  double a_ref_mps2 = 0;         ///< dV_ref/dt
  double load_velocity_mps = 0;  ///< estimated v_L: checked, unused (the model carries v_L; the plant is pulled on F_s)
  double spring_force_n = 0;     ///< estimated F_s (on the load, m_L a_L)
};

struct StateFeedbackCounters {
  std::uint64_t steps = 0;
  std::uint64_t rejected_inputs = 0;  ///< a non-finite input: output 0, the model holds
  std::uint64_t saturated = 0;
  std::uint64_t model_resets = 0;  ///< the internal model left the finite numbers: restarted at rest
};

class StateFeedback {
 public:
  /// @throws std::invalid_argument naming the invalid parameter.
  explicit StateFeedback(const StateFeedbackParams& params);
  /// Never throws: a non-finite input gives 0 N (the model holds) and is counted.
  double step(const StateFeedbackInput& in);
  const StateFeedbackCounters& counters() const { return counters_; }
  const StateFeedbackParams& params() const { return params_; }
  /// Live parameters at a tick boundary: the design's ratios (r, zeta_d, zeta_c and the
  /// correction's limit), the friction fed forward and the velocity loop's Kp (the controller's,
  /// which the model's loop runs on and the correction's gain is designed with) take effect from
  /// the next step, the internal model's and the output filter's state kept.
  /// @throws std::invalid_argument naming the invalid parameter, or any other field changed (the
  /// model, the period, the loop's limit, the output filter: a restart); the old ones are kept.
  void set_params(const StateFeedbackParams& params);
  double c0() const { return c0_; }
  double c1_s() const { return c1_s_; }
  /// The model's load velocity at the tick of the last input (what the plant is pulled onto).
  double model_load_velocity_mps() const { return model_reported_(3); }
  /// The model's spring force k (x_M - x_L) at the tick of the last input.
  double model_spring_force_n() const;

 private:
  void reset_model();
  void design();  ///< c0, c1 and the correction's gain from params_

  StateFeedbackParams params_;
  double c0_ = 0;
  double c1_s_ = 0;
  double correction_gain_ = 0;  ///< min(2 zeta_c Kp / sqrt(k m_L) - 1, max_correction_gain)
  Eigen::Matrix2d reference_phi_;
  Eigen::Vector2d reference_gamma_;
  Eigen::Matrix4d model_phi_;
  Eigen::Vector4d model_gamma_;
  Eigen::Vector4d model_next_ = Eigen::Vector4d::Zero();      ///< model state one tick ahead
  Eigen::Vector4d model_at_tick_ = Eigen::Vector4d::Zero();   ///< model state at the next input's tick
  Eigen::Vector4d model_reported_ = Eigen::Vector4d::Zero();  ///< model state at the last input's tick
  double model_motor_position_before_m_ = 0;                  ///< x_M one tick before model_next_
  double last_a_ref_mps2_ = 0;                                ///< dV_ref/dt of the last input
  Biquad output_filter_;
  StateFeedbackCounters counters_;
};

}  // namespace pmlsm

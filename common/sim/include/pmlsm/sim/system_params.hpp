// Every parameter of the simulated system in one place: what configs/system.yaml
// holds. Components take the parts they need; the controller-side models (the
// drive's motor model, the Kalman filter's masses and stiffness) are taken from
// the nominal plant, as a drive tuned on the datasheet would be.
#pragma once

#include <vector>

#include "pmlsm/compensation/accel_feedback.hpp"
#include "pmlsm/control/current_controller.hpp"
#include "pmlsm/compensation/jordan_rnn.hpp"
#include "pmlsm/estimation/kalman_filter.hpp"
#include "pmlsm/plant/plant.hpp"
#include "pmlsm/control/reference_model.hpp"
#include "pmlsm/control/velocity_pi.hpp"

namespace pmlsm {

struct TimingParams {
  double control_period_s = 0;       ///< velocity loop, estimator, reference (1 ms)
  double current_loop_period_s = 0;  ///< drive current loop (31.25 us); divides the control period
  void validate() const;
  /// control_period_s / current_loop_period_s, checked to be a whole number by validate().
  int current_steps_per_tick() const;
};

/// Current-loop tuning and limits; its motor model comes from the plant.
struct CurrentLoopTuning {
  double kp_v_per_a = 0;
  double ki_v_per_a_s = 0;
  double current_limit_a = 0;
  void validate() const;
};

/// Kalman filter tuning; its model (34) comes from the plant's mechanics. The
/// friction and ripple models of its input are its own values (what a rig
/// identifies), not the simulated plant's, so a mismatch can be studied.
struct KalmanTuning {
  Eigen::Vector3d process_noise_diag = Eigen::Vector3d::Zero();
  double measurement_noise = 0;
  Eigen::Vector3d initial_covariance_diag = Eigen::Vector3d::Zero();
  KalmanFrictionInput friction_input;
  KalmanRippleInput ripple_input;
};

struct VelocityLoopTuning {
  double kp_n_s_per_m = 0;
  double ki_n_per_m = 0;
  double force_limit_n = 0;
};

struct ReferenceTuning {
  double natural_frequency_rad_s = 0;
  double damping_ratio = 0;
};

/// The compensators added to the PI output: the Jordan RNN (section 3.2) and the
/// linear load-acceleration feedback it is compared with.
struct CompensatorTuning {
  std::vector<int> rnn_layer_sizes;
  double rnn_input_scale_s2_per_m = 0;
  double rnn_gain_n = 0;
  double rnn_learning_rate = 0;
  double rnn_momentum = 0;
  double rnn_tolerance_mps = 0;
  double rnn_kc_limit_mps = 0;
  double rnn_du_deadband_per_s = 0;
  double accel_feedback_gain_kg = 0;
};

struct SystemParams {
  TimingParams timing;
  PlantParams plant;
  CurrentLoopTuning current_loop;
  VelocityLoopTuning velocity_loop;
  ReferenceTuning reference_model;
  KalmanTuning kalman;
  CompensatorTuning compensator;

  /// @throws std::invalid_argument with the section path of the first invalid value.
  void validate() const;
  CurrentControllerParams current_controller_params() const;
  VelocityPiParams velocity_pi_params() const;
  ReferenceModelParams reference_model_params() const;
  KalmanParams kalman_params() const;
  RnnCompensatorParams rnn_compensator_params(bool online_learning) const;
  AccelFeedbackParams accel_feedback_params() const;
};

}  // namespace pmlsm

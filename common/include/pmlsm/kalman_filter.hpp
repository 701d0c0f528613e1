// Kalman filter of section 3.5 on the two-mass model (34), b neglected:
//   x = [v_M, v_L, F_s],  u = F_T (motor thrust),  y = v_M,
//   A = [[0, 0, -1/m_M], [0, 0, 1/m_L], [k, -k, 0]],  B = [1/m_M, 0, 0]^T,  C = [1, 0, 0].
// F_s = k (x_M - x_L) is the spring force; (36) gives the load acceleration
// a_L = F_s / m_L. The model is discretised exactly (ZOH) at the filter's
// period (Phi, Gamma of (26)); Q (35) and R enter (29)-(30) as the discrete
// covariances. Each step runs the time update (28)-(29) with the previous
// input u_{k-1}, then the measurement update (30)-(32) with y_k.
// Friction and ripple are not modelled: the filter treats them as process noise.
#pragma once

#include <Eigen/Dense>
#include <cstdint>

namespace pmlsm {

struct KalmanParams {
  double motor_mass_kg = 0;
  double load_mass_kg = 0;
  double spring_n_per_m = 0;
  double period_s = 0;
  Eigen::Vector3d process_noise_diag = Eigen::Vector3d::Zero();   ///< Q diagonal (35)
  double measurement_noise = 0;                                   ///< R
  Eigen::Vector3d initial_covariance_diag = Eigen::Vector3d::Zero();  ///< P_0 diagonal
  void validate() const;
};

struct KalmanInput {
  double motor_velocity_measured_mps = 0;  ///< y_k
  double thrust_previous_n = 0;            ///< u_{k-1}: the force applied over the last period
};

struct KalmanEstimate {
  double motor_velocity_mps = 0;
  double load_velocity_mps = 0;
  double spring_force_n = 0;
  double load_accel_mps2 = 0;  ///< (36)
  double innovation_mps = 0;   ///< y_k - C x_k^-
  Eigen::Vector3d covariance_diag = Eigen::Vector3d::Zero();
  bool measurement_used = false;
};

struct KalmanCounters {
  std::uint64_t steps = 0;
  std::uint64_t rejected_measurements = 0;  ///< non-finite y: time update only
  std::uint64_t rejected_inputs = 0;        ///< non-finite u: the last finite u is used
};

class KalmanFilter {
 public:
  /// @throws std::invalid_argument naming the first invalid parameter.
  explicit KalmanFilter(const KalmanParams& params);
  void reset(const Eigen::Vector3d& initial_state = Eigen::Vector3d::Zero());
  KalmanEstimate step(const KalmanInput& input);

  const Eigen::Matrix3d& phi() const { return phi_; }
  const Eigen::Vector3d& gamma() const { return gamma_; }
  const Eigen::Vector3d& state() const { return x_; }
  const Eigen::Matrix3d& covariance() const { return p_; }
  const KalmanCounters& counters() const { return counters_; }
  /// Continuous-time model (34), for tests and the estimator's documentation.
  static Eigen::Matrix3d continuous_a(const KalmanParams& params);
  static Eigen::Vector3d continuous_b(const KalmanParams& params);

 private:
  KalmanParams params_;
  Eigen::Matrix3d phi_;
  Eigen::Vector3d gamma_;
  Eigen::Matrix3d q_;
  Eigen::Vector3d x_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d p_;
  double last_input_n_ = 0;
  KalmanCounters counters_;
};

}  // namespace pmlsm

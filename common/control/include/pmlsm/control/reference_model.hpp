// Reference model (25): G_ref(s) = wn^2 / (s^2 + 2 zeta wn s + wn^2), with
// wn = 100 rad/s, zeta = 1.732 in the paper (over-damped, Bessel-like: poles
// near -31.8 and -314 rad/s). It shapes the raw velocity command into V_ref.
//
// State x = [V_ref, dV_ref/dt], discretised exactly (ZOH) at the control period:
//   x_{k+1} = Phi x_k + Gamma c_k.
// step(c_k) holds the command c_k over [kT, (k+1)T) and returns V_ref((k+1)T)
// and its derivative, so a step command appears at the output one period later,
// exactly as the continuous model sampled at the period.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <string>

#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

struct ReferenceModelParams {
  double natural_frequency_rad_s = 0;
  double damping_ratio = 0;
  double period_s = 0;
  void validate() const;
  /// Its own entries under `at` ("reference_model"); the period comes from the system.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v) {
    v.real(at + ".natural_frequency_rad_s", p.natural_frequency_rad_s,
           {0.1, 1e4, "0.1 rad/s to 10 krad/s (the loop's 1 ms sampling resolves far less)"});
    v.real(at + ".damping_ratio", p.damping_ratio, {0.01, 100.0, "from barely damped to overdamped a hundred times"});
  }
};

struct ReferenceSample {
  double velocity_mps = 0;  ///< V_ref
  double accel_mps2 = 0;    ///< dV_ref/dt
};

class ReferenceModel {
 public:
  /// @throws std::invalid_argument naming the first invalid parameter.
  explicit ReferenceModel(const ReferenceModelParams& params);
  void reset(double initial_velocity_mps = 0.0);
  /// A non-finite command is rejected (the last accepted one is held) and counted.
  ReferenceSample step(double command_mps);
  std::uint64_t rejected_inputs() const { return rejected_inputs_; }
  const Eigen::Matrix2d& phi() const { return phi_; }
  const Eigen::Vector2d& gamma() const { return gamma_; }

 private:
  ReferenceModelParams params_;
  Eigen::Matrix2d phi_;
  Eigen::Vector2d gamma_;
  Eigen::Vector2d state_ = Eigen::Vector2d::Zero();
  double last_command_mps_ = 0;
  std::uint64_t rejected_inputs_ = 0;
};

}  // namespace pmlsm

// The classical baseline the paper's RNN extends: linear load-acceleration
// feedback F_c = -K_a a_L (a_L from the Kalman filter, eq. 36).
//
// Why it damps: the stiff velocity PI makes the motor almost a velocity source,
// so a force F_c moves the motor velocity by about F_c / Kp. The load then obeys
//   m_L j_L + k (K_a / Kp) a_L + k v_L = k v_ref,
// a damping ratio zeta = (K_a / Kp) sqrt(k / m_L) / 2 (0.35 at K_a = 120 kg with
// the paper's Kp = 10000 N s/m). The force is limited to +-force_limit_n.
#pragma once

#include <cstdint>

namespace pmlsm {

struct AccelFeedbackParams {
  double gain_kg = 0;        ///< K_a, >= 0
  double force_limit_n = 0;  ///< |F_c| limit, > 0
  void validate() const;
};

struct AccelFeedbackCounters {
  std::uint64_t steps = 0;
  std::uint64_t rejected_inputs = 0;  ///< non-finite a_L: output 0
  std::uint64_t saturated = 0;
};

class AccelFeedback {
 public:
  /// @throws std::invalid_argument naming the invalid parameter.
  explicit AccelFeedback(const AccelFeedbackParams& params);
  /// Never throws: a non-finite input gives 0 N and is counted.
  double step(double load_accel_mps2);
  const AccelFeedbackCounters& counters() const { return counters_; }
  const AccelFeedbackParams& params() const { return params_; }

 private:
  AccelFeedbackParams params_;
  AccelFeedbackCounters counters_;
};

}  // namespace pmlsm

// The classical baseline the paper's RNN extends: linear load-acceleration
// feedback F_c = -K_a a_L (a_L from the Kalman filter, eq. 36), or, on the
// acceleration's error to the reference, F_c = -K_a (a_L - dV_ref/dt).
//
// Why it damps: the stiff velocity PI makes the motor almost a velocity source,
// so a force F_c moves the motor velocity by about F_c / Kp. The load then obeys
//   m_L j_L + k (K_a / Kp) a_L + k v_L = k v_ref,
// a damping ratio zeta = (K_a / Kp) sqrt(k / m_L) / 2 (0.47 at K_a = 160 kg with
// the paper's Kp = 10000 N s/m). The same term resists every load acceleration,
// the commanded ones too: on a smooth reference it acts as K_a of extra inertia
// and drags the load behind V_ref. On the error a_L - dV_ref/dt the vibration is
// damped alike while the commanded acceleration passes (K_a dV_ref/dt is then an
// inertia feedforward). The force is limited to +-force_limit_n.
#pragma once

#include <cstdint>
#include <string>

#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

struct AccelFeedbackParams {
  double gain_kg = 0;        ///< K_a, >= 0
  double force_limit_n = 0;  ///< |F_c| limit, > 0
  /// true: F_c = -K_a (a_L - dV_ref/dt); false: the paper's baseline F_c = -K_a a_L.
  bool on_reference_error = false;
  void validate() const;
  /// Its own entries under `at` ("compensator.acceleration_feedback"); K_a is taken live by
  /// `live_at`; the limit comes from the velocity loop. Self: this, const or not.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v, const char* live_at) {
    v.real(at + ".gain_kg", p.gain_kg, {0.0, 1e5, "0 to 100 t of virtual mass", live_at});
    v.flag(at + ".on_reference_error", p.on_reference_error);
  }
};

struct AccelFeedbackInput {
  double load_accel_mps2 = 0;       ///< a_L, the Kalman estimate (36)
  double reference_accel_mps2 = 0;  ///< dV_ref/dt (used when on_reference_error)
};

struct AccelFeedbackCounters {
  std::uint64_t steps = 0;
  std::uint64_t rejected_inputs = 0;  ///< non-finite input: output 0
  std::uint64_t saturated = 0;
};

class AccelFeedback {
 public:
  /// @throws std::invalid_argument naming the invalid parameter.
  explicit AccelFeedback(const AccelFeedbackParams& params);
  /// Never throws: a non-finite input gives 0 N and is counted.
  double step(const AccelFeedbackInput& in);
  const AccelFeedbackCounters& counters() const { return counters_; }
  const AccelFeedbackParams& params() const { return params_; }
  /// Live parameters at a tick boundary (the law has no state to keep).
  /// @throws std::invalid_argument naming the invalid parameter; the old ones are kept.
  void set_params(const AccelFeedbackParams& params);

 private:
  AccelFeedbackParams params_;
  AccelFeedbackCounters counters_;
};

}  // namespace pmlsm

// Motor-side velocity loop (Table 3): a discrete PI run every T_v = 1 ms,
//   F_k = sat(Kp e_k + I_k + F_ff,k, +-F_max),  e_k = v_ref,k - v_meas,k,
//   I_{k+1} = I_k + Ki T_v e_k   unless the output is saturated and e_k pushes
//                               it further into saturation (conditional
//                               integration anti-windup).
// F_ff is an added force (the vibration compensator's output, Fig. 4); it is
// inside the saturation so the total force request never exceeds F_max.
#pragma once

#include <cstdint>
#include <string>

#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

struct VelocityPiParams {
  double kp_n_s_per_m = 0;
  double ki_n_per_m = 0;
  double period_s = 0;
  double force_limit_n = 0;
  void validate() const;
  /// Its own entries under `at` ("velocity_loop"); the gains are taken live by the node that runs
  /// it (`live_at`), the limit at start; the period comes from the system. Self: this, const or not.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v, const char* live_at) {
    v.real(at + ".kp_n_s_per_m", p.kp_n_s_per_m,
           {0.0, 1e6, "above 1e6 N s/m one encoder count per tick (1 mm/s at 1 um, 1 ms) alone would command 1 kN",
            live_at});
    v.real(at + ".ki_n_per_m", p.ki_n_per_m, {0.0, 1e9, "0 to 1 kN per um of accumulated error", live_at});
    v.real(at + ".force_limit_n", p.force_limit_n, {1e-3, 1e5, "1 mN to 100 kN, beyond the largest linear motors"});
  }
};

struct VelocityPiInput {
  double velocity_reference_mps = 0;
  double velocity_measured_mps = 0;
  double feedforward_force_n = 0;
};

struct VelocityPiOutput {
  double force_n = 0;
  bool saturated = false;
};

struct VelocityPiCounters {
  std::uint64_t steps = 0;
  std::uint64_t rejected_inputs = 0;  ///< non-finite input: last output held
  std::uint64_t saturated = 0;
};

class VelocityPi {
 public:
  /// @throws std::invalid_argument naming the first invalid parameter.
  explicit VelocityPi(const VelocityPiParams& params);
  void reset();
  /// New gains or limit from the next step on (a live change at a tick boundary); the integral is
  /// kept, so the force does not jump by it. @throws std::invalid_argument as the constructor.
  void set_params(const VelocityPiParams& params);
  VelocityPiOutput step(const VelocityPiInput& input);
  double integral_n() const { return integral_n_; }
  const VelocityPiParams& params() const { return params_; }
  const VelocityPiCounters& counters() const { return counters_; }

 private:
  VelocityPiParams params_;
  double integral_n_ = 0;
  VelocityPiOutput last_output_;
  VelocityPiCounters counters_;
};

}  // namespace pmlsm

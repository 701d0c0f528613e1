// Drive-side current loop: vector control with i_d* = 0 (section 3.1), so the
// thrust (14) F = (3p/2)(pi/tau) psi_d i_q = K_m i_q is set by i_q alone.
//
// Every period T_c (31.25 us in the paper) it turns a force request into
// i_q* = sat(F* / K_m, +-current_limit) and computes, per axis,
//   u_d = Kp (0    - i_d) + I_d - w_s L_aq i_q                 (d-q decoupling)
//   u_q = Kp (i_q* - i_q) + I_q + w_s (L_ad i_d + psi_pm)      (back-EMF feed-forward)
// with w_s = pi v / tau. The voltage vector is limited to |u| <= V_dc/sqrt(3),
// the same limit as the inverter's. Anti-windup by conditional integration:
// I += Ki T_c e only on periods when the vector was not limited, so the
// integrators cannot wind up while the inverter is at its limit.
//
// Default gains place the PI zero on the winding pole (Ki/Kp = R/L) for a
// closed-loop current bandwidth of Kp/L; see configs/system.yaml.
#pragma once

#include <cstdint>
#include <string>

#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

struct CurrentControllerParams {
  double kp_v_per_a = 0;
  double ki_v_per_a_s = 0;
  double period_s = 0;         ///< T_c
  double current_limit_a = 0;  ///< |i_q*| limit (peak amperes)
  double voltage_limit_v = 0;  ///< |u_dq| limit, V_dc/sqrt(3)
  // Motor model for the force-to-current map and the decoupling terms.
  double motor_constant_n_per_a = 0;
  double pole_pitch_m = 0;
  double armature_d_inductance_h = 0;
  double armature_q_inductance_h = 0;
  double permanent_magnet_flux_wb = 0;
  void validate() const;
  /// Its own entries under `at` ("current_loop"); the period, the voltage limit and the motor
  /// model come from the system (pmlsm/util/parameter_table.hpp). Self: this, const or not.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v) {
    v.real(at + ".kp_v_per_a", p.kp_v_per_a,
           {1e-3, 1e5, "1 mV/A to 100 kV/A: L w_c for any motor and a bandwidth up to the sampling"});
    v.real(at + ".ki_v_per_a_s", p.ki_v_per_a_s, {0.0, 1e9, "0 to R w_c of the stiffest loop"});
    v.real(at + ".current_limit_a", p.current_limit_a, {1e-3, 1e4, "1 mA to 10 kA"});
  }
};

struct CurrentControllerInput {
  double force_request_n = 0;  ///< F*
  double i_d_a = 0;            ///< measured
  double i_q_a = 0;            ///< measured
  double velocity_mps = 0;     ///< mover velocity for w_s
};

struct CurrentControllerOutput {
  double u_d_v = 0;
  double u_q_v = 0;
  double i_q_ref_a = 0;
  bool voltage_limited = false;
  bool current_limited = false;
};

struct CurrentControllerCounters {
  std::uint64_t steps = 0;
  std::uint64_t rejected_inputs = 0;  ///< non-finite input: last output held
  std::uint64_t voltage_limited = 0;
  std::uint64_t current_limited = 0;
};

class CurrentController {
 public:
  /// @throws std::invalid_argument naming the first invalid parameter.
  explicit CurrentController(const CurrentControllerParams& params);
  void reset();
  CurrentControllerOutput step(const CurrentControllerInput& input);
  const CurrentControllerParams& params() const { return params_; }
  const CurrentControllerCounters& counters() const { return counters_; }

 private:
  CurrentControllerParams params_;
  double electrical_rad_per_m_ = 0;
  double integral_d_v_ = 0;
  double integral_q_v_ = 0;
  CurrentControllerOutput last_output_;
  CurrentControllerCounters counters_;
};

}  // namespace pmlsm

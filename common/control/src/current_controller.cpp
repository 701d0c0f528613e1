#include "pmlsm/control/current_controller.hpp"

#include <algorithm>
#include <cmath>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

void CurrentControllerParams::validate() const {
  check_declared_ranges(*this);
  // The rest comes from the timing and the plant's motor (SystemParams::current_controller_params).
  require_in_range("period_s", period_s, 1e-7, 1e-2);
  require_positive("voltage_limit_v", voltage_limit_v);
  require_positive("motor_constant_n_per_a", motor_constant_n_per_a);
  require_positive("pole_pitch_m", pole_pitch_m);
  require_positive("armature_d_inductance_h", armature_d_inductance_h);
  require_positive("armature_q_inductance_h", armature_q_inductance_h);
  require_non_negative("permanent_magnet_flux_wb", permanent_magnet_flux_wb);
}

CurrentController::CurrentController(const CurrentControllerParams& params) : params_(params) {
  params_.validate();
  electrical_rad_per_m_ = 3.14159265358979323846 / params_.pole_pitch_m;
}

void CurrentController::reset() {
  integral_d_v_ = 0;
  integral_q_v_ = 0;
  last_output_ = CurrentControllerOutput{};
}

CurrentControllerOutput CurrentController::step(const CurrentControllerInput& in) {
  if (!all_finite(in.force_request_n, in.i_d_a, in.i_q_a, in.velocity_mps)) {
    ++counters_.rejected_inputs;
    return last_output_;
  }
  ++counters_.steps;
  const auto& p = params_;
  CurrentControllerOutput out;
  const double i_q_unlimited = in.force_request_n / p.motor_constant_n_per_a;
  out.i_q_ref_a = std::clamp(i_q_unlimited, -p.current_limit_a, p.current_limit_a);
  out.current_limited = out.i_q_ref_a != i_q_unlimited;

  const double e_d = 0.0 - in.i_d_a;
  const double e_q = out.i_q_ref_a - in.i_q_a;
  const double w_s = electrical_rad_per_m_ * in.velocity_mps;
  const double ff_d = -w_s * p.armature_q_inductance_h * in.i_q_a;
  const double ff_q = w_s * (p.armature_d_inductance_h * in.i_d_a + p.permanent_magnet_flux_wb);
  double u_d = p.kp_v_per_a * e_d + integral_d_v_ + ff_d;
  double u_q = p.kp_v_per_a * e_q + integral_q_v_ + ff_q;

  // Squared magnitudes: std::hypot is a slow libm call, and these volts cannot overflow.
  const double magnitude_sq = u_d * u_d + u_q * u_q;
  if (magnitude_sq > p.voltage_limit_v * p.voltage_limit_v) {
    const double scale = p.voltage_limit_v / std::sqrt(magnitude_sq);
    u_d *= scale;
    u_q *= scale;
    out.voltage_limited = true;
  } else {
    integral_d_v_ += p.ki_v_per_a_s * p.period_s * e_d;
    integral_q_v_ += p.ki_v_per_a_s * p.period_s * e_q;
  }
  out.u_d_v = u_d;
  out.u_q_v = u_q;
  counters_.voltage_limited += out.voltage_limited ? 1 : 0;
  counters_.current_limited += out.current_limited ? 1 : 0;
  last_output_ = out;
  return out;
}

}  // namespace pmlsm

#include "pmlsm/sim/velocity_controller.hpp"

namespace pmlsm {

VelocityController::VelocityController(const SystemParams& params, const Scenario& scenario)
    : scenario_(scenario),
      period_s_(params.timing.control_period_s),
      reference_(params.reference_model_params()),
      velocity_(params.velocity_pi_params()) {
  scenario_.validate(period_s_);
  if (params.compensator.guard_enabled) guard_.emplace(params.vibration_guard_params());
}

VelocityControllerOutput VelocityController::step(std::uint64_t tick, double motor_velocity_mps,
                                                  double compensation_force_n) {
  VelocityControllerOutput out;
  out.command_mps = scenario_.command_mps(static_cast<double>(tick) * period_s_);
  const ReferenceSample ref = reference_.step(out.command_mps);
  out.v_ref_mps = ref.velocity_mps;
  out.a_ref_mps2 = ref.accel_mps2;
  // The guard's scale of the previous period (it judges what was applied), then its new look.
  const double scale = guard_ ? guard_->output().scale : 1.0;
  out.compensation_applied_n = scale * compensation_force_n;
  if (guard_) out.guard = guard_->step(motor_velocity_mps, out.compensation_applied_n);
  const VelocityPiOutput f = velocity_.step({ref.velocity_mps, motor_velocity_mps, out.compensation_applied_n});
  out.force_n = f.force_n;
  out.saturated = f.saturated;
  out.velocity_error_mps = ref.velocity_mps - motor_velocity_mps;
  return out;
}

}  // namespace pmlsm

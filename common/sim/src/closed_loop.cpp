#include "pmlsm/sim/closed_loop.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace pmlsm {

std::uint64_t scenario_ticks(const Scenario& scenario, double control_period_s) {
  return static_cast<std::uint64_t>(std::llround(scenario.duration_s / control_period_s));
}

PlantInitialCondition scenario_initial_condition(const Scenario& scenario) {
  PlantInitialCondition initial;
  initial.load_position_m = scenario.initial_load_displacement_m;
  return initial;
}

void record_truth(const PlantTruth& truth, TickRecord& rec) {
  rec.motor_position_m = truth.state.motor_position_m;
  rec.motor_velocity_mps = truth.state.motor_velocity_mps;
  rec.load_position_m = truth.state.load_position_m;
  rec.load_velocity_mps = truth.state.load_velocity_mps;
  rec.load_accel_mps2 = truth.load_accel_mps2;
  rec.spring_force_n = truth.spring_force_n;
  rec.thrust_n = truth.thrust_n;
  rec.ripple_n = truth.ripple_n;
  rec.friction_n = truth.friction_n;
  rec.i_q_a = truth.i_q_a;
}

ClosedLoop::ClosedLoop(const SystemParams& params, const Scenario& scenario)
    : ClosedLoop(params, scenario, scenario_initial_condition(scenario)) {}

ClosedLoop::ClosedLoop(const SystemParams& params, const Scenario& scenario, const PlantInitialCondition& initial)
    : params_(params),
      scenario_(scenario),
      drive_(params, initial),
      controller_(params, scenario),
      kalman_(params.kalman_params()) {
  params_.validate();
  if (scenario_.shape == CommandShape::kExternal) {
    throw std::invalid_argument(
        "command.shape: external: its setpoints come over DDS; run it with the controller node");
  }
  total_ticks_ = scenario_ticks(scenario_, params_.timing.control_period_s);
}

TickRecord ClosedLoop::step(const Compensation& compensation) {
  TickRecord rec;
  rec.tick = tick_;
  rec.time_s = static_cast<double>(tick_) * params_.timing.control_period_s;
  rec.u_q_v = drive_.last_u_q_v();

  const DriveFeedback feedback = drive_.sample();
  rec.encoder_position_m = feedback.encoder_position_m;
  rec.motor_velocity_measured_mps = feedback.velocity_mps;

  const KalmanEstimate est =
      kalman_.step({feedback.velocity_mps, last_force_n_, feedback.encoder_position_m, feedback.load.position_m,
                    feedback.load.acceleration_mps2, feedback.load.saturated});
  rec.est_motor_velocity_mps = est.motor_velocity_mps;
  rec.est_load_velocity_mps = est.load_velocity_mps;
  rec.est_spring_force_n = est.spring_force_n;
  rec.est_load_accel_mps2 = est.load_accel_mps2;
  rec.load_position_measured_m = feedback.load.position_m;
  rec.load_accel_measured_mps2 = feedback.load.acceleration_mps2;
  rec.load_sensor_use = load_sensor_use(est);
  rec.load_sensor_fault = est.load_sensor_problem;

  const VelocityControllerOutput control =
      controller_.step(tick_, feedback.velocity_mps, compensation, {feedback.encoder_position_m, feedback.load});
  rec.command_mps = control.command_mps;
  rec.v_ref_mps = control.v_ref_mps;
  rec.a_ref_mps2 = control.a_ref_mps2;
  rec.force_command_n = control.force_n;
  rec.compensation_force_n = control.compensation_applied_n;
  rec.guard_tripped = control.guard.tripped;

  record_truth(drive_.plant().truth(), rec);

  // A diverged plant is a fault: zero force (the plant no longer moves either).
  rec.applied_force_n = last_force_n_;
  rec.force_off = drive_.plant().divergence().diverged;
  const double applied_n = rec.force_off ? 0.0 : control.force_n;
  drive_.apply_force(applied_n);
  last_force_n_ = applied_n;
  const PlantDivergence& divergence = drive_.plant().divergence();
  if (divergence.diverged) {
    rec.plant_fault_state = divergence.state;
    rec.plant_fault_value = divergence.value;
  }
  ++tick_;
  return rec;
}

std::string plant_fault_reason(const std::vector<TickRecord>& trace) {
  for (const TickRecord& rec : trace) {
    if (rec.plant_fault_state == nullptr) continue;
    char text[200];
    std::snprintf(text, sizeof text,
                  "plant state %s = %.6g (not finite or beyond any motor) at tick %llu: zero force from tick %llu",
                  rec.plant_fault_state, rec.plant_fault_value, static_cast<unsigned long long>(rec.tick),
                  static_cast<unsigned long long>(rec.tick + 1));
    return text;
  }
  return "";
}

std::string load_sensor_failure_reason(const std::vector<TickRecord>& trace) {
  for (const TickRecord& rec : trace) {
    if (rec.load_sensor_use != LoadSensorUse::kFailed) continue;
    char text[240];
    std::snprintf(text, sizeof text,
                  "the load's sensor failed at tick %llu (t = %.3f s): %s; the estimate from then on is the motor "
                  "side's alone",
                  static_cast<unsigned long long>(rec.tick), rec.time_s, to_string(rec.load_sensor_fault));
    return text;
  }
  return "";
}

std::vector<TickRecord> run_scenario(const SystemParams& params, const Scenario& scenario) {
  ClosedLoop loop(params, scenario);
  std::vector<TickRecord> trace;
  trace.reserve(loop.total_ticks());
  while (!loop.done()) trace.push_back(loop.step());
  return trace;
}

}  // namespace pmlsm

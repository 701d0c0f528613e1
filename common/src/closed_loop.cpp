#include "pmlsm/closed_loop.hpp"

#include <cmath>

namespace pmlsm {

ClosedLoop::ClosedLoop(const SystemParams& params, const Scenario& scenario)
    : params_(params),
      scenario_(scenario),
      plant_(params.plant),
      current_(params.current_controller_params()),
      velocity_(params.velocity_pi_params()),
      reference_(params.reference_model_params()),
      kalman_(params.kalman_params()),
      encoder_velocity_(params.timing.control_period_s) {
  params_.validate();
  scenario_.validate(params_.timing.control_period_s);
  current_steps_per_tick_ = params_.timing.current_steps_per_tick();
  total_ticks_ = static_cast<std::uint64_t>(
      std::llround(scenario_.duration_s / params_.timing.control_period_s));
  PlantInitialCondition initial;
  initial.load_position_m = scenario_.initial_load_displacement_m;
  plant_.reset(initial);
  last_measurement_ = plant_.measure();
  encoder_velocity_.reset(last_measurement_.encoder_position_m);
}

TickRecord ClosedLoop::step(double compensation_force_n) {
  const double period = params_.timing.control_period_s;
  const double t = static_cast<double>(tick_) * period;

  TickRecord rec;
  rec.tick = tick_;
  rec.time_s = t;
  rec.command_mps = scenario_.command_mps(t);
  rec.encoder_position_m = last_measurement_.encoder_position_m;
  rec.motor_velocity_measured_mps = encoder_velocity_.step(last_measurement_.encoder_position_m);

  const ReferenceSample ref = reference_.step(rec.command_mps);
  rec.v_ref_mps = ref.velocity_mps;

  const KalmanEstimate est = kalman_.step({rec.motor_velocity_measured_mps, last_force_n_});
  rec.est_motor_velocity_mps = est.motor_velocity_mps;
  rec.est_load_velocity_mps = est.load_velocity_mps;
  rec.est_spring_force_n = est.spring_force_n;
  rec.est_load_accel_mps2 = est.load_accel_mps2;

  const VelocityPiOutput force =
      velocity_.step({ref.velocity_mps, rec.motor_velocity_measured_mps, compensation_force_n});
  rec.force_command_n = force.force_n;

  const PlantTruth truth = plant_.truth();
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
  rec.u_q_v = last_u_q_v_;

  // The drive's current loop between two velocity-loop ticks. Its velocity
  // for the back-EMF feed-forward is the drive's own encoder velocity.
  const double dt_current = params_.timing.current_loop_period_s;
  PlantMeasurement m = last_measurement_;
  for (int i = 0; i < current_steps_per_tick_; ++i) {
    const CurrentControllerOutput u =
        current_.step({force.force_n, m.i_d_a, m.i_q_a, rec.motor_velocity_measured_mps});
    m = plant_.step(PlantInput{u.u_d_v, u.u_q_v, 0.0}, dt_current);
    last_u_q_v_ = u.u_q_v;
  }
  last_measurement_ = m;
  last_force_n_ = force.force_n;
  ++tick_;
  return rec;
}

std::vector<TickRecord> run_scenario(const SystemParams& params, const Scenario& scenario) {
  ClosedLoop loop(params, scenario);
  std::vector<TickRecord> trace;
  trace.reserve(loop.total_ticks());
  while (!loop.done()) trace.push_back(loop.step());
  return trace;
}

}  // namespace pmlsm

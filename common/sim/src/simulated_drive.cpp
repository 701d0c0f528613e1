#include "pmlsm/sim/simulated_drive.hpp"

#include <cstdio>

namespace pmlsm {

SimulatedDrive::SimulatedDrive(const SystemParams& params, const PlantInitialCondition& initial)
    : plant_(params.plant),
      current_(params.current_controller_params()),
      encoder_velocity_(params.timing.control_period_s),
      load_sensor_(params.load_sensor, params.timing.control_period_s),
      current_steps_per_tick_(params.timing.current_steps_per_tick()),
      current_period_s_(params.timing.current_loop_period_s) {
  params.timing.validate();
  plant_.reset(initial);
  last_measurement_ = plant_.measure();
  encoder_velocity_.reset(last_measurement_.encoder_position_m);
  load_sensor_.reset(initial.load_position_m);
}

DriveFeedback SimulatedDrive::sample() {
  last_velocity_mps_ = encoder_velocity_.step(last_measurement_.encoder_position_m);
  DriveFeedback fb{
      last_measurement_.encoder_position_m, last_velocity_mps_, last_measurement_.i_d_a, last_measurement_.i_q_a, {}};
  if (load_sensor_.params().kind == LoadSensorKind::kNone) {
    fb.load = load_sensor_.step(0.0, 0.0);  // NaN: no sensor (and no truth computed for it)
  } else {
    const PlantTruth truth = plant_.truth();
    fb.load = load_sensor_.step(truth.state.load_position_m, truth.load_accel_mps2);
  }
  return fb;
}

void SimulatedDrive::apply_force(double force_request_n) {
  for (int i = 0; i < current_steps_per_tick_; ++i) {
    const CurrentControllerOutput u =
        current_.step({force_request_n, last_measurement_.i_d_a, last_measurement_.i_q_a, last_velocity_mps_});
    apply_voltage(u.u_d_v, u.u_q_v);
  }
}

void SimulatedDrive::apply_voltage(double u_d_v, double u_q_v) {
  last_measurement_ = plant_.step(PlantInput{u_d_v, u_q_v, 0.0}, current_period_s_);
  last_u_d_v_ = u_d_v;
  last_u_q_v_ = u_q_v;
}

SimulatedDriveBackend::SimulatedDriveBackend(const SystemParams& params, const PlantInitialCondition& initial,
                                             const drive::PowerStateParams& power)
    : drive_(params, initial), power_(power), motor_constant_n_per_a_(params.plant.electrical.motor_constant_n_per_a) {
  power_.step();  // initialisation done: not ready to switch on -> switch on disabled (transition 1)
}

void SimulatedDriveBackend::check_plant() {
  const PlantDivergence& d = drive_.plant().divergence();
  if (!d.diverged) return;
  if (fault_detail_[0] == '\0') {
    std::snprintf(fault_detail_, sizeof fault_detail_,
                  "plant state %s = %.6g (not finite or beyond any motor) in tick %llu", d.state, d.value,
                  static_cast<unsigned long long>(ticks_ == 0 ? 0 : ticks_ - 1));
  }
  power_.fault(drive::kErrorPlantDiverged);  // ignored while already faulted
}

drive::Measurement SimulatedDriveBackend::sample() {
  ++ticks_;
  check_plant();
  power_.step();
  const DriveFeedback fb = drive_.sample();
  drive::Measurement m;
  m.position_m = fb.encoder_position_m;
  m.velocity_mps = fb.velocity_mps;
  m.i_d_a = fb.i_d_a;
  m.i_q_a = fb.i_q_a;
  m.thrust_force_n = motor_constant_n_per_a_ * fb.i_q_a;
  m.load_position_m = fb.load.position_m;
  m.load_acceleration_mps2 = fb.load.acceleration_mps2;
  m.load_sensor_saturated = fb.load.saturated;
  return m;
}

void SimulatedDriveBackend::apply(double force_n) {
  drive_.apply_force(power_.force_allowed() ? force_n : 0.0);
  check_plant();
}

}  // namespace pmlsm

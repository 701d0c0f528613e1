#include "msg_mapping.hpp"

#include <cmath>
#include <limits>

namespace pmlsm::node {
namespace {

namespace feedback_flags = pmlsm_msgs::msg::MotorFeedback_Constants;
namespace power = pmlsm_msgs::msg::DriveState_Constants;
// The loop's status bits are the message's.
static_assert(drive::status::kSafeState == feedback_flags::STATUS_SAFE_STATE);
static_assert(drive::status::kCommandLate == feedback_flags::STATUS_COMMAND_LATE);
static_assert(drive::status::kWatchdogTripped == feedback_flags::STATUS_WATCHDOG_TRIPPED);
static_assert(drive::status::kSimulated == feedback_flags::STATUS_SIMULATED);
static_assert(drive::status::kFault == feedback_flags::STATUS_FAULT);
static_assert(drive::status::kForeignCommand == feedback_flags::STATUS_FOREIGN_COMMAND);
static_assert(drive::status::kLoadSensorSaturated == feedback_flags::STATUS_LOAD_SENSOR_SATURATED);
static_assert(static_cast<int>(drive::PowerState::kOperationEnabled) == power::POWER_OPERATION_ENABLED);
static_assert(static_cast<int>(drive::PowerState::kFault) == power::POWER_FAULT);
static_assert(static_cast<int>(drive::PowerState::kSwitchOnDisabled) == power::POWER_SWITCH_ON_DISABLED);

/// MotorFeedback's load fields as the drive's reading holds them: NaN in what the kind says is not
/// measured, the saturation from the status bit.
LoadSensorReading load_reading_of(const pmlsm_msgs::msg::MotorFeedback& in) {
  constexpr double kNotMeasured = std::numeric_limits<double>::quiet_NaN();
  return {in.load_sensor() == feedback_flags::LOAD_SENSOR_ENCODER ? in.load_position_m() : kNotMeasured,
          in.load_sensor() == feedback_flags::LOAD_SENSOR_ACCELEROMETER ? in.load_acceleration_mps2() : kNotMeasured,
          (in.status() & feedback_flags::STATUS_LOAD_SENSOR_SATURATED) != 0};
}

}  // namespace

namespace msg = pmlsm_msgs::msg;

// run_validity.hpp keeps the constants as plain numbers (no generated code there): they must
// be the IDL's.
static_assert(kFeedbackStatusSafeState == msg::MotorFeedback_Constants::STATUS_SAFE_STATE);
static_assert(kFeedbackStatusFault == msg::MotorFeedback_Constants::STATUS_FAULT);
static_assert(kPowerOperationEnabled == msg::DriveState_Constants::POWER_OPERATION_ENABLED);
static_assert(kPowerFaultReactionActive == msg::DriveState_Constants::POWER_FAULT_REACTION_ACTIVE);
static_assert(kPowerFault == msg::DriveState_Constants::POWER_FAULT);

// ---- PlantTruth ---------------------------------------------------------------------------

void to_msg(const PlantTruth& truth, const PlantAppliedInputs& applied, msg::PlantTruth& out) {
  const PlantState& s = truth.state;
  out.motor_position_m(s.motor_position_m);
  out.motor_velocity_mps(s.motor_velocity_mps);
  out.motor_acceleration_mps2(truth.motor_accel_mps2);
  out.load_position_m(s.load_position_m);
  out.load_velocity_mps(s.load_velocity_mps);
  out.load_acceleration_mps2(truth.load_accel_mps2);
  out.spring_force_n(truth.spring_force_n);
  out.thrust_force_n(truth.thrust_n);
  out.ripple_force_n(truth.ripple_n);
  out.friction_force_n(truth.friction_n);
  out.command_force_n(applied.command_force_n);
  out.psi_d_wb(s.psi_d_wb);
  out.psi_q_wb(s.psi_q_wb);
  out.psi_damper_d_wb(s.psi_dd_wb);
  out.psi_damper_q_wb(s.psi_qq_wb);
  out.i_d_a(truth.i_d_a);
  out.i_q_a(truth.i_q_a);
  out.i_damper_d_a(truth.i_dd_a);
  out.i_damper_q_a(truth.i_qq_a);
  out.u_d_v(applied.u_d_v);
  out.u_q_v(applied.u_q_v);
}

void from_msg(const msg::PlantTruth& in, PlantTruth& truth, PlantAppliedInputs& applied) {
  PlantState& s = truth.state;
  s.motor_position_m = in.motor_position_m();
  s.motor_velocity_mps = in.motor_velocity_mps();
  truth.motor_accel_mps2 = in.motor_acceleration_mps2();
  s.load_position_m = in.load_position_m();
  s.load_velocity_mps = in.load_velocity_mps();
  truth.load_accel_mps2 = in.load_acceleration_mps2();
  truth.spring_force_n = in.spring_force_n();
  truth.thrust_n = in.thrust_force_n();
  truth.ripple_n = in.ripple_force_n();
  truth.friction_n = in.friction_force_n();
  applied.command_force_n = in.command_force_n();
  s.psi_d_wb = in.psi_d_wb();
  s.psi_q_wb = in.psi_q_wb();
  s.psi_dd_wb = in.psi_damper_d_wb();
  s.psi_qq_wb = in.psi_damper_q_wb();
  truth.i_d_a = in.i_d_a();
  truth.i_q_a = in.i_q_a();
  truth.i_dd_a = in.i_damper_d_a();
  truth.i_qq_a = in.i_damper_q_a();
  applied.u_d_v = in.u_d_v();
  applied.u_q_v = in.u_q_v();
}

void from_msg(const msg::PlantTruth& in, TickRecord& rec) {
  PlantTruth truth;
  PlantAppliedInputs applied;
  from_msg(in, truth, applied);
  record_truth(truth, rec);  // the same fields as the in-process loop's record
  rec.u_q_v = applied.u_q_v;
}

// ---- MotorFeedback ------------------------------------------------------------------------

void from_msg(const msg::MotorFeedback& in, TickRecord& rec) {
  rec.encoder_position_m = in.position_m();
  rec.motor_velocity_measured_mps = in.velocity_mps();
  rec.applied_force_n = in.applied_force_n();
  const LoadSensorReading load = load_reading_of(in);
  rec.load_position_measured_m = load.position_m;
  rec.load_accel_measured_mps2 = load.acceleration_mps2;
  DriveTickStatus status;
  from_msg(in, status);
  rec.force_off = !force_applied(status);
}

void from_msg(const msg::MotorFeedback& in, KalmanInput& out) {
  out.motor_velocity_measured_mps = in.velocity_mps();
  out.thrust_previous_n = in.applied_force_n();
  out.motor_position_m = in.position_m();
  const LoadSensorReading load = load_reading_of(in);
  out.load_position_m = load.position_m;
  out.load_accel_mps2 = load.acceleration_mps2;
  out.load_sensor_saturated = load.saturated;
}

LoadWitness load_witness(const msg::MotorFeedback& in) { return {in.position_m(), load_reading_of(in)}; }

void from_msg(const msg::MotorFeedback& in, DriveTickStatus& out) {
  out.status = in.status();
  out.power_state = in.power_state();
  out.error_code = in.error_code();
}

// ---- VelocityReference, ForceCommand ------------------------------------------------------

void to_msg(const VelocityControllerOutput& control, std::uint64_t parameters_version, msg::VelocityReference& out) {
  out.velocity_command_mps(control.command_mps);
  out.v_ref_mps(control.v_ref_mps);
  out.a_ref_mps2(control.a_ref_mps2);
  out.parameters_version(parameters_version);
}

void from_msg(const msg::VelocityReference& in, TickRecord& rec) {
  rec.command_mps = in.velocity_command_mps();
  rec.v_ref_mps = in.v_ref_mps();
  rec.a_ref_mps2 = in.a_ref_mps2();
}

void to_msg(const VelocityControllerOutput& control, double compensation_force_n, std::uint64_t feedback_tick,
            msg::ForceCommand& out) {
  out.feedback_tick(feedback_tick);
  out.force_n(control.force_n);
  out.pi_force_n(control.force_n - compensation_force_n);
  out.compensation_force_n(compensation_force_n);
  out.velocity_error_mps(control.velocity_error_mps);
  out.saturated(control.saturated);
  out.v_ref_mps(control.v_ref_mps + control.position.correction_mps);
  out.x_ref_m(control.x_ref_m);
}

void from_msg(const msg::ForceCommand& in, TickRecord& rec) {
  rec.force_command_n = in.force_n();
  rec.compensation_force_n = in.compensation_force_n();
}

// ---- EstimatedState -----------------------------------------------------------------------

namespace estimate_flags = msg::EstimatedState_Constants;
static_assert(static_cast<int>(LoadSensorUse::kNotUsed) == estimate_flags::LOAD_SENSOR_NOT_USED);
static_assert(static_cast<int>(LoadSensorUse::kUsed) == estimate_flags::LOAD_SENSOR_USED);
static_assert(static_cast<int>(LoadSensorUse::kRefused) == estimate_flags::LOAD_SENSOR_REFUSED);
static_assert(static_cast<int>(LoadSensorUse::kFailed) == estimate_flags::LOAD_SENSOR_FAILED);
static_assert(static_cast<int>(LoadSensorFault::kNone) == estimate_flags::LOAD_FAULT_NONE);
static_assert(static_cast<int>(LoadSensorFault::kSilent) == estimate_flags::LOAD_FAULT_SILENT);
static_assert(static_cast<int>(LoadSensorFault::kSaturated) == estimate_flags::LOAD_FAULT_SATURATED);
static_assert(static_cast<int>(LoadSensorFault::kJumping) == estimate_flags::LOAD_FAULT_JUMPING);
static_assert(static_cast<int>(LoadSensorFault::kStuck) == estimate_flags::LOAD_FAULT_STUCK);

namespace {
/// A LOAD_FAULT_* value off the wire; one past the last reads as none (a newer sender's fault is
/// still a refusal: load_sensor_use says so).
LoadSensorFault load_fault_of(std::uint8_t value) {
  return value <= estimate_flags::LOAD_FAULT_STUCK ? static_cast<LoadSensorFault>(value) : LoadSensorFault::kNone;
}
}  // namespace

void to_msg(const KalmanEstimate& estimate, std::uint64_t feedback_tick, msg::EstimatedState& out) {
  out.feedback_tick(feedback_tick);
  out.v_motor_mps(estimate.motor_velocity_mps);
  out.v_load_mps(estimate.load_velocity_mps);
  out.spring_force_n(estimate.spring_force_n);
  out.a_load_mps2(estimate.load_accel_mps2);
  out.input_force_n(estimate.input_force_n);
  out.innovation_mps(estimate.innovation_mps);
  auto& p = out.covariance_diag();
  for (int i = 0; i < 3; ++i) p[static_cast<std::size_t>(i)] = estimate.covariance_diag(i);
  out.load_sensor_use(static_cast<std::uint8_t>(load_sensor_use(estimate)));
  out.load_sensor_fault(static_cast<std::uint8_t>(estimate.load_sensor_problem));
  out.accelerometer_bias_mps2(estimate.accelerometer_bias_mps2);
}

void from_msg(const msg::EstimatedState& in, KalmanEstimate& out) {
  out.motor_velocity_mps = in.v_motor_mps();
  out.load_velocity_mps = in.v_load_mps();
  out.spring_force_n = in.spring_force_n();
  out.load_accel_mps2 = in.a_load_mps2();
  out.input_force_n = in.input_force_n();
  out.innovation_mps = in.innovation_mps();
  const auto& p = in.covariance_diag();
  for (int i = 0; i < 3; ++i) out.covariance_diag(i) = p[static_cast<std::size_t>(i)];
  out.load_measurement_used = in.load_sensor_use() == estimate_flags::LOAD_SENSOR_USED;
  out.load_sensor_failed = in.load_sensor_use() == estimate_flags::LOAD_SENSOR_FAILED;
  out.load_sensor_problem = load_fault_of(in.load_sensor_fault());
  out.accelerometer_bias_mps2 = in.accelerometer_bias_mps2();
}

void from_msg(const msg::EstimatedState& in, TickRecord& rec) {
  rec.est_motor_velocity_mps = in.v_motor_mps();
  rec.est_load_velocity_mps = in.v_load_mps();
  rec.est_spring_force_n = in.spring_force_n();
  rec.est_load_accel_mps2 = in.a_load_mps2();
  rec.load_sensor_use = in.load_sensor_use() <= estimate_flags::LOAD_SENSOR_FAILED
                            ? static_cast<LoadSensorUse>(in.load_sensor_use())
                            : LoadSensorUse::kRefused;
  rec.load_sensor_fault = load_fault_of(in.load_sensor_fault());
}

// ---- drive messages -----------------------------------------------------------------------

void to_msg(const drive::TickReport& r, pmlsm_msgs::msg::MotorFeedback& out) {
  out.position_m(r.measurement.position_m);
  out.velocity_mps(r.measurement.velocity_mps);
  out.i_d_a(r.measurement.i_d_a);
  out.i_q_a(r.measurement.i_q_a);
  out.thrust_force_n(r.measurement.thrust_force_n);
  out.applied_force_n(r.applied_force_n);
  out.applied_command_tick(r.applied_command_tick);
  out.status(r.status);
  out.power_state(static_cast<std::uint8_t>(r.power_state));
  out.error_code(r.error_code);
  // The load's sensor: NaN in the measurement is "not measured", on the wire the kind and a 0.
  const bool position = std::isfinite(r.measurement.load_position_m);
  const bool acceleration = std::isfinite(r.measurement.load_acceleration_mps2);
  out.load_sensor(position       ? feedback_flags::LOAD_SENSOR_ENCODER
                  : acceleration ? feedback_flags::LOAD_SENSOR_ACCELEROMETER
                                 : feedback_flags::LOAD_SENSOR_NONE);
  out.load_position_m(position ? r.measurement.load_position_m : 0.0);
  out.load_acceleration_mps2(acceleration ? r.measurement.load_acceleration_mps2 : 0.0);
}

void from_msg(const pmlsm_msgs::msg::MotorFeedback& in, drive::Measurement& out) {
  out.position_m = in.position_m();
  out.velocity_mps = in.velocity_mps();
  out.i_d_a = in.i_d_a();
  out.i_q_a = in.i_q_a();
  out.thrust_force_n = in.thrust_force_n();
  out.applied_force_n = in.applied_force_n();
  const LoadSensorReading load = load_reading_of(in);
  out.load_position_m = load.position_m;
  out.load_acceleration_mps2 = load.acceleration_mps2;
  out.load_sensor_saturated = load.saturated;
}

drive::ForceCommandIn from_msg(const pmlsm_msgs::msg::ForceCommand& c, std::uint64_t writer,
                               std::int64_t received_wall_ns) {
  drive::ForceCommandIn in;
  in.run_id = c.stamp().run_id();
  in.feedback_tick = c.feedback_tick();
  in.force_n = c.force_n();
  in.writer_id = writer;
  in.received_wall_ns = received_wall_ns;
  in.feedforward_force_n = c.compensation_force_n();
  in.velocity_mps = c.v_ref_mps();
  in.position_m = c.x_ref_m();
  return in;
}

void to_msg(const CompensatorStep& step, std::uint32_t mode_flags, std::uint64_t estimate_tick,
            std::uint64_t weights_version, pmlsm_msgs::msg::CompensatorOutput& out) {
  namespace Flags = pmlsm_msgs::msg::CompensatorOutput_Constants;
  std::uint32_t flags = mode_flags;
  if (step.weights_updated) flags |= Flags::FLAG_WEIGHTS_UPDATED;
  if (step.kc_guarded) flags |= Flags::FLAG_KC_CLAMPED;
  if (step.input_rejected) flags |= Flags::FLAG_INPUT_STALE;
  out.force_n(step.force_n);
  out.u_n(step.u_n);
  out.training_error_mps(step.training_error_mps);
  out.k_c_mps(step.k_c_mps);
  out.flags(flags);
  out.estimate_tick(estimate_tick);
  out.weights_version(weights_version);
}

void to_msg(const drive::Drive& drive, const drive::DriveLoop& loop, std::uint64_t refused_requests,
            pmlsm_msgs::msg::DriveState& out) {
  out.power_state(static_cast<std::uint8_t>(drive.power_state()));
  out.statusword(drive::statusword_of(drive.power_state()));
  out.error_code(drive.error_code());
  out.refused_requests(refused_requests);
  out.safe_ticks(loop.counters().safe_ticks);
  out.watchdog_armed(loop.watchdog_armed());
  out.faults(drive.fault_count());
}

}  // namespace pmlsm::node

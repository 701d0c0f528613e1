// The one place where messages (pmlsm_msgs::msg, generated from idl/) and the pure domain
// structs of common/ meet. Every field copy between the two goes through here, so a renamed or
// added field is mapped once, and the IDL names that differ from the domain's are paired here:
//
//   PlantTruth (IDL)             pmlsm::PlantTruth / TickRecord
//   motor_acceleration_mps2      motor_accel_mps2
//   load_acceleration_mps2       load_accel_mps2
//   thrust_force_n               thrust_n
//   ripple_force_n               ripple_n
//   friction_force_n             friction_n
//   psi_damper_d_wb, _q_wb       state.psi_dd_wb, state.psi_qq_wb
//   i_damper_d_a, _q_a           i_dd_a, i_qq_a
//   MotorFeedback.position_m     TickRecord::encoder_position_m, KalmanInput::motor_position_m
//   MotorFeedback.velocity_mps   TickRecord::motor_velocity_measured_mps,
//                                KalmanInput::motor_velocity_measured_mps
//   MotorFeedback.applied_force_n  KalmanInput::thrust_previous_n (u_{k-1})
//   VelocityReference.velocity_command_mps  command_mps
//   ForceCommand.force_n         VelocityControllerOutput::force_n, TickRecord::force_command_n,
//                                drive::ForceCommandIn::force_n
//   MotorFeedback.load_sensor, load_position_m, load_acceleration_mps2
//                                drive::Measurement::load_* (NaN: not measured), KalmanInput::load_*
//   ForceCommand.compensation_force_n  drive::ForceCommandIn::feedforward_force_n
//   ForceCommand.v_ref_mps, x_ref_m    drive::ForceCommandIn::velocity_mps, position_m
//   EstimatedState.v_motor_mps / v_load_mps / a_load_mps2  motor_velocity_mps /
//                                load_velocity_mps / load_accel_mps2 (est_* in TickRecord)
//   EstimatedState.accelerometer_bias_mps2  KalmanEstimate::accelerometer_bias_mps2
//
// None of these touches the Stamp: the caller stamps what it publishes (tick, times, run_id)
// and reads the stamp of what it takes. They do not allocate: each runs once per tick.
#pragma once

#include <cstdint>

#include "EstimatedState.h"
#include "CompensatorOutput.h"
#include "DriveState.h"
#include "ForceCommand.h"
#include "MotorFeedback.h"
#include "PlantTruth.h"
#include "VelocityReference.h"
#include "pmlsm/drive/drive_loop.hpp"
#include "pmlsm/estimation/kalman_filter.hpp"
#include "pmlsm/plant/plant.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/velocity_controller.hpp"
#include "run_validity.hpp"

namespace pmlsm::node {

// ---- PlantTruth ---------------------------------------------------------------------------

/// What PlantTruth carries besides pmlsm::PlantTruth: what the drive applied to the plant.
struct PlantAppliedInputs {
  double command_force_n = 0;  ///< force command in effect (zero-order hold) [N]
  double u_d_v = 0;            ///< the current loop's last d-axis voltage [V]
  double u_q_v = 0;            ///< the current loop's last q-axis voltage [V]
};

/// Every field but the stamp.
void to_msg(const PlantTruth& truth, const PlantAppliedInputs& applied, pmlsm_msgs::msg::PlantTruth& out);
void from_msg(const pmlsm_msgs::msg::PlantTruth& in, PlantTruth& truth, PlantAppliedInputs& applied);
/// The true-plant fields of a record, as the in-process loop fills them (record_truth), and
/// u_q_v, the last q-axis voltage of the previous tick.
void from_msg(const pmlsm_msgs::msg::PlantTruth& in, TickRecord& rec);

// ---- MotorFeedback ------------------------------------------------------------------------

/// encoder_position_m and motor_velocity_measured_mps.
void from_msg(const pmlsm_msgs::msg::MotorFeedback& in, TickRecord& rec);
/// The filter's input for this tick: y_k = velocity_mps, u_{k-1} = applied_force_n (the force
/// the drive applied over the last tick), x_k = position_m.
void from_msg(const pmlsm_msgs::msg::MotorFeedback& in, KalmanInput& out);
/// status, power_state, error_code: what RunValidity judges.
void from_msg(const pmlsm_msgs::msg::MotorFeedback& in, DriveTickStatus& out);
/// The load sensor's reading with the motor's position (position_m), the standstill gate's
/// witness of the load.
LoadWitness load_witness(const pmlsm_msgs::msg::MotorFeedback& in);

/// Every field but the stamp, from the drive loop's report of the tick.
void to_msg(const drive::TickReport& report, pmlsm_msgs::msg::MotorFeedback& out);
/// The drive's reading of the tick (the measurement in to_msg's report), for a tool that drives
/// the force itself (`pmlsm commission` on a live drive).
void from_msg(const pmlsm_msgs::msg::MotorFeedback& in, drive::Measurement& out);

// ---- DriveState ---------------------------------------------------------------------------
/// power_state, statusword, error_code, refused_requests, safe_ticks, watchdog_armed, faults
/// (stamp, drive name and the request fields are the caller's).
void to_msg(const drive::Drive& drive, const drive::DriveLoop& loop, std::uint64_t refused_requests,
            pmlsm_msgs::msg::DriveState& out);

// ---- VelocityReference, ForceCommand (the controller's output) ----------------------------

/// velocity_command_mps, v_ref_mps, a_ref_mps2, and the live-parameter version the tick was computed with.
void to_msg(const VelocityControllerOutput& control, std::uint64_t parameters_version,
            pmlsm_msgs::msg::VelocityReference& out);
/// command_mps, v_ref_mps and a_ref_mps2.
void from_msg(const pmlsm_msgs::msg::VelocityReference& in, TickRecord& rec);

/// force_n, pi_force_n (= force_n - compensation_force_n: the PI's part), compensation_force_n,
/// velocity_error_mps, saturated, and feedback_tick (the MotorFeedback tick it answers).
void to_msg(const VelocityControllerOutput& control, double compensation_force_n, std::uint64_t feedback_tick,
            pmlsm_msgs::msg::ForceCommand& out);
/// force_command_n and compensation_force_n.
void from_msg(const pmlsm_msgs::msg::ForceCommand& in, TickRecord& rec);
/// The drive loop's arbitration input: the stamp's run_id, feedback_tick, force_n, with the
/// writer and the reception time the caller read from the sample's info.
drive::ForceCommandIn from_msg(const pmlsm_msgs::msg::ForceCommand& in, std::uint64_t writer_id,
                               std::int64_t received_wall_ns);

// ---- CompensatorOutput -----------------------------------------------------------------------

/// A compensator's answer to estimate tick k: the step's force_n, u_n, training_error_mps and
/// k_c_mps; flags: `mode_flags` (FLAG_ENABLED, FLAG_ONLINE_LEARNING) and the step's own (weights
/// updated, k_c clamped, input stale); estimate_tick and weights_version. Every field but the stamp.
void to_msg(const CompensatorStep& step, std::uint32_t mode_flags, std::uint64_t estimate_tick,
            std::uint64_t weights_version, pmlsm_msgs::msg::CompensatorOutput& out);

// ---- EstimatedState -----------------------------------------------------------------------

/// Every field but the stamp; feedback_tick: the MotorFeedback tick the update used.
void to_msg(const KalmanEstimate& estimate, std::uint64_t feedback_tick, pmlsm_msgs::msg::EstimatedState& out);
/// All of KalmanEstimate but measurement_used, which the message does not carry (left as is).
void from_msg(const pmlsm_msgs::msg::EstimatedState& in, KalmanEstimate& out);
/// est_motor_velocity_mps, est_load_velocity_mps, est_spring_force_n, est_load_accel_mps2.
void from_msg(const pmlsm_msgs::msg::EstimatedState& in, TickRecord& rec);

}  // namespace pmlsm::node

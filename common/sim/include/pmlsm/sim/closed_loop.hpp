// The whole control cascade in one process, without DDS: the reference model,
// the encoder velocity, the Kalman filter, the velocity PI (1 ms) and the
// drive's current loop (31.25 us) around the nonlinear plant (10 us RK4).
// The distributed nodes run these same components; this loop is their
// reference trace.
//
// One tick k (t_k = k T):
//   1. read the encoder and the currents of the plant at t_k;
//   2. v_M,meas = encoder difference; V_ref = reference model (command c(t_k));
//   3. Kalman step with y = v_M,meas and u = the force applied over the last tick (plus the
//      modelled friction and ripple when the filter is configured with them);
//   4. force F_k = velocity PI(V_ref, v_M,meas, compensation);
//   5. 32 current-loop periods: voltages from the current controller, plant integrated.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "pmlsm/estimation/kalman_filter.hpp"
#include "pmlsm/sim/scenario.hpp"
#include "pmlsm/sim/simulated_drive.hpp"
#include "pmlsm/sim/system_params.hpp"
#include "pmlsm/sim/velocity_controller.hpp"

namespace pmlsm {

/// What happened at one control tick: the state at t_k and the commands computed at t_k.
struct TickRecord {
  std::uint64_t tick = 0;
  double time_s = 0;
  double command_mps = 0;  ///< command c(t_k) into the reference model (after input shaping)
  double v_ref_mps = 0;    ///< reference model output
  double a_ref_mps2 = 0;   ///< its derivative dV_ref/dt
  double encoder_position_m = 0;
  double motor_velocity_measured_mps = 0;
  double motor_position_m = 0;    ///< true
  double motor_velocity_mps = 0;  ///< true
  double load_position_m = 0;     ///< true
  double load_velocity_mps = 0;   ///< true
  double load_accel_mps2 = 0;     ///< true
  double spring_force_n = 0;      ///< true F_s
  double est_motor_velocity_mps = 0;
  double est_load_velocity_mps = 0;
  double est_spring_force_n = 0;
  double est_load_accel_mps2 = 0;
  double force_command_n = 0;       ///< velocity loop output F_k (PI + compensation, limited)
  double compensation_force_n = 0;  ///< compensator force added to the PI output at t_k (after the guard)
  bool guard_tripped = false;       ///< the vibration guard has taken the compensation out (latched)
  double thrust_n = 0;              ///< true F_dx at t_k
  double ripple_n = 0;
  double friction_n = 0;
  double i_q_a = 0;
  double u_q_v = 0;            ///< last q-axis voltage of the previous tick
  double applied_force_n = 0;  ///< force the drive applied during the previous tick (MotorFeedback's)
  bool force_off = false;      ///< the drive had its force off at t_k (fault, safe state, not enabled)
  /// The load's sensor as the drive read it at t_k (NaN: not measured) and what the filter did with it.
  double load_position_measured_m = std::numeric_limits<double>::quiet_NaN();
  double load_accel_measured_mps2 = std::numeric_limits<double>::quiet_NaN();
  LoadSensorUse load_sensor_use = LoadSensorUse::kNotUsed;
  LoadSensorFault load_sensor_fault = LoadSensorFault::kNone;  ///< why refused, or why it failed
  /// Set from the tick whose integration diverged on (PlantDivergence): the plant
  /// entry that left the numbers and its value. The loop applies zero force from the
  /// next tick and the plant stays at its last good state: the run is not valid.
  const char* plant_fault_state = nullptr;
  double plant_fault_value = 0;
};

/// "plant state <name> = <value> (not finite or beyond any motor) at tick k: zero force
/// from tick k+1", or "" when no record of the trace has a plant fault.
std::string plant_fault_reason(const std::vector<TickRecord>& trace);

/// "the load's sensor failed at tick k (t = X s): <why>; the estimate from then on is the motor
/// side's alone", or "" when no record has it failed. A run asked for with a load sensor that lost
/// it is not the run asked for: the results table marks it, the exit code is not 0.
std::string load_sensor_failure_reason(const std::vector<TickRecord>& trace);

class ClosedLoop {
 public:
  /// @throws std::invalid_argument from any component or the scenario.
  ClosedLoop(const SystemParams& params, const Scenario& scenario);
  /// Starts from `initial` instead of the scenario's initial condition.
  ClosedLoop(const SystemParams& params, const Scenario& scenario, const PlantInitialCondition& initial);

  /// Runs one control tick and returns its record. The compensation's force is
  /// added to the PI output inside its saturation (the hybrid controller, Fig. 4).
  TickRecord step(const Compensation& compensation = {});

  std::uint64_t tick() const { return tick_; }
  std::uint64_t total_ticks() const { return total_ticks_; }
  bool done() const { return tick_ >= total_ticks_; }

  const Plant& plant() const { return drive_.plant(); }
  const SimulatedDrive& drive() const { return drive_; }
  const VelocityController& controller() const { return controller_; }
  const KalmanFilter& kalman() const { return kalman_; }

 private:
  SystemParams params_;
  Scenario scenario_;
  SimulatedDrive drive_;
  VelocityController controller_;
  KalmanFilter kalman_;
  std::uint64_t tick_ = 0;
  std::uint64_t total_ticks_ = 0;
  double last_force_n_ = 0;
};

/// Ticks in a scenario: duration / control period.
std::uint64_t scenario_ticks(const Scenario& scenario, double control_period_s);

/// The initial condition a scenario sets.
PlantInitialCondition scenario_initial_condition(const Scenario& scenario);

/// Fills the true-plant fields of a record from the plant at t_k.
void record_truth(const PlantTruth& truth, TickRecord& rec);

/// Runs a scenario to its end; the trace is reserved up front (no allocation per tick).
std::vector<TickRecord> run_scenario(const SystemParams& params, const Scenario& scenario);

/// What a compensator sees of tick k: the Kalman estimate and V_ref (never the true plant).
/// (EstimatedState and VelocityReference of tick k carry every field.)
struct CompensatorView {
  double load_accel_mps2 = 0;  ///< a_L estimate, eq. (36)
  double v_ref_mps = 0;
  double v_load_mps = 0;      ///< estimated load velocity (the paper's V_load)
  double spring_force_n = 0;  ///< estimated spring force F_s
  double command_mps = 0;     ///< command c(t_k) into the reference model (after input shaping)
  double a_ref_mps2 = 0;      ///< dV_ref/dt
};
inline CompensatorView compensator_view(const TickRecord& rec) {
  return {rec.est_load_accel_mps2, rec.v_ref_mps,   rec.est_load_velocity_mps,
          rec.est_spring_force_n,  rec.command_mps, rec.a_ref_mps2};
}
/// The part of the view acceleration feedback takes (the in-process loop and the node alike).
inline AccelFeedbackInput accel_feedback_input(const CompensatorView& view) {
  return {view.load_accel_mps2, view.a_ref_mps2};
}
/// The part of the view the RNN takes (the in-process loop and the node alike).
inline CompensatorInput rnn_input(const CompensatorView& view) {
  return {view.load_accel_mps2, view.v_ref_mps, view.v_load_mps, view.a_ref_mps2, view.command_mps};
}
/// The part of the view state feedback takes (the in-process loop and the node alike).
inline StateFeedbackInput state_feedback_input(const CompensatorView& view) {
  return {view.command_mps, view.v_ref_mps, view.a_ref_mps2, view.v_load_mps, view.spring_force_n};
}

/// Runs up to max_ticks ticks of a scenario with a compensator in the loop. The
/// compensator works on tick k's estimate and its force is applied at tick k+1:
/// the one-tick delay of the distributed system, where the estimator and the
/// compensator run while the plant integrates tick k (1 ms, 3.7 degrees at the
/// 10.2 Hz load mode), so they never lengthen the plant-controller chain.
/// compensate: Compensation(const CompensatorView&): the force [N] and its share of the compensator's range.
template <typename Compensate>
std::vector<TickRecord> run_compensated(const SystemParams& params, const Scenario& scenario, Compensate&& compensate,
                                        std::uint64_t max_ticks = UINT64_MAX) {
  ClosedLoop loop(params, scenario);
  std::vector<TickRecord> trace;
  const std::uint64_t ticks = std::min(loop.total_ticks(), max_ticks);
  trace.reserve(ticks);
  Compensation compensation;
  while (trace.size() < ticks) {
    trace.push_back(loop.step(compensation));
    compensation = compensate(compensator_view(trace.back()));
  }
  return trace;
}

}  // namespace pmlsm

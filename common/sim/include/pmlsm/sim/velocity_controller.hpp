// The motor-side controller of one control tick: the scenario's raw command, input-shaped when
// the scenario asks (ZV, ZVD, EI timed to the loop's mode), shaped by the reference model (25)
// into V_ref (or taken as V_ref when the scenario bypasses the model), and the velocity PI with the
// compensator's force added inside its saturation (the hybrid controller,
// Fig. 4), with the filter slots (filters.* of the system file) on the compensator's force and on
// the force command. The controller node and the in-process loop both run it.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>

#include "pmlsm/control/biquad.hpp"
#include "pmlsm/control/external_reference.hpp"
#include "pmlsm/control/input_shaper.hpp"
#include "pmlsm/control/position_loop.hpp"
#include "pmlsm/control/reference_model.hpp"
#include "pmlsm/sim/scenario.hpp"
#include "pmlsm/sim/system_params.hpp"
#include "pmlsm/control/velocity_pi.hpp"
#include "pmlsm/estimation/load_sensor_monitor.hpp"
#include "pmlsm/plant/load_sensor.hpp"

namespace pmlsm {

/// What a compensator hands the velocity loop for one tick: its force, and how much of its own
/// range that is, |F_c| / F_c,max in [0, 1] (the RNN's |u_n|, a clamped law's |F_c| / its limit;
/// CompensatorOutput.u_n on DDS), by which the vibration guard knows a saturated compensator.
struct Compensation {
  double force_n = 0;
  double output_share = 0;
};

/// A compensator's force and its output u_n (CompensatorOutput.u_n, |u_n| <= 1 of its range):
/// the share is |u_n|. The in-process loops and the controller node map it here alike.
inline Compensation compensation_from_output(double force_n, double u_n) { return {force_n, std::fabs(u_n)}; }

/// A law clamped to +-force_limit_n: its output is F_c / limit (as the compensator nodes' u_n).
inline Compensation clamped_compensation(double force_n, double force_limit_n) {
  return compensation_from_output(force_n, force_n / force_limit_n);
}

/// A tick's load sensor reading with the motor encoder's position of the same tick: the position
/// loop's feedback (position_loop.closes_on) and the standstill gate's witness of the load
/// (x_M - x_L of a load encoder; (m_L / k) a_L of an accelerometer, low-passed at the load's
/// mode), once the controller's own
/// LoadSensorMonitor believes it. The monitor is the estimator's, on the same readings, so the
/// two agree tick by tick without a word on the wire: a reading the filter refuses, or a sensor
/// it has failed (a count stuck during a move, then a swing at rest it cannot see), is no
/// witness either, and the gate judges the motor's side alone (the position loop closes on the
/// motor's encoder).
struct LoadWitness {
  double motor_position_m = std::numeric_limits<double>::quiet_NaN();
  LoadSensorReading reading;  ///< NaN in what the sensor does not measure
};

struct VelocityControllerOutput {
  double command_mps = 0;  ///< the command c(t_k) into the reference model, after input shaping
  double v_ref_mps = 0;
  double a_ref_mps2 = 0;
  /// x_ref,k = T sum_{j<k} V_ref,j: where the motor should be at this tick's start, from the
  /// controller's start (a drive closing position follows its motion) [m].
  double x_ref_m = 0;
  /// The position loop's (position_loop.closes_on; 0 without it): the PI follows V_ref + this.
  PositionLoopOutput position;
  double force_n = 0;             ///< force request after the limit
  double velocity_error_mps = 0;  ///< the PI's: V_ref + the position loop's correction - v_M
  bool saturated = false;
  /// The compensation added: the request times the guard's and the standstill gate's scales.
  double compensation_applied_n = 0;
  VibrationGuardOutput guard;
  StandstillGateOutput standstill;
};

class VelocityController {
 public:
  /// @throws std::invalid_argument from the parameters or the scenario.
  VelocityController(const SystemParams& params, const Scenario& scenario);
  /// Tick k with the scenario's command c(t_k); `load`: the load sensor's reading of the tick
  /// (none: the gate judges the motor alone).
  VelocityControllerOutput step(std::uint64_t tick, double motor_velocity_mps, const Compensation& compensation,
                                const LoadWitness& load = {});
  /// A tick with a command from elsewhere (an external scenario: the setpoints' command).
  VelocityControllerOutput step_command(double command_mps, double motor_velocity_mps, const Compensation& compensation,
                                        const LoadWitness& load = {});
  /// The live parameters (LiveParameters) at a tick boundary: the PI's gains and limit (its
  /// integral kept), each filter chain rebuilt from rest when its slots changed (unchanged
  /// chains keep their state), and the input shaper retimed when the loop's mode moved with the
  /// gains (SystemParams::input_shaper_params; its past commands kept). The rest of `params` is
  /// not looked at.
  /// @throws std::invalid_argument from the components (LiveParameters has checked them before).
  void retune(const SystemParams& params);
  const VelocityPi& velocity_pi() const { return velocity_; }
  const ReferenceModel& reference() const { return reference_; }
  /// The input shaper (nullptr when the scenario has none).
  const InputShaper* input_shaper() const { return shaper_ ? &*shaper_ : nullptr; }
  /// The guard in the compensation path (nullptr when compensator.guard.enabled is false).
  const VibrationGuard* guard() const { return guard_ ? &*guard_ : nullptr; }
  /// The standstill gate (nullptr when compensator.standstill.enabled is false).
  const StandstillGate* standstill_gate() const { return standstill_ ? &*standstill_ : nullptr; }
  const PositionLoop& position_loop() const { return position_; }
  /// The judge of the load sensor's readings for the gate and the position loop (nullptr without a
  /// load sensor, or with neither a gate nor a position loop on the load).
  const LoadSensorMonitor* load_sensor_monitor() const { return load_monitor_ ? &*load_monitor_ : nullptr; }

 private:
  Scenario scenario_;
  double period_s_;
  ReferenceModel reference_;
  std::optional<InputShaper> shaper_;
  double last_command_mps_ = 0;  ///< without the reference model: c(t_{k-1})
  bool have_last_command_ = false;
  double x_ref_m_ = 0;  ///< x_ref of the next tick
  PositionLoop position_;
  VelocityPi velocity_;
  std::optional<VibrationGuard> guard_;
  std::optional<StandstillGate> standstill_;
  std::optional<LoadSensorMonitor> load_monitor_;  ///< with a load sensor and a gate or a load loop
  std::optional<Biquad> accel_witness_;            ///< an accelerometer's reading, low-passed at w_L
  std::optional<Biquad> accel_mode_notch_;         ///< a full notch at w_L: the reading less it, band-passed
  double stretch_per_accel_s2_ = 0;                ///< m_L / k of the filter's model
  std::uint64_t steps_ = 0;                        ///< the monitor's tick
  FilterChain compensation_filters_;               ///< on the compensator's force, before the PI adds it
  FilterChain force_filters_;                      ///< on the PI's output, then the force limit again
};

/// An external scenario's setpoint policy at the control period.
ExternalReferenceParams external_reference_params(const Scenario& scenario, double control_period_s);

}  // namespace pmlsm

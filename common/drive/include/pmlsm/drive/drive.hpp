// The seam between the drive loop and a drive backend (ros2_control's hardware interface, for
// one servo axis): the loop owns timing, command arbitration, the watchdog and statistics; a
// backend measures, applies a force and runs (or mirrors) the drive's CiA 402 power state
// machine. SimulatedDrive (common/sim) is one backend; a CANopen bridge to a real drive is
// another. The controller on the other side of the bus cannot tell them apart.
#pragma once

#include <cstdint>
#include <limits>

#include "pmlsm/drive/power_state.hpp"

namespace pmlsm::drive {

/// What a drive measures at the start of a control tick.
struct Measurement {
  double position_m = 0;      ///< motor position from the encoder (quantised) [m]
  double velocity_mps = 0;    ///< encoder difference over the last tick [m/s]
  double i_d_a = 0;           ///< measured d-axis current [A]
  double i_q_a = 0;           ///< measured q-axis current [A]
  double thrust_force_n = 0;  ///< thrust from the currents, K_m i_q (eq. 14) [N]
  /// The force the drive held over the tick before this reading, as it reports it (a command
  /// that came late leaves the one before in force; a drive closing its own loops: their force)
  /// [N]; NaN when the reading does not say (the caller knows what it applied).
  double applied_force_n = std::numeric_limits<double>::quiet_NaN();
  /// A sensor on the load beside the motor's encoder (a second encoder, CiA 402 0x60E4, or an
  /// accelerometer), read at the tick's start: NaN in what the drive does not measure.
  double load_position_m = std::numeric_limits<double>::quiet_NaN();
  double load_acceleration_mps2 = std::numeric_limits<double>::quiet_NaN();
  bool load_sensor_saturated = false;  ///< the accelerometer at its rail
};

/// What the controller asks of the drive for one period, in every form a drive may take it. A
/// drive in cyclic synchronous torque (and the simulation) applies `force_n`. A drive that closes
/// its own velocity loop (CiA 402's cyclic synchronous velocity) follows `velocity_mps` with
/// `feedforward_force_n` added inside its loop, where the controller adds the compensator's force
/// inside its PI (Fig. 4); one that closes position too (cyclic synchronous position) follows
/// `position_m`, `velocity_mps` its velocity offset.
struct Setpoint {
  double force_n = 0;              ///< the force: the velocity PI's and the compensation's [N]
  double feedforward_force_n = 0;  ///< the part a drive's own velocity loop adds (the compensation) [N]
  double velocity_mps = 0;         ///< the velocity reference V_ref the PI followed [m/s]
  double position_m = 0;           ///< V_ref's integral since the controller's start [m]
};

/// A drive backend. Called from the loop thread only; no call may block past its tick, throw
/// or allocate.
class Drive {
 public:
  virtual ~Drive() = default;

  /// Once per tick, first: the readings at the tick's start; the power state machine's
  /// automatic transitions (fault reaction done, quick stop done) happen here.
  virtual Measurement sample() = 0;
  /// Once per tick, last: hold `force_n` for one control period. The backend applies it
  /// only in operation enabled (zero force in every other state, whatever is asked).
  virtual void apply(double force_n) = 0;
  /// As apply(), with the whole setpoint, for a backend that closes loops itself (its
  /// Measurement::applied_force_n then says what force its loops applied). The rest apply the force.
  virtual void apply_setpoint(const Setpoint& setpoint) { apply(setpoint.force_n); }
  /// An operator's or supervisor's request to the power state machine.
  virtual TransitionResult request(DriveCommand command) = 0;
  /// A fault the loop detected (watchdog, a command that cannot be applied): transition 13,
  /// latched until fault reset. The backend keeps the first code while faulted.
  virtual void fault(std::uint16_t error_code) = 0;
  virtual PowerState power_state() const = 0;
  /// The last fault's code (CiA 402 object 0x603F), 0 when there was none.
  virtual std::uint16_t error_code() const = 0;
  /// Faults since start (entries into fault reaction active).
  virtual std::uint64_t fault_count() const = 0;
  /// True for a simulation (MotorFeedback's STATUS_SIMULATED bit).
  virtual bool simulated() const = 0;
  /// The backend's own account of the last fault it raised itself ("" when none), e.g. the
  /// simulation's diverged plant state; faults the loop raises are reported by the loop.
  virtual const char* fault_detail() const { return ""; }
};

/// Error codes of faults the drive loop raises (CiA 301 / 402 error code classes).
/// 0x8130 "life guard or heartbeat error": the controller stopped answering.
inline constexpr std::uint16_t kErrorCommandTimeout = 0x8130;
/// 0x6100 "internal software": the simulated plant's state left the numbers (not finite or
/// beyond any motor); the backend stays faulted, a fault reset cannot clear it.
inline constexpr std::uint16_t kErrorPlantDiverged = 0x6100;

}  // namespace pmlsm::drive

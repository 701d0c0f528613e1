// The drive's application behind a CiA 402 dictionary, whatever carries the dictionary's objects
// (CANopen PDOs and SDOs, EtherCAT process data and CoE): a controlword written is decoded with
// decode_controlword(previous) and requested from the drive's power state machine; a period steps
// the drive with the force of the mode 0x6060 names (applied in operation enabled only) and writes
// back the statusword, the error code and register, the mode displayed, the actual position,
// velocity and torque (the force the current loop produces, K_f i_q), the torque demand (the force
// the period applied), the load's sensor where the drive has one (0x60E4:1 a load encoder's
// position, 0x2003 an accelerometer's reading) and the periods stepped. A fault sets the drive's
// fault (force zero) and asks the carrier for its emergency (CANopen's EMCY, EtherCAT's CoE
// emergency); a fault reset and enable clear it, with the emergency 0x0000. Pure: no bus, no clock
// (times are given), never throws after construction.
//
// The force of a period, by mode (CiA 402-2's cyclic synchronous modes; targets and offsets in
// the dictionary's units, scaled; x and v the drive's encoder reading at the period's start):
//   cst (10)  F = target torque 0x6071 + torque offset 0x60B2
//   csv (9)   F = PI(0x60FF + 0x60B1 - v) + 0x60B2                      the drive's velocity loop
//   csp (8)   F = PI(Kp_x (0x607A - x) + 0x60B1 - v) + 0x60B2          and its position loop
// PI is VelocityPi (Table 3's law, the offset inside its saturation, as the compensator's force is
// in the controller's). Its integral starts from zero on entering operation enabled and at a mode
// change, so a mode switched in operation (CiA 402 allows it) does not inherit the other's state.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "pmlsm/canopen/object_dictionary.hpp"
#include "pmlsm/canopen/scaling.hpp"
#include "pmlsm/control/velocity_pi.hpp"
#include "pmlsm/drive/drive.hpp"

namespace pmlsm::canopen {

// The lockstep contract's manufacturer objects, whatever the bus (configs/canopen/virtual_drive_od.yaml
// declares them): the periods the drive stepped, and the tick of the command written for the next.
inline constexpr std::uint16_t kObjectPeriodsStepped = 0x2001;
inline constexpr std::uint16_t kObjectCommandTick = 0x2002;
// A manufacturer object of the virtual drive's (configs/canopen/virtual_drive_od.yaml): the load's
// acceleration from an accelerometer on it [um/s^2], the accelerometer's counterpart of CiA 402's
// additional position 0x60E4 (a load encoder's), which has no standard object.
inline constexpr std::uint16_t kObjectLoadAcceleration = 0x2003;
/// 0x2003's unit: um/s^2 (a 32-bit value spans +-2147 m/s^2, 219 g).
inline constexpr double kLoadAccelerationPerUnit = 1e-6;

/// The loops a drive closes itself in the velocity and position modes: its own tuning (a real
/// drive's is set in its vendor's tool; the virtual drives take the system file's velocity loop).
struct DriveOwnLoopsParams {
  /// The velocity PI, its period the drive's cycle (0x60C2).
  VelocityPiParams velocity;
  /// Kp_x: position error to velocity command [1/s]. > 0, finite.
  double position_gain_per_s = 100.0;
  /// @throws std::invalid_argument naming the field and value.
  void validate() const;
  /// A drive tuned as the controller is: its velocity PI `pi` run at the drive's `period_s`.
  static DriveOwnLoopsParams like_controller(const VelocityPiParams& pi, double period_s);
};

struct Cia402ApplicationParams {
  /// Target torque per mille -> newtons, metres and m/s -> increments.
  ScalingConfig scaling;
  /// Fault 0x5000 (device hardware) when this many periods are stepped.
  std::optional<std::uint64_t> inject_fault_at_period;
  /// The drive's own loops; without them the drive is torque only (its dictionary's 0x6502 must
  /// then offer cst alone, which make_cia402_dictionary's default does).
  std::optional<DriveOwnLoopsParams> own_loops;
};

/// What the application asks of its carrier. Called from the application's calls.
class Cia402ApplicationEvents {
 public:
  virtual ~Cia402ApplicationEvents() = default;
  /// A line for the log: a state change (error false) or a fault or refusal (error true).
  virtual void log(bool error, const std::string& line, std::int64_t now_ns) = 0;
  /// The emergency the carrier sends for `code` (0x0000: the errors are gone).
  virtual void emergency(std::uint16_t code) = 0;
};

class Cia402Application {
 public:
  /// `dictionary`, `drive` and `events` outlive the application. Writes the live objects once.
  /// @throws std::invalid_argument for a scaling UnitScaling refuses, own loops that are not
  /// valid, or a dictionary whose 0x6502 offers velocity or position without own loops.
  Cia402Application(const Cia402ApplicationParams& params, ObjectDictionary& dictionary, drive::Drive& drive,
                    Cia402ApplicationEvents& events);

  /// The controlword (0x6040) was written: the command it makes, requested of the drive.
  void apply_controlword(std::int64_t now_ns);
  /// One period with the force of the mode (see the file comment); the live objects written back.
  void step_period(std::int64_t now_ns);
  /// The drive faults with `code` (the first cause is kept): force off, the emergency sent.
  void raise_fault(std::uint16_t code, const std::string& why, std::int64_t now_ns);
  /// The live objects from the drive's state and last measurement.
  void update_objects();
  /// Forgets the last controlword (a reset of the device): the next one is read afresh.
  void forget_controlword() { previous_controlword_ = 0; }

  std::uint64_t periods() const { return periods_; }
  bool enabled() const { return drive_.power_state() == drive::PowerState::kOperationEnabled; }
  double applied_force_n() const { return applied_force_n_; }
  /// When the drive last entered operation enabled (the start of its watchdogs).
  std::int64_t enabled_since_ns() const { return enabled_since_ns_; }
  void set_enabled_since_ns(std::int64_t now_ns) { enabled_since_ns_ = now_ns; }
  const UnitScaling& scaling() const { return scaling_; }
  /// The mode the last period ran in (0x6061's value then).
  std::int8_t mode() const { return mode_; }

 private:
  /// The force of the mode (see the file comment) from the dictionary's targets and the last
  /// reading; steps the velocity PI in the velocity and position modes.
  double commanded_force();

  Cia402ApplicationParams params_;
  UnitScaling scaling_;
  ObjectDictionary& od_;
  drive::Drive& drive_;
  Cia402ApplicationEvents& events_;
  drive::Measurement measurement_;
  std::optional<VelocityPi> velocity_loop_;
  std::int8_t mode_ = 0;
  bool was_enabled_ = false;
  double applied_force_n_ = 0.0;
  std::uint64_t periods_ = 0;
  std::uint16_t previous_controlword_ = 0;
  bool injected_ = false;
  std::int64_t enabled_since_ns_ = 0;
};

}  // namespace pmlsm::canopen

// The drive's application behind a CiA 402 dictionary, whatever carries the dictionary's objects
// (CANopen PDOs and SDOs, EtherCAT process data and CoE): a controlword written is decoded with
// decode_controlword(previous) and requested from the drive's power state machine; a period steps
// the drive with the target torque (per mille of the rated force -> newtons, applied in operation
// enabled only) and writes back the statusword, the error code and register, the mode displayed,
// the actual position, velocity and torque (the force the current loop produces, K_f i_q) and the
// periods stepped. A fault sets the drive's fault (force zero) and asks the carrier for its
// emergency (CANopen's EMCY, EtherCAT's CoE emergency); a fault reset and enable clear it, with
// the emergency 0x0000. Pure: no bus, no clock (times are given), never throws after construction.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "pmlsm/canopen/object_dictionary.hpp"
#include "pmlsm/canopen/scaling.hpp"
#include "pmlsm/drive/drive.hpp"

namespace pmlsm::canopen {

// The lockstep contract's manufacturer objects, whatever the bus (configs/canopen/virtual_drive_od.yaml
// declares them): the periods the drive stepped, and the tick of the command written for the next.
inline constexpr std::uint16_t kObjectPeriodsStepped = 0x2001;
inline constexpr std::uint16_t kObjectCommandTick = 0x2002;

struct Cia402ApplicationParams {
  /// Target torque per mille -> newtons, metres and m/s -> increments.
  ScalingConfig scaling;
  /// Fault 0x5000 (device hardware) when this many periods are stepped.
  std::optional<std::uint64_t> inject_fault_at_period;
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
  /// @throws std::invalid_argument for a scaling UnitScaling refuses.
  Cia402Application(const Cia402ApplicationParams& params, ObjectDictionary& dictionary, drive::Drive& drive,
                    Cia402ApplicationEvents& events);

  /// The controlword (0x6040) was written: the command it makes, requested of the drive.
  void apply_controlword(std::int64_t now_ns);
  /// One period with the target torque (0x6071); the live objects written back.
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

 private:
  double commanded_force() const;

  Cia402ApplicationParams params_;
  UnitScaling scaling_;
  ObjectDictionary& od_;
  drive::Drive& drive_;
  Cia402ApplicationEvents& events_;
  drive::Measurement measurement_;
  double applied_force_n_ = 0.0;
  std::uint64_t periods_ = 0;
  std::uint16_t previous_controlword_ = 0;
  bool injected_ = false;
  std::int64_t enabled_since_ns_ = 0;
};

}  // namespace pmlsm::canopen

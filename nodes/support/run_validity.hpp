// Whether a run's results may be presented as valid: the decision and its
// reason text, from what the drive reported every tick (MotorFeedback's
// status bits, power state and error code). No DDS here: the evaluator feeds
// it the fields of each MotorFeedback, the tests feed it numbers.
//
// A tick is bad when the drive had its force off or was not following the
// force command: STATUS_SAFE_STATE or STATUS_FAULT set, or a power state other
// than operation enabled. One bad tick makes the whole run invalid (its metrics
// measure the drive's stopping, not the controller).
//
// A run is also unusable when the drive restarted in the middle of it (a new
// Stamp.run_id): RunIdTracker notices that.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace pmlsm::node {

// The MotorFeedback / DriveState constants this decision uses, as plain numbers so that this
// file needs no generated code; msg_mapping.cpp checks them against the IDL at compile time.
inline constexpr std::uint32_t kFeedbackStatusSafeState = 1;  ///< MotorFeedback_Constants::STATUS_SAFE_STATE
inline constexpr std::uint32_t kFeedbackStatusFault = 128;    ///< MotorFeedback_Constants::STATUS_FAULT
inline constexpr std::uint8_t kPowerOperationEnabled = 4;     ///< DriveState_Constants::POWER_OPERATION_ENABLED
inline constexpr std::uint8_t kPowerFaultReactionActive = 6;  ///< DriveState_Constants::POWER_FAULT_REACTION_ACTIVE
inline constexpr std::uint8_t kPowerFault = 7;                ///< DriveState_Constants::POWER_FAULT

/// The CiA 402 name of a DriveState_Constants::POWER_* value ("operation enabled", "fault",
/// ...; "unknown" outside 0..7).
const char* power_state_name(std::uint8_t power_state) noexcept;

/// What the drive reported about itself at one tick (MotorFeedback's status, power_state,
/// error_code).
struct DriveTickStatus {
  std::uint32_t status = 0;      ///< MotorFeedback_Constants::STATUS_* bits
  std::uint8_t power_state = 0;  ///< DriveState_Constants::POWER_*
  std::uint16_t error_code = 0;  ///< last fault's error code (0x603F), 0: none
};

/// True when the drive applied the command at this tick: no safe state, no fault, operation
/// enabled.
bool force_applied(const DriveTickStatus& s) noexcept;

/// Collects every tick's drive status and gives the verdict. Ticks may come in any order;
/// each tick should be added once. add() is allocation-free (it runs per tick).
class RunValidity {
 public:
  void add(std::uint64_t tick, const DriveTickStatus& s) noexcept;

  bool valid() const noexcept { return bad_ticks_ == 0; }
  std::uint64_t ticks() const noexcept { return ticks_; }
  std::uint64_t bad_ticks() const noexcept { return bad_ticks_; }
  /// The first bad tick (meaningful when !valid()).
  std::uint64_t first_bad_tick() const noexcept { return first_bad_; }
  /// The error code of the earliest bad tick that had one (0: none).
  std::uint16_t error_code() const noexcept { return error_code_; }

  /// Empty when valid, else why not, e.g.
  ///   "drive force off for 1998 ticks from tick 2 (fault 0x8130, power state fault)"
  ///   "drive force off for 3 ticks, ticks 10..40 (safe state)"
  /// "from tick F" when the bad ticks are contiguous, "ticks F..L" when not. In the
  /// parentheses: "fault 0xXXXX" (the earliest bad tick's error code; "fault" without one)
  /// when a bad tick had STATUS_FAULT or a fault power state; else "safe state" when one had
  /// STATUS_SAFE_STATE and "last error 0xXXXX" when one carried an error code (an earlier
  /// fault's, since reset); then "power state <name>" of the earliest bad tick not in
  /// operation enabled.
  std::string reason() const;

 private:
  std::uint64_t ticks_ = 0;
  std::uint64_t bad_ticks_ = 0;
  std::uint64_t first_bad_ = 0;
  std::uint64_t last_bad_ = 0;
  bool any_fault_ = false;
  bool any_safe_state_ = false;
  std::uint16_t error_code_ = 0;
  std::uint64_t error_code_tick_ = 0;
  bool any_power_off_ = false;
  std::uint8_t power_state_ = 0;  // of the earliest bad tick not in operation enabled
  std::uint64_t power_state_tick_ = 0;
};

/// A change of run: the drive restarted (new Stamp.run_id) while the run was being collected.
struct RunChange {
  std::uint64_t from_run = 0;
  std::uint64_t to_run = 0;
  std::uint64_t tick = 0;  ///< stamp tick of the first sample of the new run
};

/// Remembers the first non-zero run_id seen and reports the first sample with another one.
/// run_id 0 (a node that follows no run yet) is ignored.
class RunIdTracker {
 public:
  /// The change, if this sample belongs to another run than the first one seen.
  std::optional<RunChange> observe(std::uint64_t run_id, std::uint64_t tick) noexcept;
  /// The first non-zero run_id seen (0: none yet).
  std::uint64_t run_id() const noexcept { return run_id_; }

 private:
  std::uint64_t run_id_ = 0;
};

/// "evaluator: the drive restarted (run 0000000000001a2b -> 0000000000003c4d) at its tick 812:
/// results would mix two runs; none written" (no newline), with `program` in place of
/// "evaluator"; the run ids as 16 hex digits, as the controller prints them.
std::string restart_message(const char* program, const RunChange& change);

}  // namespace pmlsm::node

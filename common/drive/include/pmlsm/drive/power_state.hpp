// The drive's power state machine after CiA 402 (IEC 61800-7-201, "device control" FSA):
// states, commands, the statusword (object 0x6041) and controlword (0x6040) codings, and a
// PowerStateMachine that a drive (real-drive bridge or plant simulator) runs once per control
// tick. Pure C++17, no DDS.
//
// Transition numbers are the standard's:
//   0  start -> not ready to switch on (power on)        automatic
//   1  not ready to switch on -> switch on disabled     automatic (initialisation done)
//   2  switch on disabled -> ready to switch on         shutdown
//   3  ready to switch on -> switched on                switch on
//   4  switched on -> operation enabled                 enable operation
//   5  operation enabled -> switched on                 disable operation
//   6  switched on -> ready to switch on                shutdown
//   7  ready to switch on -> switch on disabled         disable voltage or quick stop
//   8  operation enabled -> ready to switch on          shutdown
//   9  operation enabled -> switch on disabled          disable voltage
//   10 switched on -> switch on disabled                disable voltage or quick stop
//   11 operation enabled -> quick stop active           quick stop
//   12 quick stop active -> switch on disabled          quick stop completed, or disable voltage
//   13 any state -> fault reaction active               fault detected
//   14 fault reaction active -> fault                   automatic (fault reaction completed)
//   15 fault -> switch on disabled                      fault reset
//   16 quick stop active -> operation enabled           enable operation (only when the quick
//                                                       stop does not end in switch on disabled)
//
// Only operation enabled may command force. Quick stop active and fault reaction active still
// drive the power stage, but only to decelerate (the drive's own stopping ramp), never to follow
// a setpoint.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace pmlsm::drive {

// ---- object dictionary indices ------------------------------------------------------------

inline constexpr std::uint16_t kObjectErrorCode = 0x603F;
inline constexpr std::uint16_t kObjectControlword = 0x6040;
inline constexpr std::uint16_t kObjectStatusword = 0x6041;

/// 0x603F "generic error": stored by fault() in place of 0, which the standard's error code
/// table reserves for "no error".
inline constexpr std::uint16_t kErrorCodeGeneric = 0x1000;

// ---- states and commands ------------------------------------------------------------------

enum class PowerState : std::uint8_t {
  kNotReadyToSwitchOn,
  kSwitchOnDisabled,
  kReadyToSwitchOn,
  kSwitchedOn,
  kOperationEnabled,
  kQuickStopActive,
  kFaultReactionActive,
  kFault,
};

inline constexpr int kPowerStateCount = 8;

/// The standard's name in lower case: "not ready to switch on", "switch on disabled",
/// "ready to switch on", "switched on", "operation enabled", "quick stop active",
/// "fault reaction active", "fault" ("unknown" for a value outside the enum).
const char* to_string(PowerState state) noexcept;

enum class DriveCommand : std::uint8_t {
  kShutdown,
  kSwitchOn,
  kEnableOperation,
  kDisableOperation,
  kDisableVoltage,
  kQuickStop,
  kFaultReset,
};

inline constexpr int kDriveCommandCount = 7;

/// "shutdown", "switch on", "enable operation", "disable operation", "disable voltage",
/// "quick stop", "fault reset" ("unknown" for a value outside the enum).
const char* to_string(DriveCommand command) noexcept;

/// The names of to_string(DriveCommand), ASCII case-insensitive, with '-', '_' or ' ' between
/// the words ("enable-operation", "quick_stop", "Fault Reset"); nullopt for anything else.
std::optional<DriveCommand> parse_drive_command(std::string_view text) noexcept;

// ---- statusword (0x6041) ------------------------------------------------------------------

inline constexpr std::uint16_t kStatusReadyToSwitchOn = 1U << 0;
inline constexpr std::uint16_t kStatusSwitchedOn = 1U << 1;
inline constexpr std::uint16_t kStatusOperationEnabled = 1U << 2;
inline constexpr std::uint16_t kStatusFault = 1U << 3;
inline constexpr std::uint16_t kStatusVoltageEnabled = 1U << 4;
/// Active low: 1 = not in quick stop, 0 = quick stop active.
inline constexpr std::uint16_t kStatusQuickStop = 1U << 5;
inline constexpr std::uint16_t kStatusSwitchOnDisabled = 1U << 6;
inline constexpr std::uint16_t kStatusWarning = 1U << 7;
inline constexpr std::uint16_t kStatusRemote = 1U << 9;
inline constexpr std::uint16_t kStatusTargetReached = 1U << 10;
inline constexpr std::uint16_t kStatusInternalLimitActive = 1U << 11;

/// The state's bits (0-3, 5, 6) with the standard's "x" bits clear, plus bit 4 when
/// voltage_enabled (high voltage present at the drive, a measurement the caller supplies) and
/// bit 9 when remote (the controlword is obeyed). E.g. operation enabled -> 0x0237.
std::uint16_t statusword_of(PowerState state, bool voltage_enabled = true, bool remote = true) noexcept;

/// The state the statusword shows, by the standard's masks over bits 0-3, 5 and 6 (all other
/// bits - voltage enabled, warning, remote, target reached, ... - are ignored):
///   not ready to switch on  0x004F / 0x0000     switch on disabled     0x004F / 0x0040
///   ready to switch on      0x006F / 0x0021     switched on            0x006F / 0x0023
///   operation enabled       0x006F / 0x0027     quick stop active      0x006F / 0x0007
///   fault reaction active   0x004F / 0x000F     fault                  0x004F / 0x0008
/// The masks are disjoint; nullopt for a word no state shows (e.g. 0x0001).
std::optional<PowerState> decode_statusword(std::uint16_t statusword) noexcept;

// ---- controlword (0x6040) -----------------------------------------------------------------

inline constexpr std::uint16_t kControlSwitchOn = 1U << 0;
inline constexpr std::uint16_t kControlEnableVoltage = 1U << 1;
/// Active low: 0 = quick stop requested.
inline constexpr std::uint16_t kControlQuickStop = 1U << 2;
inline constexpr std::uint16_t kControlEnableOperation = 1U << 3;
inline constexpr std::uint16_t kControlFaultReset = 1U << 7;
inline constexpr std::uint16_t kControlHalt = 1U << 8;

/// The standard's command coding: shutdown 0x0006, switch on 0x0007, enable operation 0x000F,
/// disable operation 0x0007 (the same as switch on), disable voltage 0x0000, quick stop 0x0002,
/// fault reset 0x0080 (acts on the rising edge of bit 7, so the master sends it after a word
/// with bit 7 clear).
std::uint16_t controlword_of(DriveCommand command) noexcept;

/// The command a controlword carries, given the previous controlword the drive received:
///   fault reset         bit 7 rising (0 in previous, 1 now); takes precedence over the rest
///   disable voltage     mask 0x0082 / 0x0000
///   quick stop          mask 0x0086 / 0x0002
///   shutdown            mask 0x0087 / 0x0006
///   switch on           mask 0x008F / 0x0007  (also "disable operation", see below)
///   enable operation    mask 0x008F / 0x000F
/// Bit 7 held high after its rising edge is ignored (taken as 0), so a master that keeps the
/// fault reset bit set is decoded by bits 0-3: 0x0080 after 0x0080 is disable voltage.
/// "Switch on" and "disable operation" share the code 0x0007: this returns kSwitchOn, and
/// PowerStateMachine::request(kSwitchOn) in operation enabled performs disable operation
/// (transition 5), which is what 0x0007 means there.
/// The masks cover every combination of bits 0-3, so with the bit 7 rule every word decodes
/// to a command; bits 4-6 and 8-15 (operation-mode bits, halt, manufacturer bits) are ignored.
std::optional<DriveCommand> decode_controlword(std::uint16_t controlword, std::uint16_t previous_controlword) noexcept;

// ---- the state machine --------------------------------------------------------------------

struct PowerStateParams {
  /// Ticks the fault reaction (the drive's stopping ramp) lasts before fault (transition 14).
  /// >= 1.
  std::uint32_t fault_reaction_ticks = 1;
  /// Ticks the quick stop ramp lasts before switch on disabled (transition 12), when
  /// quick_stop_to_switch_on_disabled. >= 1 (checked even when unused).
  std::uint32_t quick_stop_ticks = 1;
  /// true: quick stop active ends by itself in switch on disabled (0x605A quick stop option
  /// codes 1-4); false: the drive stays in quick stop active until disable voltage (12) or
  /// enable operation (16) (option codes 5-8).
  bool quick_stop_to_switch_on_disabled = true;
};

struct TransitionResult {
  bool accepted = false;
  PowerState from = PowerState::kNotReadyToSwitchOn;
  PowerState to = PowerState::kNotReadyToSwitchOn;  // == from when nothing changed
  int transition = 0;                               // CiA 402 transition number, 0 if none
  const char* reason = "";                          // static text, never null
};

/// One drive's power state machine. Construction validates the parameters and may throw;
/// everything after that is noexcept and allocation-free (it runs inside the 1 kHz loop).
class PowerStateMachine {
 public:
  /// @throws std::invalid_argument naming the field and its value, e.g.
  ///         "fault_reaction_ticks: must be >= 1, got 0".
  explicit PowerStateMachine(PowerStateParams params = {});

  /// Once per control tick: completes the automatic transitions.
  ///   not ready to switch on -> switch on disabled on the first step (1);
  ///   fault reaction active -> fault after fault_reaction_ticks steps in it (14);
  ///   quick stop active -> switch on disabled after quick_stop_ticks steps in it, when
  ///   quick_stop_to_switch_on_disabled (12).
  void step() noexcept;

  /// Applies a master's command (CiA 402 transitions 2-12, 15, 16). Besides the standard:
  ///   - enable operation in ready to switch on goes straight to operation enabled (3 and 4 in
  ///     one, as many real drives accept; reported as transition 4);
  ///   - switch on in operation enabled is disable operation (5): both are controlword 0x0007.
  /// A command whose target state is the current state is accepted with transition 0 and no
  /// change (enable operation in operation enabled, shutdown in ready to switch on, switch on
  /// or disable operation in switched on, disable voltage / quick stop / fault reset in switch
  /// on disabled, quick stop in quick stop active): repeating a cyclic command is not an error.
  /// Anything else is refused: no change, refused_count() grows, reason says why.
  /// Not ready to switch on and fault reaction active refuse every command; fault refuses all
  /// but fault reset.
  TransitionResult request(DriveCommand command) noexcept;

  /// A fault detected (transition 13, from any state but fault reaction active and fault):
  /// enters fault reaction active, stores the 0x603F-style error code (kErrorCodeGeneric in
  /// place of 0) and counts the fault. A fault while already in fault reaction active or fault
  /// changes nothing: the first cause is kept and a persisting fault reported every tick is
  /// counted once.
  void fault(std::uint16_t error_code) noexcept;

  PowerState state() const noexcept { return state_; }
  /// The error code of the latest fault (0 if none yet). Like 0x603F ("last error"), it is kept
  /// after fault reset; statusword bit 3 tells whether the drive is faulted now.
  std::uint16_t error_code() const noexcept { return error_code_; }
  /// Number of entries into fault reaction active (transition 13).
  std::uint64_t fault_count() const noexcept { return fault_count_; }
  /// Number of refused requests.
  std::uint64_t refused_count() const noexcept { return refused_count_; }

  /// Force (a setpoint) may be applied: operation enabled only.
  bool force_allowed() const noexcept { return state_ == PowerState::kOperationEnabled; }
  /// The power stage is switched on (it produces force): operation enabled, and quick stop
  /// active and fault reaction active, where it only brakes the motor to standstill.
  bool power_stage_enabled() const noexcept;
  /// High voltage may be applied to the drive (main contactor closed): from ready to switch on
  /// up to operation enabled, and during quick stop and fault reaction. Not in not ready to
  /// switch on or switch on disabled (the standard forbids it there), nor in fault (application
  /// dependent in the standard; here the fault drops it).
  bool high_voltage_allowed() const noexcept;

  /// statusword_of(state(), voltage_enabled, remote). voltage_enabled is the measured DC bus,
  /// which this machine does not know.
  std::uint16_t statusword(bool voltage_enabled = true, bool remote = true) const noexcept {
    return statusword_of(state_, voltage_enabled, remote);
  }

  const PowerStateParams& params() const noexcept { return params_; }

 private:
  TransitionResult move(PowerState to, int transition) noexcept;
  TransitionResult stay(const char* reason, bool accepted) noexcept;

  PowerStateParams params_;
  PowerState state_ = PowerState::kNotReadyToSwitchOn;
  std::uint32_t ticks_in_state_ = 0;  // steps since entering the state (bounded by the params)
  std::uint16_t error_code_ = 0;
  std::uint64_t fault_count_ = 0;
  std::uint64_t refused_count_ = 0;
};

/// The command a master sends next to walk a drive from `state` to operation enabled:
///   fault -> fault reset, switch on disabled -> shutdown, ready to switch on -> switch on,
///   switched on -> enable operation, quick stop active -> disable voltage (12, allowed whatever
///   quick_stop_to_switch_on_disabled is; the walk goes on from switch on disabled);
///   operation enabled (there), not ready to switch on and fault reaction active (wait for the
///   automatic transition) -> nullopt.
std::optional<DriveCommand> next_command_towards_operation_enabled(PowerState state) noexcept;

}  // namespace pmlsm::drive

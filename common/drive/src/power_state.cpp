// CiA 402 power state machine; see power_state.hpp for the transitions.
#include "pmlsm/drive/power_state.hpp"

#include <stdexcept>
#include <string>

namespace pmlsm::drive {
namespace {

constexpr const char* kReasonTransition = "transition taken";
constexpr const char* kReasonAlreadyThere = "already in the requested state";
constexpr const char* kReasonNotAllowed = "not allowed in this state";
constexpr const char* kReasonInitialising = "drive is initialising (not ready to switch on)";
constexpr const char* kReasonFaultReaction = "fault reaction in progress";
constexpr const char* kReasonFault = "only fault reset leaves fault";
constexpr const char* kReasonQuickStopEnds = "quick stop ends in switch on disabled (transition 16 not enabled)";

struct StatusPattern {
  PowerState state;
  std::uint16_t mask;
  std::uint16_t value;
};

// The standard's statusword masks (bits 0-3, 6; bit 5 where it tells quick stop apart).
constexpr StatusPattern kStatusPatterns[] = {
    {PowerState::kNotReadyToSwitchOn, 0x004F, 0x0000},  {PowerState::kSwitchOnDisabled, 0x004F, 0x0040},
    {PowerState::kReadyToSwitchOn, 0x006F, 0x0021},     {PowerState::kSwitchedOn, 0x006F, 0x0023},
    {PowerState::kOperationEnabled, 0x006F, 0x0027},    {PowerState::kQuickStopActive, 0x006F, 0x0007},
    {PowerState::kFaultReactionActive, 0x004F, 0x000F}, {PowerState::kFault, 0x004F, 0x0008},
};

char ascii_lower(char c) noexcept { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c; }

// `text` equals `name` (lower case, words separated by single spaces), case-insensitively and
// with '-', '_' or ' ' standing for each space.
bool matches_name(std::string_view text, std::string_view name) noexcept {
  if (text.size() != name.size()) return false;
  for (std::size_t i = 0; i < name.size(); ++i) {
    const char c = text[i];
    if (name[i] == ' ') {
      if (c != ' ' && c != '-' && c != '_') return false;
    } else if (ascii_lower(c) != name[i]) {
      return false;
    }
  }
  return true;
}

void require_at_least_one(const char* name, std::uint32_t value) {
  if (value < 1) {
    throw std::invalid_argument(std::string(name) + ": must be >= 1, got " + std::to_string(value));
  }
}

}  // namespace

const char* to_string(PowerState state) noexcept {
  switch (state) {
    case PowerState::kNotReadyToSwitchOn: return "not ready to switch on";
    case PowerState::kSwitchOnDisabled: return "switch on disabled";
    case PowerState::kReadyToSwitchOn: return "ready to switch on";
    case PowerState::kSwitchedOn: return "switched on";
    case PowerState::kOperationEnabled: return "operation enabled";
    case PowerState::kQuickStopActive: return "quick stop active";
    case PowerState::kFaultReactionActive: return "fault reaction active";
    case PowerState::kFault: return "fault";
  }
  return "unknown";
}

const char* to_string(DriveCommand command) noexcept {
  switch (command) {
    case DriveCommand::kShutdown: return "shutdown";
    case DriveCommand::kSwitchOn: return "switch on";
    case DriveCommand::kEnableOperation: return "enable operation";
    case DriveCommand::kDisableOperation: return "disable operation";
    case DriveCommand::kDisableVoltage: return "disable voltage";
    case DriveCommand::kQuickStop: return "quick stop";
    case DriveCommand::kFaultReset: return "fault reset";
  }
  return "unknown";
}

std::optional<DriveCommand> parse_drive_command(std::string_view text) noexcept {
  for (int i = 0; i < kDriveCommandCount; ++i) {
    const auto command = static_cast<DriveCommand>(i);
    if (matches_name(text, to_string(command))) return command;
  }
  return std::nullopt;
}

std::uint16_t statusword_of(PowerState state, bool voltage_enabled, bool remote) noexcept {
  std::uint16_t word = 0;
  for (const auto& pattern : kStatusPatterns) {
    if (pattern.state == state) word = pattern.value;
  }
  if (voltage_enabled) word |= kStatusVoltageEnabled;
  if (remote) word |= kStatusRemote;
  return word;
}

std::optional<PowerState> decode_statusword(std::uint16_t statusword) noexcept {
  for (const auto& pattern : kStatusPatterns) {
    if ((statusword & pattern.mask) == pattern.value) return pattern.state;
  }
  return std::nullopt;
}

std::uint16_t controlword_of(DriveCommand command) noexcept {
  switch (command) {
    case DriveCommand::kShutdown: return 0x0006;
    case DriveCommand::kSwitchOn: return 0x0007;
    case DriveCommand::kEnableOperation: return 0x000F;
    case DriveCommand::kDisableOperation: return 0x0007;
    case DriveCommand::kDisableVoltage: return 0x0000;
    case DriveCommand::kQuickStop: return 0x0002;
    case DriveCommand::kFaultReset: return 0x0080;
  }
  return 0x0000;  // out-of-range value: the safe word (disable voltage)
}

std::optional<DriveCommand> decode_controlword(std::uint16_t controlword, std::uint16_t previous_controlword) noexcept {
  // Fault reset acts on the edge, so that a master leaving bit 7 set does not reset a fault
  // that comes back.
  if ((controlword & kControlFaultReset) != 0 && (previous_controlword & kControlFaultReset) == 0) {
    return DriveCommand::kFaultReset;
  }
  // The standard's masks include bit 7 = 0; a held bit 7 is taken as 0 (see the header).
  const std::uint16_t word = controlword & static_cast<std::uint16_t>(~kControlFaultReset);
  if ((word & 0x0082) == 0x0000) return DriveCommand::kDisableVoltage;
  if ((word & 0x0086) == 0x0002) return DriveCommand::kQuickStop;
  if ((word & 0x0087) == 0x0006) return DriveCommand::kShutdown;
  if ((word & 0x008F) == 0x0007) return DriveCommand::kSwitchOn;
  if ((word & 0x008F) == 0x000F) return DriveCommand::kEnableOperation;
  return std::nullopt;  // unreachable: the masks above cover bits 0-3
}

std::optional<DriveCommand> next_command_towards_operation_enabled(PowerState state) noexcept {
  switch (state) {
    case PowerState::kFault: return DriveCommand::kFaultReset;
    case PowerState::kSwitchOnDisabled: return DriveCommand::kShutdown;
    case PowerState::kReadyToSwitchOn: return DriveCommand::kSwitchOn;
    case PowerState::kSwitchedOn: return DriveCommand::kEnableOperation;
    case PowerState::kQuickStopActive: return DriveCommand::kDisableVoltage;
    case PowerState::kOperationEnabled:
    case PowerState::kNotReadyToSwitchOn:
    case PowerState::kFaultReactionActive: return std::nullopt;
  }
  return std::nullopt;
}

// ---- PowerStateMachine --------------------------------------------------------------------

PowerStateMachine::PowerStateMachine(PowerStateParams params) : params_(params) {
  require_at_least_one("fault_reaction_ticks", params_.fault_reaction_ticks);
  require_at_least_one("quick_stop_ticks", params_.quick_stop_ticks);
}

void PowerStateMachine::step() noexcept {
  switch (state_) {
    case PowerState::kNotReadyToSwitchOn:
      move(PowerState::kSwitchOnDisabled, 1);  // initialisation takes one tick
      return;
    case PowerState::kFaultReactionActive:
      if (++ticks_in_state_ >= params_.fault_reaction_ticks) move(PowerState::kFault, 14);
      return;
    case PowerState::kQuickStopActive:
      if (!params_.quick_stop_to_switch_on_disabled) return;  // stays until 12 or 16 is commanded
      if (++ticks_in_state_ >= params_.quick_stop_ticks) move(PowerState::kSwitchOnDisabled, 12);
      return;
    case PowerState::kSwitchOnDisabled:
    case PowerState::kReadyToSwitchOn:
    case PowerState::kSwitchedOn:
    case PowerState::kOperationEnabled:
    case PowerState::kFault: return;
  }
}

TransitionResult PowerStateMachine::request(DriveCommand command) noexcept {
  using C = DriveCommand;
  using S = PowerState;
  switch (state_) {
    case S::kNotReadyToSwitchOn: return stay(kReasonInitialising, false);
    case S::kFaultReactionActive: return stay(kReasonFaultReaction, false);

    case S::kFault:
      if (command == C::kFaultReset) return move(S::kSwitchOnDisabled, 15);
      return stay(kReasonFault, false);

    case S::kSwitchOnDisabled:
      switch (command) {
        case C::kShutdown: return move(S::kReadyToSwitchOn, 2);
        case C::kDisableVoltage:
        case C::kQuickStop:
        case C::kFaultReset: return stay(kReasonAlreadyThere, true);
        case C::kSwitchOn:
        case C::kEnableOperation:
        case C::kDisableOperation: break;
      }
      break;

    case S::kReadyToSwitchOn:
      switch (command) {
        case C::kShutdown: return stay(kReasonAlreadyThere, true);
        case C::kSwitchOn: return move(S::kSwitchedOn, 3);
        case C::kEnableOperation: return move(S::kOperationEnabled, 4);  // 3 + 4 in one
        case C::kDisableVoltage:
        case C::kQuickStop: return move(S::kSwitchOnDisabled, 7);
        case C::kDisableOperation:
        case C::kFaultReset: break;
      }
      break;

    case S::kSwitchedOn:
      switch (command) {
        case C::kShutdown: return move(S::kReadyToSwitchOn, 6);
        case C::kSwitchOn:
        case C::kDisableOperation: return stay(kReasonAlreadyThere, true);
        case C::kEnableOperation: return move(S::kOperationEnabled, 4);
        case C::kDisableVoltage:
        case C::kQuickStop: return move(S::kSwitchOnDisabled, 10);
        case C::kFaultReset: break;
      }
      break;

    case S::kOperationEnabled:
      switch (command) {
        case C::kShutdown: return move(S::kReadyToSwitchOn, 8);
        case C::kSwitchOn:  // controlword 0x0007 here means disable operation
        case C::kDisableOperation: return move(S::kSwitchedOn, 5);
        case C::kEnableOperation: return stay(kReasonAlreadyThere, true);
        case C::kDisableVoltage: return move(S::kSwitchOnDisabled, 9);
        case C::kQuickStop: return move(S::kQuickStopActive, 11);
        case C::kFaultReset: break;
      }
      break;

    case S::kQuickStopActive:
      switch (command) {
        case C::kDisableVoltage: return move(S::kSwitchOnDisabled, 12);
        case C::kQuickStop: return stay(kReasonAlreadyThere, true);
        case C::kEnableOperation:
          if (params_.quick_stop_to_switch_on_disabled) return stay(kReasonQuickStopEnds, false);
          return move(S::kOperationEnabled, 16);
        case C::kShutdown:
        case C::kSwitchOn:
        case C::kDisableOperation:
        case C::kFaultReset: break;
      }
      break;
  }
  return stay(kReasonNotAllowed, false);
}

void PowerStateMachine::fault(std::uint16_t error_code) noexcept {
  if (state_ == PowerState::kFaultReactionActive || state_ == PowerState::kFault) return;
  error_code_ = error_code != 0 ? error_code : kErrorCodeGeneric;
  ++fault_count_;
  move(PowerState::kFaultReactionActive, 13);
}

bool PowerStateMachine::power_stage_enabled() const noexcept {
  return state_ == PowerState::kOperationEnabled || state_ == PowerState::kQuickStopActive ||
         state_ == PowerState::kFaultReactionActive;
}

bool PowerStateMachine::high_voltage_allowed() const noexcept {
  switch (state_) {
    case PowerState::kReadyToSwitchOn:
    case PowerState::kSwitchedOn:
    case PowerState::kOperationEnabled:
    case PowerState::kQuickStopActive:
    case PowerState::kFaultReactionActive: return true;
    case PowerState::kNotReadyToSwitchOn:
    case PowerState::kSwitchOnDisabled:
    case PowerState::kFault: return false;
  }
  return false;
}

TransitionResult PowerStateMachine::move(PowerState to, int transition) noexcept {
  const PowerState from = state_;
  state_ = to;
  ticks_in_state_ = 0;
  return TransitionResult{true, from, to, transition, kReasonTransition};
}

TransitionResult PowerStateMachine::stay(const char* reason, bool accepted) noexcept {
  if (!accepted) ++refused_count_;
  return TransitionResult{accepted, state_, state_, 0, reason};
}

}  // namespace pmlsm::drive

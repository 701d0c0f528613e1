#include "pmlsm/canopen/cia402_remote_state.hpp"

#include <cstdio>

namespace pmlsm::canopen {

Cia402RemoteState::Cia402RemoteState(std::uint32_t enable_timeout_cycles)
    : master_(Cia402MasterParams{enable_timeout_cycles}) {}

void Cia402RemoteState::set_problem(const char* text) noexcept { std::snprintf(problem_, sizeof problem_, "%s", text); }

void Cia402RemoteState::on_statusword(std::uint16_t statusword) noexcept {
  statusword_ = statusword;
  statusword_valid_ = true;
  const std::optional<drive::PowerState> state = drive::decode_statusword(statusword);
  const bool faulted = state == drive::PowerState::kFaultReactionActive || state == drive::PowerState::kFault;
  if (faulted && !drive_faulted_ && !local_fault_) ++fault_count_;
  drive_faulted_ = faulted;
}

void Cia402RemoteState::on_drive_error(std::uint16_t error_code, const char* problem) noexcept {
  error_code_ = error_code;
  set_problem(problem);
}

void Cia402RemoteState::lose(const char* what) noexcept {
  if (!lost_) {
    lost_ = true;
    set_problem(what);
  }
  fault(drive::kErrorCommandTimeout);
}

Cia402MasterOutput Cia402RemoteState::walk() noexcept {
  enable_ = true;
  master_.quick_stop(false);
  return master_.update(statusword_, true);
}

std::uint16_t Cia402RemoteState::next_controlword() noexcept {
  const Cia402MasterOutput out = master_.update(statusword_, enable_ && !local_fault_ && !lost_);
  stuck_in_.reset();
  if (out.timed_out && !lost_) stuck_in_ = out.stuck_in ? *out.stuck_in : drive::PowerState::kNotReadyToSwitchOn;
  if (!partial_target_ || local_fault_ || lost_ || master_.quick_stop_active()) return out.controlword;
  // An operator's walk one state at a time (shutdown, switch on): the word for that state.
  const std::optional<drive::PowerState> state = drive::decode_statusword(statusword_);
  if (!state || *state == drive::PowerState::kFault || *state == drive::PowerState::kFaultReactionActive) {
    return out.controlword;
  }
  if (*state == drive::PowerState::kQuickStopActive) return drive::controlword_of(drive::DriveCommand::kDisableVoltage);
  const bool to_switched_on =
      *partial_target_ == drive::DriveCommand::kSwitchOn && *state != drive::PowerState::kSwitchOnDisabled;
  return drive::controlword_of(to_switched_on ? drive::DriveCommand::kSwitchOn : drive::DriveCommand::kShutdown);
}

drive::TransitionResult Cia402RemoteState::request(drive::DriveCommand command) noexcept {
  drive::TransitionResult r;
  r.from = power_state();
  r.to = r.from;
  r.accepted = true;
  partial_target_.reset();
  switch (command) {
    case drive::DriveCommand::kEnableOperation:
      if (local_fault_ || r.from == drive::PowerState::kFault || r.from == drive::PowerState::kFaultReactionActive) {
        r.accepted = false;
        r.reason = "the drive is in fault: fault reset first";
        return r;
      }
      if (lost_) {
        r.accepted = false;
        r.reason = "the drive is lost (no answer on the bus)";
        return r;
      }
      enable_ = true;
      master_.quick_stop(false);
      r.reason = "sent: the drive walks to operation enabled over the next cycles";
      break;
    case drive::DriveCommand::kQuickStop:
      enable_ = false;
      master_.quick_stop(true);
      r.reason = "sent: quick stop";
      break;
    case drive::DriveCommand::kFaultReset:
      local_fault_ = false;
      if (r.from == drive::PowerState::kFault || drive::decode_statusword(statusword_) == drive::PowerState::kFault) {
        master_.request_fault_reset();
      }
      master_.quick_stop(false);
      enable_ = false;
      r.to = power_state();
      r.reason = "sent: fault reset";
      break;
    case drive::DriveCommand::kShutdown:
    case drive::DriveCommand::kSwitchOn:
    case drive::DriveCommand::kDisableOperation:
      if (local_fault_ || lost_ || r.from == drive::PowerState::kFault) {
        r.accepted = false;
        r.reason = "the drive is in fault: fault reset first";
        return r;
      }
      enable_ = false;
      master_.quick_stop(false);
      partial_target_ = command == drive::DriveCommand::kShutdown ? command : drive::DriveCommand::kSwitchOn;
      r.reason = command == drive::DriveCommand::kShutdown ? "sent: shutdown" : "sent: switch on";
      break;
    case drive::DriveCommand::kDisableVoltage:
      enable_ = false;
      master_.quick_stop(false);
      r.reason = "sent: disable voltage";
      break;
  }
  return r;
}

void Cia402RemoteState::fault(std::uint16_t error_code) noexcept {
  if (local_fault_) return;  // the first cause is kept
  local_fault_ = true;
  ++fault_count_;
  error_code_ = error_code == 0 ? drive::kErrorCodeGeneric : error_code;
  enable_ = false;
  master_.quick_stop(true);
  if (problem_[0] == '\0') {
    char text[64];
    std::snprintf(text, sizeof text, "fault 0x%04X raised by the drive loop", error_code_);
    set_problem(text);
  }
}

drive::PowerState Cia402RemoteState::power_state() const noexcept {
  drive::PowerState decoded = drive::PowerState::kNotReadyToSwitchOn;
  if (statusword_valid_) {
    if (const auto state = drive::decode_statusword(statusword_)) decoded = *state;
  }
  if (local_fault_ || lost_) {
    return decoded == drive::PowerState::kFaultReactionActive ? decoded : drive::PowerState::kFault;
  }
  return decoded;
}

}  // namespace pmlsm::canopen

// The master's walk through CiA 402's power state machine; see cia402_master.hpp.
#include "pmlsm/canopen/cia402_master.hpp"

#include <stdexcept>
#include <string>

namespace pmlsm::canopen {

using drive::DriveCommand;
using drive::PowerState;

const char* to_string(Cia402MasterStatus status) noexcept {
  switch (status) {
    case Cia402MasterStatus::kDisabled: return "disabled";
    case Cia402MasterStatus::kDisabling: return "disabling";
    case Cia402MasterStatus::kWalking: return "walking";
    case Cia402MasterStatus::kOperationEnabled: return "operation enabled";
    case Cia402MasterStatus::kFaultResetNeeded: return "fault reset needed";
    case Cia402MasterStatus::kFaultResetting: return "fault resetting";
    case Cia402MasterStatus::kQuickStop: return "quick stop";
    case Cia402MasterStatus::kInvalidStatusword: return "invalid statusword";
  }
  return "unknown";
}

Cia402Master::Cia402Master(Cia402MasterParams params) : params_(params) {
  if (params.timeout_cycles < 1) throw std::invalid_argument("timeout_cycles: must be >= 1, got 0");
}

Cia402MasterOutput Cia402Master::finish(Cia402MasterOutput out, bool expect_move) noexcept {
  const bool same_state = have_state_ && last_state_ == out.state;
  if (!expect_move) {
    waiting_cycles_ = 0;
  } else if (same_state && waiting_cycles_ > 0) {
    if (waiting_cycles_ < UINT32_MAX) ++waiting_cycles_;
  } else {
    waiting_cycles_ = 1;
  }
  have_state_ = true;
  last_state_ = out.state;
  out.waiting_cycles = waiting_cycles_;
  out.timed_out = waiting_cycles_ > params_.timeout_cycles;
  if (out.timed_out) out.stuck_in = out.state;
  last_controlword_ = out.controlword;
  return out;
}

Cia402MasterOutput Cia402Master::update(std::uint16_t statusword, bool enable) noexcept {
  Cia402MasterOutput out;
  out.state = drive::decode_statusword(statusword);
  auto send = [&out](DriveCommand command) {
    out.command = command;
    out.controlword = drive::controlword_of(command);
  };

  if (!out.state) {
    out.status = Cia402MasterStatus::kInvalidStatusword;
    out.controlword = last_controlword_;
    return finish(out, true);
  }
  const PowerState state = *out.state;
  if (state != PowerState::kFault) fault_reset_sent_ = false;

  // Fault: only an explicit request resets it, as a rising edge of bit 7.
  if (state == PowerState::kFault) {
    if (fault_reset_requested_) {
      out.status = Cia402MasterStatus::kFaultResetting;
      if ((last_controlword_ & drive::kControlFaultReset) != 0) {
        send(DriveCommand::kDisableVoltage);  // bit 7 low first, so the next word is an edge
      } else {
        send(DriveCommand::kFaultReset);
        fault_reset_requested_ = false;
        fault_reset_sent_ = true;
      }
      return finish(out, true);
    }
    if (fault_reset_sent_) {
      out.status = Cia402MasterStatus::kFaultResetting;  // hold bit 7 until the drive leaves fault
      send(DriveCommand::kFaultReset);
      return finish(out, true);
    }
    out.status = Cia402MasterStatus::kFaultResetNeeded;
    send(DriveCommand::kDisableVoltage);
    return finish(out, false);
  }

  if (quick_stop_) {
    out.status = Cia402MasterStatus::kQuickStop;
    send(DriveCommand::kQuickStop);
    // Quick stop moves operation enabled to quick stop active, ready to switch on / switched on
    // to switch on disabled; the automatic states move by themselves.
    const bool expect_move = state != PowerState::kSwitchOnDisabled && state != PowerState::kQuickStopActive;
    return finish(out, expect_move);
  }

  if (!enable) {
    send(DriveCommand::kDisableVoltage);
    if (state == PowerState::kSwitchOnDisabled) {
      out.status = Cia402MasterStatus::kDisabled;
      return finish(out, false);
    }
    out.status = Cia402MasterStatus::kDisabling;
    return finish(out, true);
  }

  if (state == PowerState::kOperationEnabled) {
    out.status = Cia402MasterStatus::kOperationEnabled;
    send(DriveCommand::kEnableOperation);
    return finish(out, false);
  }
  out.status = Cia402MasterStatus::kWalking;
  const std::optional<DriveCommand> next = drive::next_command_towards_operation_enabled(state);
  // No command: the drive moves by itself (not ready to switch on, fault reaction active).
  send(next ? *next : DriveCommand::kDisableVoltage);
  return finish(out, true);
}

}  // namespace pmlsm::canopen

// The master's side of CiA 402's power state machine: from the drive's last statusword (0x6041)
// and what the master wants (drive enabled or not), the controlword (0x6040) to send next.
// Pure: no I/O, noexcept and allocation-free after construction. The state machine, statusword
// and controlword codings are pmlsm::drive's.
//
// Each cycle, update(statusword, enable):
//   - statusword no state shows: hold the last controlword (kInvalidStatusword);
//   - quick stop requested (quick_stop(true), held until quick_stop(false)): quick stop 0x0002
//     (operation enabled -> quick stop active; ready to switch on / switched on -> switch on
//     disabled);
//   - fault: fault reset only when request_fault_reset() was called: first a word with bit 7
//     clear (disable voltage 0x0000) if the last one had it set, then 0x0080 (the rising edge)
//     once; the request is used up by that edge. Without a request: disable voltage, status
//     kFaultResetNeeded (a fault is never reset by the master on its own);
//   - enable: next_command_towards_operation_enabled() (shutdown, switch on, enable operation;
//     from quick stop active disable voltage); in operation enabled enable operation 0x000F
//     is held; while the drive moves by itself (not ready to switch on, fault reaction
//     active) disable voltage 0x0000;
//   - not enable: disable voltage 0x0000 (to switch on disabled: no high voltage).
// Time-out: the cycles the drive has stayed in the same state while the master wants it to
// move on (walking, waiting for an automatic transition, fault reset sent, quick stop not
// yet reached) are counted; after timeout_cycles the output says timed_out and stuck_in (the
// state). The master keeps sending the same controlword; the caller decides (e.g. exits naming
// the state). Any state change restarts the count.
#pragma once

#include <cstdint>
#include <optional>

#include "pmlsm/drive/power_state.hpp"

namespace pmlsm::canopen {

struct Cia402MasterParams {
  /// Cycles in one state, while a move is expected, before timed_out. >= 1.
  std::uint32_t timeout_cycles = 1000;
};

enum class Cia402MasterStatus : std::uint8_t {
  kDisabled,           // not enable, and the drive is in switch on disabled
  kDisabling,          // not enable, the drive not yet in switch on disabled
  kWalking,            // enable, on the way to operation enabled
  kOperationEnabled,   // enable, and there
  kFaultResetNeeded,   // the drive is in fault and no fault reset was requested
  kFaultResetting,     // fault reset edge being sent / awaited
  kQuickStop,          // quick stop requested
  kInvalidStatusword,  // the statusword shows no state
};

/// "disabled", "disabling", "walking", "operation enabled", "fault reset needed",
/// "fault resetting", "quick stop", "invalid statusword" ("unknown").
const char* to_string(Cia402MasterStatus status) noexcept;

struct Cia402MasterOutput {
  std::uint16_t controlword = 0;
  /// The command that controlword carries (nullopt when a word is held for an invalid
  /// statusword).
  std::optional<drive::DriveCommand> command;
  /// The drive's state by the statusword (nullopt when it shows none).
  std::optional<drive::PowerState> state;
  Cia402MasterStatus status = Cia402MasterStatus::kDisabled;
  /// Consecutive cycles in the current state (or with an invalid statusword) while a move was
  /// expected; 0 when none is.
  std::uint32_t waiting_cycles = 0;
  bool timed_out = false;
  /// timed_out: the state the drive is stuck in (nullopt: stuck with an invalid statusword).
  std::optional<drive::PowerState> stuck_in;
};

class Cia402Master {
 public:
  /// @throws std::invalid_argument "timeout_cycles: must be >= 1, got 0".
  explicit Cia402Master(Cia402MasterParams params = {});

  Cia402MasterOutput update(std::uint16_t statusword, bool enable) noexcept;

  /// One fault reset (a rising edge of controlword bit 7) when the drive is in fault. A
  /// request made while the drive is not in fault stays until it is, or until cancelled.
  void request_fault_reset() noexcept { fault_reset_requested_ = true; }
  void cancel_fault_reset() noexcept { fault_reset_requested_ = false; }
  bool fault_reset_pending() const noexcept { return fault_reset_requested_; }

  /// Quick stop while active (held until quick_stop(false)).
  void quick_stop(bool active) noexcept { quick_stop_ = active; }
  bool quick_stop_active() const noexcept { return quick_stop_; }

  /// The controlword sent last (0x0000 before the first update).
  std::uint16_t last_controlword() const noexcept { return last_controlword_; }

  const Cia402MasterParams& params() const noexcept { return params_; }

 private:
  Cia402MasterOutput finish(Cia402MasterOutput out, bool expect_move) noexcept;

  Cia402MasterParams params_;
  std::uint16_t last_controlword_ = 0;
  bool fault_reset_requested_ = false;
  bool fault_reset_sent_ = false;  // the edge was sent; waiting for the drive to leave fault
  bool quick_stop_ = false;
  bool have_state_ = false;
  std::optional<drive::PowerState> last_state_;
  std::uint32_t waiting_cycles_ = 0;
};

}  // namespace pmlsm::canopen

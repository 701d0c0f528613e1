// A CiA 402 drive as its master sees it, whatever bus carries the words: the operator's intent
// (enabled or not, a walk to one state, quick stop, fault reset), the faults the master raised
// itself (the drive loop's, a lost drive), the drive's own faults counted from its statusword and
// its emergencies, and from all of it the controlword to send and the power state to report. The
// CANopen master (Cia402Drive) and the EtherCAT master (ethercat::EthercatCia402Drive) keep one
// each; the bus part (when a statusword arrives, where the controlword goes) is theirs.
// Pure: no I/O, noexcept after construction, no allocation.
#pragma once

#include <cstdint>
#include <optional>

#include "pmlsm/canopen/cia402_master.hpp"
#include "pmlsm/drive/drive.hpp"
#include "pmlsm/drive/power_state.hpp"

namespace pmlsm::canopen {

class Cia402RemoteState {
 public:
  /// `enable_timeout_cycles`: cycles in one state while a move is expected before the walk is
  /// stuck. @throws std::invalid_argument when it is 0.
  explicit Cia402RemoteState(std::uint32_t enable_timeout_cycles);

  /// The drive's statusword as heard: an entry into fault reaction active or fault that the
  /// master did not raise counts as one of the drive's faults.
  void on_statusword(std::uint16_t statusword) noexcept;
  /// An error the drive reported (its emergency): the code kept as 0x603F, `problem` as the text.
  void on_drive_error(std::uint16_t error_code, const char* problem) noexcept;

  /// An operator's or supervisor's request (drive::Drive::request).
  drive::TransitionResult request(drive::DriveCommand command) noexcept;
  /// A fault the drive loop raised (drive::Drive::fault): latched, quick stop sent, the first code
  /// kept.
  void fault(std::uint16_t error_code) noexcept;
  /// The drive stopped answering (or left the bus's operational state): lost for good, fault
  /// 0x8130, `what` kept as the problem.
  void lose(const char* what) noexcept;

  /// The walk before a run: wants the drive enabled and returns the master's next step.
  Cia402MasterOutput walk() noexcept;
  /// This cycle's controlword: the walk to the intent, an operator's walk to one state, quick stop
  /// or fault reset; stuck_in() updated.
  std::uint16_t next_controlword() noexcept;

  /// The state the drive reports, or fault while the master holds a fault of its own (or lost it).
  drive::PowerState power_state() const noexcept;
  std::uint16_t statusword() const noexcept { return statusword_; }
  std::uint16_t last_controlword() const noexcept { return master_.last_controlword(); }
  std::uint16_t error_code() const noexcept { return error_code_; }
  std::uint64_t fault_count() const noexcept { return fault_count_; }
  bool lost() const noexcept { return lost_; }
  /// Why the drive was lost or faulted, its emergency, a stuck walk ("" when none).
  const char* problem() const noexcept { return problem_; }
  void set_problem(const char* text) noexcept;
  /// The walk has been stuck in one state for enable_timeout_cycles (during the run).
  std::optional<drive::PowerState> stuck_in() const noexcept { return stuck_in_; }

 private:
  Cia402Master master_;
  std::uint16_t statusword_ = 0;
  bool statusword_valid_ = false;
  bool enable_ = false;
  /// shutdown / switch on requested: held in that state (nullopt: enable_ decides).
  std::optional<drive::DriveCommand> partial_target_;
  bool local_fault_ = false;
  bool drive_faulted_ = false;  // the statusword shows fault reaction active or fault
  bool lost_ = false;
  std::uint16_t error_code_ = 0;
  std::uint64_t fault_count_ = 0;
  std::optional<drive::PowerState> stuck_in_;
  char problem_[192] = {};
};

}  // namespace pmlsm::canopen

#include "run_validity.hpp"

#include <cinttypes>
#include <cstdio>

#include "pmlsm/drive/power_state.hpp"

namespace pmlsm::node {

static_assert(kPowerOperationEnabled == static_cast<std::uint8_t>(drive::PowerState::kOperationEnabled));
static_assert(kPowerFaultReactionActive == static_cast<std::uint8_t>(drive::PowerState::kFaultReactionActive));
static_assert(kPowerFault == static_cast<std::uint8_t>(drive::PowerState::kFault));

const char* power_state_name(std::uint8_t power_state) noexcept {
  if (power_state >= drive::kPowerStateCount) return "unknown";
  return drive::to_string(static_cast<drive::PowerState>(power_state));
}

bool force_applied(const DriveTickStatus& s) noexcept {
  return (s.status & (kFeedbackStatusSafeState | kFeedbackStatusFault)) == 0 && s.power_state == kPowerOperationEnabled;
}

void RunValidity::add(std::uint64_t tick, const DriveTickStatus& s) noexcept {
  ++ticks_;
  if (force_applied(s)) return;
  if (bad_ticks_ == 0 || tick < first_bad_) first_bad_ = tick;
  if (bad_ticks_ == 0 || tick > last_bad_) last_bad_ = tick;
  ++bad_ticks_;
  if ((s.status & kFeedbackStatusFault) != 0 || s.power_state == kPowerFaultReactionActive ||
      s.power_state == kPowerFault) {
    any_fault_ = true;
  }
  if ((s.status & kFeedbackStatusSafeState) != 0) any_safe_state_ = true;
  if (s.error_code != 0 && (error_code_ == 0 || tick < error_code_tick_)) {
    error_code_ = s.error_code;
    error_code_tick_ = tick;
  }
  if (s.power_state != kPowerOperationEnabled && (!any_power_off_ || tick < power_state_tick_)) {
    any_power_off_ = true;
    power_state_ = s.power_state;
    power_state_tick_ = tick;
  }
}

std::string RunValidity::reason() const {
  if (valid()) return {};
  char buf[160];
  const bool contiguous = last_bad_ - first_bad_ + 1 == bad_ticks_;
  if (contiguous) {
    std::snprintf(buf, sizeof buf, "drive force off for %" PRIu64 " tick%s from tick %" PRIu64, bad_ticks_,
                  bad_ticks_ == 1 ? "" : "s", first_bad_);
  } else {
    std::snprintf(buf, sizeof buf, "drive force off for %" PRIu64 " ticks, ticks %" PRIu64 "..%" PRIu64, bad_ticks_,
                  first_bad_, last_bad_);
  }
  std::string text = buf;
  std::string detail;
  if (any_fault_) {
    if (error_code_ != 0) {
      std::snprintf(buf, sizeof buf, "fault 0x%04X", static_cast<unsigned>(error_code_));
      detail = buf;
    } else {
      detail = "fault";
    }
  } else {
    if (any_safe_state_) detail = "safe state";
    if (error_code_ != 0) {
      // Not faulted now: the code is an earlier fault's, kept after its reset.
      std::snprintf(buf, sizeof buf, "%slast error 0x%04X", detail.empty() ? "" : ", ",
                    static_cast<unsigned>(error_code_));
      detail += buf;
    }
  }
  if (any_power_off_) {
    if (!detail.empty()) detail += ", ";
    detail += "power state ";
    detail += power_state_name(power_state_);
  }
  if (!detail.empty()) text += " (" + detail + ")";
  return text;
}

std::optional<RunChange> RunIdTracker::observe(std::uint64_t run_id, std::uint64_t tick) noexcept {
  if (run_id == 0) return std::nullopt;
  if (run_id_ == 0) {
    run_id_ = run_id;
    return std::nullopt;
  }
  if (run_id == run_id_) return std::nullopt;
  return RunChange{run_id_, run_id, tick};
}

std::string restart_message(const char* program, const RunChange& change) {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "%s: the drive restarted (run %016" PRIx64 " -> %016" PRIx64 ") at its tick %" PRIu64
                ": results would mix two runs; none written",
                program, change.from_run, change.to_run, change.tick);
  return buf;
}

}  // namespace pmlsm::node

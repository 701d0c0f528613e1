// The drive loop: what every drive node (plant simulator, real-drive bridge) does each control
// tick, DDS-free. Per tick k:
//   begin_tick   the backend samples; the loop reports tick k's feedback (measurement, the
//                force applied during the last tick, status, power state)
//   published    the node has written the feedback (times kept for latency and the watchdog)
//   offer        each ForceCommand received is arbitrated (below)
//   end_tick     realtime: late count, watchdog, lost-controller check; the backend applies
//                the setpoint for the next period (zero unless operation enabled)
//
// Arbitration (a command names the feedback tick it answers, its run and its writer):
//   - another run's command (run_id differs: a controller still following a drive that has
//     restarted) is rejected;
//   - lockstep: only the answer to tick k is taken; answers to other ticks are stale (late);
//     a non-finite setpoint answers the tick but is rejected: the last one is held;
//   - realtime: the newest command is held (zero-order hold); a command is rejected when its
//     setpoint (force, feedforward, velocity, position) is not finite, when it answers a tick not yet published
//     (malformed: taken, it would make every genuine answer after it look stale) or one not newer than the applied one;
//   - one writer owns the drive: the first whose command is taken after the drive entered
//     operation enabled. Commands of any other writer (a second controller) are rejected,
//     counted and flagged (STATUS_FOREIGN_COMMAND), never applied: the drive never alternates
//     between two controllers. Ownership ends when the drive leaves operation enabled, so a
//     new controller takes over only through fault reset and enable.
//
// Watchdog (realtime): arms once `watchdog_arm_ticks` consecutive ticks were answered in
// their own tick while in operation enabled (a controller working through a backlog of old
// feedback, as at start-up, does not arm it); it trips when the oldest feedback still
// unanswered was published `watchdog_s` ago or more: the backend faults (0x8130), force off,
// latched until fault reset. It is checked at the start of every tick and again after the
// tick's command deadline, so a controller that dies is cut off at most watchdog + 1 tick
// after its last answer. Counting from the unanswered feedback, not from the last command,
// means a drive thread that itself stalled does not blame the controller; and a tick that
// starts more than a period late (the drive's own thread was held, by the host, not by the
// controller) suspends the check until the drive is back on time and one more tick has passed
// (the controller was held with it), counted as a drive stall.
// Lost controller (realtime): no command taken for `controller_lost_s` since the last one (or
// since start) -> controller_lost(); the node decides what follows (a simulation ends, a
// rig's drive stays up in its safe state to be reset).
//
// Nothing here allocates, throws or blocks after construction.
#pragma once

#include <cstdint>
#include <vector>

#include "pmlsm/drive/drive.hpp"
#include "pmlsm/drive/loop_statistics.hpp"

namespace pmlsm::drive {

struct DriveLoopParams {
  double period_s = 1e-3;
  bool realtime = false;
  double watchdog_s = 3e-3;
  std::uint32_t watchdog_arm_ticks = 3;
  double controller_lost_s = 0.05;
  /// Realtime: how long after the first tick the first command may take (discovery, start-up).
  double first_command_timeout_s = 10.0;
  /// Latencies kept for the percentiles (the scenario's ticks).
  std::uint64_t expected_ticks = 0;
  /// @throws std::invalid_argument naming the field and value.
  void validate() const;
};

/// MotorFeedback status bits (the IDL's MotorFeedback_Constants, checked against them where
/// the messages are filled).
namespace status {
inline constexpr std::uint32_t kSafeState = 1;         ///< force off: not operation enabled
inline constexpr std::uint32_t kCommandLate = 8;       ///< realtime: last tick had no fresh command
inline constexpr std::uint32_t kWatchdogTripped = 16;  ///< latched until fault reset
inline constexpr std::uint32_t kSimulated = 64;
inline constexpr std::uint32_t kFault = 128;                ///< fault reaction active or fault
inline constexpr std::uint32_t kForeignCommand = 256;       ///< a second writer's commands were refused
inline constexpr std::uint32_t kLoadSensorSaturated = 512;  ///< the load's accelerometer at its rail
}  // namespace status

struct ForceCommandIn {
  std::uint64_t run_id = 0;
  std::uint64_t feedback_tick = 0;
  double force_n = 0;
  std::uint64_t writer_id = 0;        ///< identifies the writer (a hash of its GUID)
  std::int64_t received_wall_ns = 0;  ///< reception time (CLOCK_REALTIME), for latency
  /// The rest of the setpoint (Setpoint), for a drive closing its own loops.
  double feedforward_force_n = 0;
  double velocity_mps = 0;
  double position_m = 0;
};

enum class Verdict : std::uint8_t {
  kAccepted,
  kStale,       ///< answers an older (or, in lockstep, another) tick
  kFutureTick,  ///< answers a tick not yet published
  kNonFinite,
  kOtherRun,
  kForeignWriter,
};
const char* to_string(Verdict verdict) noexcept;

/// Tick k's feedback as the node publishes it.
struct TickReport {
  std::uint64_t tick = 0;
  Measurement measurement;
  /// Force in effect during the last tick: the drive's account when it gives one
  /// (Measurement::applied_force_n), else the force the loop held.
  double applied_force_n = 0;
  std::uint64_t applied_command_tick = 0;
  std::uint32_t status = 0;  ///< status::k* bits
  PowerState power_state = PowerState::kNotReadyToSwitchOn;
  std::uint16_t error_code = 0;
};

struct TickEvents {
  bool watchdog_tripped = false;      ///< this tick
  std::uint64_t unanswered_tick = 0;  ///< the feedback tick that tripped it
  std::int64_t tripped_mono_ns = 0;   ///< when it tripped (force off from then on)
  bool controller_lost = false;       ///< this tick (reported once until the next enable)
};

struct DriveCounters {
  std::uint64_t late = 0;        ///< ticks without their command (realtime), stale answers (lockstep)
  std::uint64_t rejected = 0;    ///< non-finite, future, out of order, other run
  std::uint64_t foreign = 0;     ///< commands of a writer that does not own the drive
  std::uint64_t other_run = 0;   ///< of which from another run
  std::uint64_t safe_ticks = 0;  ///< ticks with force off after the drive was first enabled
  std::uint64_t watchdog_trips = 0;
  std::uint64_t uncommanded_ticks = 0;  ///< ticks that got no acceptable command
  std::uint64_t drive_stalls = 0;       ///< ticks that started more than a period late
};

class DriveLoop {
 public:
  /// `drive` must outlive the loop. @throws std::invalid_argument for bad params.
  DriveLoop(const DriveLoopParams& params, Drive& drive);

  /// Starts tick `tick` at CLOCK_MONOTONIC `now_mono_ns`, due at `scheduled_mono_ns`
  /// (realtime; lockstep: the same): checks the watchdog, samples the drive.
  const TickReport& begin_tick(std::uint64_t tick, std::int64_t now_mono_ns, std::int64_t scheduled_mono_ns);
  const TickReport& begin_tick(std::uint64_t tick, std::int64_t now_mono_ns) {
    return begin_tick(tick, now_mono_ns, now_mono_ns);
  }
  /// The feedback of the current tick was written at these times.
  void published(std::int64_t wall_ns, std::int64_t mono_ns);
  /// Arbitrates one received command (see the file comment).
  Verdict offer(const ForceCommandIn& command);
  /// The current tick's own command is in (lockstep waits for it; realtime: a fresh one).
  bool answered() const { return answered_; }
  /// Ends the tick at `now_mono_ns`: checks, then the backend applies the force for the next
  /// period (apply_force false: the node drove the period itself, as at the voltage level).
  TickEvents end_tick(std::int64_t now_mono_ns, bool apply_force = true);

  /// An operator's request; on entering operation enabled the watchdog re-arms from scratch
  /// and ownership is open.
  TransitionResult request(DriveCommand command, std::int64_t now_mono_ns);
  /// The run this loop's drive belongs to; commands of other runs are rejected.
  void set_run_id(std::uint64_t run_id) { run_id_ = run_id; }

  const DriveCounters& counters() const { return counters_; }
  LoopStatistics& statistics() { return statistics_; }
  bool watchdog_armed() const { return armed_; }
  bool ever_enabled() const { return ever_enabled_; }
  bool any_command() const { return any_command_; }
  std::uint64_t owner_writer_id() const { return owner_set_ ? owner_writer_id_ : 0; }
  /// A writer refused as foreign for the first time since the last call (for one log line).
  bool take_new_foreign_writer(std::uint64_t& writer_id);
  const Drive& drive() const { return drive_; }

 private:
  void track_power_state(std::int64_t now_mono_ns);
  /// The watchdog's check at `now_mono_ns` (see the file comment); trips into `events_`.
  void check_watchdog(std::int64_t now_mono_ns, bool at_tick_start);

  static constexpr std::uint64_t kRing = 4096;  // publish times remembered

  DriveLoopParams params_;
  Drive& drive_;
  LoopStatistics statistics_;
  DriveCounters counters_;
  std::vector<std::int64_t> published_wall_ns_;
  std::vector<std::int64_t> published_mono_ns_;
  std::uint64_t watchdog_ticks_;  // whole periods in the watchdog time
  TickReport report_;
  std::uint64_t run_id_ = 0;
  std::uint64_t tick_ = 0;
  Setpoint setpoint_;  // zero-order hold of the last accepted command
  std::uint64_t applied_tick_ = 0;
  bool any_command_ = false;
  bool answered_ = false;
  bool fresh_ = false;
  // ownership
  bool owner_set_ = false;
  std::uint64_t owner_writer_id_ = 0;
  bool foreign_seen_ = false;
  bool new_foreign_ = false;
  std::uint64_t new_foreign_writer_ = 0;
  // watchdog and liveness
  bool was_enabled_ = false;
  bool ever_enabled_ = false;
  bool armed_ = false;
  std::uint32_t consecutive_fresh_ = 0;
  std::uint64_t arm_tick_ = 0;
  bool watchdog_latched_ = false;
  std::int64_t last_accept_mono_ns_ = 0;
  std::int64_t tick_start_mono_ns_ = 0;
  double last_applied_force_n_ = 0;
  bool last_fresh_ = true;
  bool accepted_this_tick_ = false;
  bool any_stall_ = false;
  std::uint64_t grace_until_tick_ = 0;
  bool published_this_tick_ = false;
  TickEvents events_;
  bool liveness_started_ = false;
  bool lost_reported_ = false;
};

}  // namespace pmlsm::drive

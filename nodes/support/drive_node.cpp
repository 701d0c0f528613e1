#include "drive_node.hpp"
#include <CLI/CLI.hpp>

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "msg_mapping.hpp"
#include "pmlsm/sim/closed_loop.hpp"

namespace pmlsm::node {

namespace {
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;

/// User + system CPU time of the whole process so far.
double process_cpu_s() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec) * 1e-6;
}
}  // namespace

void add_drive_node_options(CLI::App& app, DriveNodeOptions& opt) {
  app.add_option("--peers", opt.peers, "MotorFeedback readers to wait for before tick 0")->check(CLI::Range(1, 64));
  app.add_option("--watchdog-ms", opt.watchdog_ms, "realtime: the oldest unanswered feedback this old -> fault")
      ->check(CLI::PositiveNumber);
  app.add_option("--watchdog-arm-ticks", opt.watchdog_arm_ticks,
                 "realtime: consecutive ticks answered in their own tick before the watchdog counts")
      ->check(CLI::Range(1, 100000));
  app.add_option("--controller-lost-ms", opt.controller_lost_ms,
                 "realtime: no acceptable command this long -> controller lost")
      ->check(CLI::PositiveNumber);
  app.add_option("--on-controller-lost", opt.on_controller_lost,
                 "realtime: exit (simulation: end with code 4) or stay (rig: stay up in the safe state to be reset)")
      ->check(CLI::IsMember({"exit", "stay"}))
      ->capture_default_str();
  app.add_option("--command-deadline-us", opt.command_deadline_us,
                 "realtime: how long into a tick the plant waits for that tick's command")
      ->check(CLI::Range(0.0, 1e6));
  app.add_option("--wake-early-us", opt.wake_early_us,
                 "realtime: sleep until this long before each tick, then poll the clock to its start "
                 "(a sleeping thread may wake tens of microseconds late)")
      ->check(CLI::Range(0.0, 900.0));
  app.add_option("--auto-enable", opt.auto_enable,
                 "enable the drive (walk to operation enabled) once the peers are there; false: wait for "
                 "`pmlsm drive enable`")
      ->capture_default_str();
}

void check_drive_node_options(const char* node_name, const DriveNodeOptions& opt, const CommonOptions& common,
                              const NodeRuntime& rt) {
  if (opt.wake_early_us * 1e-6 >= rt.period_s) {
    throw ConfigError("--wake-early-us " + std::to_string(opt.wake_early_us) +
                      ": must be shorter than the control period (" + std::to_string(rt.period_s * 1e6) + " us)");
  }
  if (opt.watchdog_ms * 1e-3 < rt.period_s) {
    throw ConfigError("--watchdog-ms " + std::to_string(opt.watchdog_ms) + ": must be at least one control period (" +
                      std::to_string(rt.period_s * 1e3) + " ms)");
  }
  if (common.wake_batch_us > 0.0) {
    throw ConfigError("--wake-batch-us " + std::to_string(common.wake_batch_us) + ": " + std::string(node_name) +
                      " is on the control chain; batching would pace the loop");
  }
}

DriveNode::DriveNode(std::string name, const CommonOptions& common, const DriveNodeOptions& options, NodeRuntime& rt,
                     drive::Drive& backend, DriveNodeHooks& hooks)
    : name_(std::move(name)),
      common_(common),
      opt_(options),
      rt_(rt),
      backend_(backend),
      hooks_(hooks),
      period_s_(rt.period_s),
      ticks_(scenario_ticks(rt.cfg.scenario, period_s_)),
      voltage_level_(rt.cfg.command_level == CommandLevel::kVoltage),
      realtime_(rt.cfg.clock == Clock::kRealtime),
      feedback_writer_(rt.participant.make_writer(pdds::topics::kMotorFeedback)),
      command_reader_(rt.participant.make_reader(pdds::topics::kForceCommand, rt.wakeup)),
      control_reader_(rt.participant.make_reader(pdds::topics::kDriveControl, rt.wakeup)),
      state_writer_(rt.participant.make_writer(pdds::topics::kDriveState)),
      loop_(loop_params(), backend_),
      clock_(static_cast<std::int64_t>(std::llround(period_s_ * 1e9)), realtime_,
             static_cast<std::int64_t>(std::llround(options.wake_early_us * 1e3))),
      run_id_(new_run_id()) {
  loop_.set_run_id(run_id_);
  drive_state_.drive_name(name_);
}

drive::DriveLoopParams DriveNode::loop_params() const {
  drive::DriveLoopParams p;
  p.period_s = period_s_;
  p.realtime = realtime_;
  p.watchdog_s = opt_.watchdog_ms * 1e-3;
  p.watchdog_arm_ticks = opt_.watchdog_arm_ticks;
  p.controller_lost_s = opt_.controller_lost_ms * 1e-3;
  p.first_command_timeout_s = common_.peer_timeout_s;
  p.expected_ticks = ticks_;
  return p;
}

bool DriveNode::peers_ready() {
  return feedback_writer_.matched_readers() >= static_cast<std::size_t>(opt_.peers) &&
         command_reader_.matched_writers() >= 1 && hooks_.peers_ready();
}

void DriveNodeHooks::enable_at_start(DriveNode& node) {
  const std::int64_t now = monotonic_ns();
  while (const auto next = drive::next_command_towards_operation_enabled(node.backend().power_state())) {
    const drive::TransitionResult r = node.loop().request(*next, now);
    if (!r.accepted) break;  // cannot happen from switch on disabled; never loop
  }
  std::printf("%s: drive %s (auto-enable)\n", node.name().c_str(), drive::to_string(node.backend().power_state()));
}

void DriveNode::publish_drive_state(std::uint64_t tick) {
  drive_state_.stamp(node::make_stamp(tick, period_s_, run_id_));
  node::to_msg(backend_, loop_, refused_requests_, drive_state_);
  state_writer_.write(drive_state_);
  published_state_ = backend_.power_state();
}

void DriveNode::report(const std::string& message) {
  rt_.status.publish(backend_.power_state() == drive::PowerState::kOperationEnabled ? node_state::STATE_RUNNING
                                                                                    : node_state::STATE_SAFE,
                     loop_.statistics().ticks(), period_s_, message);
}

void DriveNode::serve_drive_control() {
  while (control_reader_.take(control_)) {
    const std::string target = control_.drive_name().to_string();
    if (!target.empty() && target != "*" && target != name_) continue;
    const drive::PowerState before = backend_.power_state();
    std::string text;
    bool accepted = false;
    if (control_.command() >= drive::kDriveCommandCount) {
      text = "unknown command " + std::to_string(control_.command());
    } else {
      const auto command = static_cast<drive::DriveCommand>(control_.command());
      const drive::TransitionResult r = loop_.request(command, monotonic_ns());
      accepted = r.accepted;
      text = std::string(drive::to_string(command)) + (r.accepted ? "" : " refused") + " in " +
             drive::to_string(before) +
             (r.accepted ? " -> " + std::string(drive::to_string(r.to)) : ": " + std::string(r.reason));
    }
    if (!accepted) ++refused_requests_;
    std::printf("%s: drive control from %s (request %llu): %s\n", name_.c_str(), control_.requester().c_str(),
                static_cast<unsigned long long>(control_.request_id()), text.c_str());
    drive_state_.request_id(control_.request_id());
    drive_state_.request_accepted(accepted);
    drive_state_.request_message(text.substr(0, 127));
    publish_drive_state(loop_.statistics().ticks());
  }
}

bool DriveNode::take_commands() {
  while (!(loop_.answered() && !realtime_) && command_reader_.take(command_, info_)) {
    std::int64_t received_ns = info_.reception_timestamp.to_ns();
    if (received_ns <= 0) received_ns = wall_time_ns();
    loop_.offer(node::from_msg(command_, node::writer_id(info_), received_ns));
  }
  std::uint64_t foreign = 0;
  if (loop_.take_new_foreign_writer(foreign)) {
    std::fprintf(stderr, "%s: a second ForceCommand writer (%016llx) at tick %llu: refused; following %016llx\n",
                 name_.c_str(), static_cast<unsigned long long>(foreign), static_cast<unsigned long long>(k_),
                 static_cast<unsigned long long>(loop_.owner_writer_id()));
    rt_.status.publish(node_state::STATE_RUNNING, k_, period_s_, "second ForceCommand writer refused");
  }
  serve_drive_control();
  return loop_.answered();
}

int DriveNode::report_missing_peers() {
  if (pdds::stop_requested()) return kExitOk;
  std::fprintf(stderr, "%s: peers missing after %.1f s: %zu of %d MotorFeedback readers, %zu ForceCommand writers\n",
               name_.c_str(), common_.peer_timeout_s, feedback_writer_.matched_readers(), opt_.peers,
               command_reader_.matched_writers());
  return kExitPeerMissing;
}

void DriveNode::start_run() {
  std::printf("%s: %d peers matched %.1f ms after start%s\n", name_.c_str(), opt_.peers,
              static_cast<double>(monotonic_ns() - rt_.start_ns) * 1e-6,
              rt_.participant.identity().empty() ? "" : " (secure)");
  std::printf("%s: %s clock, %s command level, %llu ticks of %.3g ms, scenario %s, run %016llx\n", name_.c_str(),
              realtime_ ? "realtime" : "lockstep", voltage_level_ ? "voltage" : "force",
              static_cast<unsigned long long>(ticks_), period_s_ * 1e3, rt_.cfg.scenario.name.c_str(),
              static_cast<unsigned long long>(run_id_));
  hooks_.before_run(*this);
  if (opt_.auto_enable) hooks_.enable_at_start(*this);
  publish_drive_state(0);
  rt_.status.publish(node_state::STATE_RUNNING, 0, period_s_, "running");
}

void DriveNode::publish_feedback(std::uint64_t k) {
  const drive::TickReport& report = loop_.begin_tick(k, monotonic_ns(), clock_.tick_start_ns());
  feedback_.stamp(node::make_stamp(k, period_s_, run_id_));
  node::to_msg(report, feedback_);
  hooks_.before_publish(k, report);
  loop_.published(wall_time_ns(), monotonic_ns());
  feedback_writer_.write(feedback_);
  hooks_.after_publish(k);
}

void DriveNode::report_watchdog_trip(std::uint64_t k, const drive::TickEvents& events) {
  // The wall time the force went off (the trip may have come at the tick's start).
  const std::int64_t tripped_wall_ns = wall_time_ns() - (monotonic_ns() - events.tripped_mono_ns);
  std::fprintf(stderr,
               "%s: watchdog: tick %llu unanswered for %.1f ms at tick %llu: fault 0x%04x, zero force "
               "[wall %.6f s]\n",
               name_.c_str(), static_cast<unsigned long long>(events.unanswered_tick), opt_.watchdog_ms,
               static_cast<unsigned long long>(k), backend_.error_code(), static_cast<double>(tripped_wall_ns) * 1e-9);
  rt_.status.publish(node_state::STATE_SAFE, k, period_s_, "watchdog: feedback unanswered, fault, zero force");
  char reason[128];
  std::snprintf(reason, sizeof reason, "watchdog: feedback of tick %llu unanswered for %.1f ms (tick %llu)",
                static_cast<unsigned long long>(events.unanswered_tick), opt_.watchdog_ms,
                static_cast<unsigned long long>(k));
  drive_state_.fault_reason(reason);
}

void DriveNode::report_tick_events(std::uint64_t k, const drive::TickEvents& events, std::uint64_t& faults_seen) {
  if (loop_.watchdog_armed() != watchdog_armed_) {
    watchdog_armed_ = loop_.watchdog_armed();
    if (watchdog_armed_) {
      std::printf("%s: watchdog armed at tick %llu (%u ticks answered in their own tick)\n", name_.c_str(),
                  static_cast<unsigned long long>(k), opt_.watchdog_arm_ticks);
    }
  }
  if (events.watchdog_tripped) report_watchdog_trip(k, events);
  if (backend_.fault_count() != faults_seen) {
    faults_seen = backend_.fault_count();
    const char* detail = backend_.fault_detail();
    if (!events.watchdog_tripped && detail[0] != '\0') {
      std::fprintf(stderr, "%s: drive fault 0x%04x at tick %llu: %s: zero force\n", name_.c_str(),
                   backend_.error_code(), static_cast<unsigned long long>(k), detail);
      rt_.status.publish(node_state::STATE_SAFE, k, period_s_, "drive fault, zero force");
      set_fault_reason(detail);
    }
  }
}

bool DriveNode::controller_lost_ends_run(std::uint64_t k) {
  std::fprintf(stderr, "%s: no acceptable ForceCommand for %.0f ms at tick %llu: controller lost [wall %.6f s]\n",
               name_.c_str(), loop_.any_command() ? opt_.controller_lost_ms : common_.peer_timeout_s * 1e3,
               static_cast<unsigned long long>(k), static_cast<double>(wall_time_ns()) * 1e-9);
  rt_.status.publish(node_state::STATE_SAFE, k, period_s_, "controller lost");
  if (backend_.power_state() == drive::PowerState::kOperationEnabled)
    loop_.request(drive::DriveCommand::kQuickStop, monotonic_ns());
  return opt_.on_controller_lost == "exit";
}

void DriveNode::publish_periodic_status(std::uint64_t k) {
  auto& s = rt_.status.status();
  s.late(loop_.counters().late);
  s.rejected(loop_.counters().rejected + loop_.counters().foreign);
  s.deadline_misses(loop_.statistics().deadline_misses());
  rt_.status.publish(backend_.power_state() == drive::PowerState::kOperationEnabled ? node_state::STATE_RUNNING
                                                                                    : node_state::STATE_SAFE,
                     k, period_s_);
  publish_drive_state(k);
}

void DriveNode::activate() { rt_.status.publish(node_state::STATE_WAITING, 0, period_s_, "waiting for peers"); }

std::chrono::duration<double> DriveNode::input_timeout() const {
  return std::chrono::duration<double>(common_.peer_timeout_s);
}

CycleStep DriveNode::update() {
  switch (phase_) {
    case Phase::kPeers:
      if (!peers_ready()) return CycleStep::waiting();
      start_run();
      faults_at_start_ = backend_.fault_count();
      faults_seen_ = faults_at_start_;
      cpu_at_start_s_ = process_cpu_s();
      loop_start_ns_ = monotonic_ns();
      clock_.start();
      phase_ = Phase::kFeedback;
      // Realtime: tick 0 on the clock's grid, a period away at most.
      if (realtime_ && monotonic_ns() < clock_.tick_start_ns()) {
        return CycleStep::sleeping_until(clock_.tick_start_ns(), clock_.wake_early_ns());
      }
      [[fallthrough]];
    case Phase::kFeedback:
      if (k_ == ticks_) return CycleStep::finished(kExitOk);
      publish_feedback(k_);
      command_deadline_ns_ = clock_.tick_start_ns() + static_cast<std::int64_t>(opt_.command_deadline_us * 1e3);
      phase_ = Phase::kCommand;
      [[fallthrough]];
    case Phase::kCommand:
      // Lockstep: the tick waits for its command (a lost controller is the input timeout);
      // realtime: until the command deadline, then it goes on without (the loop holds or goes safe).
      if (!take_commands()) {
        if (!realtime_) return CycleStep::waiting();
        if (monotonic_ns() < command_deadline_ns_) return CycleStep::waiting_until(command_deadline_ns_);
      }
      phase_ = Phase::kExchange;
      [[fallthrough]];
    case Phase::kExchange:
      switch (hooks_.exchange(k_)) {
        case Progress::kWaiting: return CycleStep::waiting();
        case Progress::kFinished: break;
        default: return CycleStep::worked();
      }
      return end_tick();
  }
  return CycleStep::finished(kExitError);
}

CycleStep DriveNode::end_tick() {
  const std::uint64_t k = k_;
  const drive::TickEvents events = loop_.end_tick(monotonic_ns(), hooks_.apply_force());
  report_tick_events(k, events, faults_seen_);
  ++k_;  // this tick is done
  phase_ = Phase::kFeedback;
  if (events.controller_lost && controller_lost_ends_run(k)) return CycleStep::finished(kExitPeerLost);
  hooks_.after_tick(*this, k);
  if (backend_.power_state() != published_state_) publish_drive_state(k);
  if (k_ == ticks_) {
    // The last tick's command is out: end in order now, not after a wait for a tick that will
    // not come. A drive on its own clock watches SYNC while enabled, and whatever holds this
    // thread next (peers ending, in a container their participants leaving) may take longer
    // than that watch.
    hooks_.at_end(*this);
    ended_in_order_ = true;
  }
  if (k % 1000 == 999) publish_periodic_status(k);
  if (clock_.advance()) loop_.statistics().record_deadline_miss();
  if (!realtime_ || k_ == ticks_) return CycleStep::worked();
  return CycleStep::sleeping_until(clock_.tick_start_ns(), clock_.wake_early_ns());
}

int DriveNode::inputs_lost() {
  switch (phase_) {
    case Phase::kPeers: return report_missing_peers();
    case Phase::kCommand:
      std::fprintf(stderr, "%s: no ForceCommand for tick %llu within %.1f s: controller lost; safe state\n",
                   name_.c_str(), static_cast<unsigned long long>(k_), common_.peer_timeout_s);
      break;
    default:
      std::fprintf(stderr, "%s: no %s in tick %llu within %.1f s: controller lost; safe state\n", name_.c_str(),
                   hooks_.awaited(), static_cast<unsigned long long>(k_), common_.peer_timeout_s);
      break;
  }
  rt_.status.publish(node_state::STATE_SAFE, k_, period_s_, "controller lost");
  return kExitPeerLost;
}

int DriveNode::finish(int exit_code) {
  if (phase_ == Phase::kPeers) return exit_code;  // nothing ran
  const double loop_s = static_cast<double>(monotonic_ns() - loop_start_ns_) * 1e-9;
  if (exit_code == kExitOk && !ended_in_order_) hooks_.at_end(*this);
  return summary(exit_code, loop_s);
}

int DriveNode::summary(int exit_code, double loop_s) {
  const std::uint64_t k = k_;
  const drive::DriveCounters& c = loop_.counters();
  auto& s = rt_.status.status();
  s.late(c.late);
  s.rejected(c.rejected + c.foreign);
  s.deadline_misses(loop_.statistics().deadline_misses());
  publish_drive_state(k);
  rt_.status.publish(node_state::STATE_STOPPING, k, period_s_, "done");
  const auto flush_s = node::flush_timeout(exit_code);
  feedback_writer_.wait_for_acknowledgments(flush_s);
  state_writer_.wait_for_acknowledgments(flush_s);
  hooks_.flush(flush_s);
  if (realtime_ && k > 1) {
    const double mean_period = loop_.statistics().mean_period_s();
    std::printf("%s: mean tick period %.3f us (nominal %.3f us, %+.1f ppm)\n", name_.c_str(), mean_period * 1e6,
                period_s_ * 1e6, (mean_period / period_s_ - 1.0) * 1e6);
  }
  const drive::LatencySummary latency = loop_.statistics().latency();
  if (latency.count > 0) {
    std::printf("%s: chain latency feedback -> command over %zu ticks: p50 %.1f us, p99 %.1f us, max %.1f us\n",
                name_.c_str(), latency.count, latency.p50_us, latency.p99_us, latency.max_us);
  }
  if (k > 0 && loop_s > 0.0) {
    // The whole process: in a container, every component of it.
    const double cpu_s = process_cpu_s() - cpu_at_start_s_;
    std::printf("%s: process CPU over the loop: %.1f us a tick, %.3f cores\n", name_.c_str(),
                cpu_s * 1e6 / static_cast<double>(k), cpu_s / loop_s);
  }
  if (c.uncommanded_ticks > 0) {
    std::printf("%s: %llu of %llu ticks got no acceptable command\n", name_.c_str(),
                static_cast<unsigned long long>(c.uncommanded_ticks), static_cast<unsigned long long>(k));
  }
  std::printf(
      "%s: %llu ticks in %.3f s (%.1fx real time), late %llu, rejected %llu, foreign %llu, "
      "deadline misses %llu, safe ticks %llu, drive stalls %llu, drive %s\n",
      name_.c_str(), static_cast<unsigned long long>(k), loop_s, static_cast<double>(k) * period_s_ / loop_s,
      static_cast<unsigned long long>(c.late + hooks_.extra_late()),
      static_cast<unsigned long long>(c.rejected + hooks_.extra_rejected()), static_cast<unsigned long long>(c.foreign),
      static_cast<unsigned long long>(loop_.statistics().deadline_misses()),
      static_cast<unsigned long long>(c.safe_ticks), static_cast<unsigned long long>(c.drive_stalls),
      drive::to_string(backend_.power_state()));
  if (exit_code != kExitOk) return exit_code;
  if (!hooks_.outputs_complete()) {
    std::fprintf(stderr, "%s: an output the run was asked to write is not whole (above): run not valid\n",
                 name_.c_str());
    return kExitError;
  }
  // Stopped by a signal: the operator's stop is no failure, but force-off ticks before it still are.
  if (!loop_.ever_enabled() && !pdds::stop_requested()) {
    std::fprintf(stderr, "%s: the drive was never enabled: no force was applied; run not valid\n", name_.c_str());
    return kExitSafeState;
  }
  if (c.safe_ticks > 0 || backend_.fault_count() != faults_at_start_) {
    std::fprintf(stderr, "%s: force was off for %llu of %llu ticks (fault 0x%04x%s%s): run not valid\n", name_.c_str(),
                 static_cast<unsigned long long>(c.safe_ticks), static_cast<unsigned long long>(k),
                 backend_.error_code(), backend_.fault_detail()[0] != '\0' ? ": " : "", backend_.fault_detail());
    return kExitSafeState;
  }
  return kExitOk;
}

}  // namespace pmlsm::node

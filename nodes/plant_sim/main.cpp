// plant_sim: the simulated servo drive on DDS, a thin adapter over the drive loop
// (common/drive/drive_loop.hpp: arbitration, watchdog, power states, statistics) with the
// simulated drive as its backend. Publishes MotorFeedback (what the drive measures),
// PlantTruth (evaluation only) and DriveState; applies ForceCommand; obeys DriveControl.
//
// Clocks:
//  - lockstep: the plant is the clock. It publishes tick k and integrates to k+1 only when the
//    command answering tick k has arrived: deterministic, as fast as the machine goes.
//  - realtime: ticks on absolute time. The plant waits at most --command-deadline-us into the
//    tick for that tick's command, then holds the newest one; the watchdog faults the drive
//    when feedback stays unanswered for --watchdog-ms; a controller silent for
//    --controller-lost-ms is lost.
//
// Power: the drive starts in switch on disabled. With --auto-enable (the default; simulation
// launch files say so) it walks to operation enabled once its peers are there; otherwise an
// operator enables it (`pmlsm drive enable`). A latched fault is cleared by fault reset and
// enable (`pmlsm drive fault-reset`, `pmlsm drive enable`), never by a restart.
//
// Exit codes: 0 the scenario ran with force on throughout; 4 the controller was lost (lockstep
// timeout; realtime with --on-controller-lost exit); 5 the drive spent ticks with force off
// after it was first enabled (fault, quick stop, disabled) or was never enabled.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "CurrentFeedbackPubSubTypes.h"
#include "DriveControlPubSubTypes.h"
#include "DriveStatePubSubTypes.h"
#include "ForceCommandPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "PlantTruthPubSubTypes.h"
#include "VoltageCommandPubSubTypes.h"
#include "msg_mapping.hpp"
#include "node_support.hpp"
#include "pmlsm/drive/drive_loop.hpp"
#include "pmlsm/drive/tick_clock.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/simulated_drive.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;

struct PlantOptions {
  int peers = 2;
  double watchdog_ms = 3.0;
  std::uint32_t watchdog_arm_ticks = 3;
  double controller_lost_ms = 50.0;
  std::string on_controller_lost = "exit";
  double command_deadline_us = 500.0;
  double wake_early_us = 0.0;
  bool auto_enable = true;
};

class PlantSimNode {
 public:
  PlantSimNode(const node::CommonOptions& common, const PlantOptions& options, node::NodeRuntime& rt)
      : common_(common),
        opt_(options),
        rt_(rt),
        period_s_(rt.period_s),
        ticks_(scenario_ticks(rt.cfg.scenario, period_s_)),
        voltage_level_(rt.cfg.command_level == node::CommandLevel::kVoltage),
        realtime_(rt.cfg.clock == node::Clock::kRealtime),
        feedback_writer_(rt.participant.make_writer<msg::MotorFeedbackPubSubType>(pdds::topics::kMotorFeedback)),
        truth_writer_(rt.participant.make_writer<msg::PlantTruthPubSubType>(pdds::topics::kPlantTruth)),
        command_reader_(rt.participant.make_reader<msg::ForceCommandPubSubType>(pdds::topics::kForceCommand, rt.wakeup)),
        current_writer_(rt.participant.make_writer<msg::CurrentFeedbackPubSubType>(pdds::topics::kCurrentFeedback)),
        voltage_reader_(
            rt.participant.make_reader<msg::VoltageCommandPubSubType>(pdds::topics::kVoltageCommand, rt.wakeup)),
        control_reader_(rt.participant.make_reader<msg::DriveControlPubSubType>(pdds::topics::kDriveControl, rt.wakeup)),
        state_writer_(rt.participant.make_writer<msg::DriveStatePubSubType>(pdds::topics::kDriveState)),
        backend_(rt.cfg.params, scenario_initial_condition(rt.cfg.scenario)),
        loop_(loop_params(), backend_),
        clock_(static_cast<std::int64_t>(std::llround(period_s_ * 1e9)), realtime_,
               static_cast<std::int64_t>(std::llround(options.wake_early_us * 1e3))),
        run_id_(node::new_run_id()) {
    loop_.set_run_id(run_id_);
    drive_state_.drive_name("plant_sim");
  }

  int run();

 private:
  drive::DriveLoopParams loop_params() const {
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
  bool wait_for_peers();
  void enable_at_start();
  /// Takes DriveControl requests addressed to this drive and answers each on DriveState.
  void serve_drive_control();
  void publish_drive_state(std::uint64_t tick);
  void take_commands(std::uint64_t k);
  bool exchange_voltages(std::uint64_t k);
  int finish(std::uint64_t ticks_done, int exit_code, double loop_s);

  const node::CommonOptions& common_;
  PlantOptions opt_;
  node::NodeRuntime& rt_;
  double period_s_;
  std::uint64_t ticks_;
  bool voltage_level_;
  bool realtime_;
  pdds::Writer<msg::MotorFeedbackPubSubType> feedback_writer_;
  pdds::Writer<msg::PlantTruthPubSubType> truth_writer_;
  pdds::Reader<msg::ForceCommandPubSubType> command_reader_;
  pdds::Writer<msg::CurrentFeedbackPubSubType> current_writer_;
  pdds::Reader<msg::VoltageCommandPubSubType> voltage_reader_;
  pdds::Reader<msg::DriveControlPubSubType> control_reader_;
  pdds::Writer<msg::DriveStatePubSubType> state_writer_;
  SimulatedDriveBackend backend_;
  drive::DriveLoop loop_;
  drive::TickClock clock_;
  std::uint64_t run_id_;

  msg::MotorFeedback feedback_;
  msg::PlantTruth truth_;
  msg::ForceCommand command_;
  msg::CurrentFeedback current_feedback_;
  msg::VoltageCommand voltage_command_;
  msg::DriveControl control_;
  msg::DriveState drive_state_;
  eprosima::fastdds::dds::SampleInfo info_;
  double u_d_v_ = 0.0, u_q_v_ = 0.0;  // held voltage at the voltage command level
  std::uint64_t stale_voltages_ = 0, rejected_voltages_ = 0;
  drive::PowerState published_state_ = drive::PowerState::kNotReadyToSwitchOn;
  std::uint64_t refused_requests_ = 0;
  bool watchdog_armed_ = false;
};

bool PlantSimNode::wait_for_peers() {
  rt_.status.publish(node_state::STATE_WAITING, 0, period_s_, "waiting for peers");
  const auto timeout = std::chrono::duration<double>(common_.peer_timeout_s);
  return node::wait_until(rt_.wakeup, timeout, [&] {
    return feedback_writer_.matched_readers() >= static_cast<std::size_t>(opt_.peers) &&
           command_reader_.matched_writers() >= 1 &&
           (!voltage_level_ || (current_writer_.matched_readers() >= 1 && voltage_reader_.matched_writers() >= 1));
  });
}

void PlantSimNode::enable_at_start() {
  const std::int64_t now = monotonic_ns();
  while (const auto next = drive::next_command_towards_operation_enabled(backend_.power_state())) {
    const drive::TransitionResult r = loop_.request(*next, now);
    if (!r.accepted) break;  // cannot happen from switch on disabled; never loop
  }
  std::printf("plant_sim: drive %s (auto-enable)\n", drive::to_string(backend_.power_state()));
}

void PlantSimNode::publish_drive_state(std::uint64_t tick) {
  drive_state_.stamp(node::make_stamp(tick, period_s_, run_id_));
  node::to_msg(backend_, loop_, refused_requests_, drive_state_);
  state_writer_.write(drive_state_);
  published_state_ = backend_.power_state();
}

void PlantSimNode::serve_drive_control() {
  while (control_reader_.take(control_)) {
    const std::string target = control_.drive_name().to_string();
    if (!target.empty() && target != "*" && target != "plant_sim") continue;
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
             drive::to_string(before) + (r.accepted ? " -> " + std::string(drive::to_string(r.to)) : ": " + std::string(r.reason));
    }
    if (!accepted) ++refused_requests_;
    std::printf("plant_sim: drive control from %s (request %llu): %s\n", control_.requester().c_str(),
                static_cast<unsigned long long>(control_.request_id()), text.c_str());
    drive_state_.request_id(control_.request_id());
    drive_state_.request_accepted(accepted);
    drive_state_.request_message(text.substr(0, 127));
    publish_drive_state(loop_.statistics().ticks());
  }
}

void PlantSimNode::take_commands(std::uint64_t k) {
  const auto offer_all = [&] {
    while (!(loop_.answered() && !realtime_) && command_reader_.take(command_, info_)) {
      std::int64_t received_ns = info_.reception_timestamp.to_ns();
      if (received_ns <= 0) received_ns = wall_time_ns();
      loop_.offer(node::from_msg(command_, node::writer_id(info_), received_ns));
    }
    std::uint64_t foreign = 0;
    if (loop_.take_new_foreign_writer(foreign)) {
      std::fprintf(stderr,
                   "plant_sim: a second ForceCommand writer (%016llx) at tick %llu: refused; following %016llx\n",
                   static_cast<unsigned long long>(foreign), static_cast<unsigned long long>(k),
                   static_cast<unsigned long long>(loop_.owner_writer_id()));
      rt_.status.publish(node_state::STATE_RUNNING, k, period_s_, "second ForceCommand writer refused");
    }
    serve_drive_control();
    return loop_.answered();
  };
  if (!realtime_) {
    node::wait_until(rt_.wakeup, std::chrono::duration<double>(common_.peer_timeout_s), offer_all);
    return;
  }
  const std::int64_t deadline = clock_.tick_start_ns() + static_cast<std::int64_t>(opt_.command_deadline_us * 1e3);
  const double wait_s = std::max(0.0, static_cast<double>(deadline - monotonic_ns()) * 1e-9);
  node::wait_until(rt_.wakeup, std::chrono::duration<double>(wait_s), offer_all);
  offer_all();
}

bool PlantSimNode::exchange_voltages(std::uint64_t k) {
  // 32 exchanges per tick: currents out, the controller's voltage back.
  SimulatedDrive& drive = backend_.simulated_drive();
  const bool enabled = backend_.power_state() == drive::PowerState::kOperationEnabled;
  for (int sub = 0; sub < drive.current_steps_per_tick(); ++sub) {
    const PlantMeasurement& m = drive.measurement();
    current_feedback_.stamp(feedback_.stamp());
    current_feedback_.substep(static_cast<std::uint32_t>(sub));
    current_feedback_.i_d_a(m.i_d_a);
    current_feedback_.i_q_a(m.i_q_a);
    current_feedback_.velocity_mps(drive.tick_velocity_mps());
    current_feedback_.position_m(m.encoder_position_m);
    current_writer_.write(current_feedback_);
    bool answered = false;
    const bool ok = node::wait_until(rt_.wakeup, std::chrono::duration<double>(common_.peer_timeout_s), [&] {
      while (!answered && voltage_reader_.take(voltage_command_)) {
        if (voltage_command_.stamp().tick() != k || voltage_command_.substep() != static_cast<std::uint32_t>(sub)) {
          ++stale_voltages_;
        } else {
          if (std::isfinite(voltage_command_.u_d_v()) && std::isfinite(voltage_command_.u_q_v())) {
            u_d_v_ = voltage_command_.u_d_v();
            u_q_v_ = voltage_command_.u_q_v();
          } else {
            ++rejected_voltages_;  // the last finite voltage is held
          }
          answered = true;
        }
      }
      return answered;
    });
    if (!ok) return false;
    // Force off outside operation enabled: no voltage either.
    drive.apply_voltage(enabled ? u_d_v_ : 0.0, enabled ? u_q_v_ : 0.0);
  }
  return true;
}

int PlantSimNode::run() {
  if (!wait_for_peers()) {
    if (pdds::stop_requested()) return kExitOk;
    std::fprintf(stderr, "plant_sim: peers missing after %.1f s: %zu of %d MotorFeedback readers, %zu ForceCommand writers\n",
                 common_.peer_timeout_s, feedback_writer_.matched_readers(), opt_.peers,
                 command_reader_.matched_writers());
    return kExitPeerMissing;
  }
  std::printf("plant_sim: %s clock, %s command level, %llu ticks of %.3g ms, scenario %s, run %016llx\n",
              realtime_ ? "realtime" : "lockstep", voltage_level_ ? "voltage" : "force",
              static_cast<unsigned long long>(ticks_), period_s_ * 1e3, rt_.cfg.scenario.name.c_str(),
              static_cast<unsigned long long>(run_id_));
  if (opt_.auto_enable) enable_at_start();
  publish_drive_state(0);
  rt_.status.publish(node_state::STATE_RUNNING, 0, period_s_, "running");

  int exit_code = kExitOk;
  const auto loop_start = std::chrono::steady_clock::now();
  clock_.start();
  std::uint64_t k = 0;
  for (; k < ticks_ && !pdds::stop_requested(); ++k) {
    const drive::TickReport& report = loop_.begin_tick(k, monotonic_ns(), clock_.tick_start_ns());
    feedback_.stamp(node::make_stamp(k, period_s_, run_id_));
    node::to_msg(report, feedback_);
    const SimulatedDrive& simulated = backend_.simulated_drive();
    node::to_msg(simulated.plant().truth(), {report.applied_force_n, simulated.last_u_d_v(), simulated.last_u_q_v()},
                 truth_);
    truth_.stamp(feedback_.stamp());
    loop_.published(wall_time_ns(), monotonic_ns());
    feedback_writer_.write(feedback_);
    truth_writer_.write(truth_);

    take_commands(k);
    if (!realtime_ && !loop_.answered()) {
      if (pdds::stop_requested()) break;
      std::fprintf(stderr, "plant_sim: no ForceCommand for tick %llu within %.1f s: controller lost; safe state\n",
                   static_cast<unsigned long long>(k), common_.peer_timeout_s);
      rt_.status.publish(node_state::STATE_SAFE, k, period_s_, "controller lost");
      exit_code = kExitPeerLost;
      break;
    }
    if (voltage_level_ && !exchange_voltages(k)) {
      if (pdds::stop_requested()) break;
      std::fprintf(stderr, "plant_sim: no VoltageCommand in tick %llu within %.1f s: controller lost; safe state\n",
                   static_cast<unsigned long long>(k), common_.peer_timeout_s);
      rt_.status.publish(node_state::STATE_SAFE, k, period_s_, "controller lost");
      exit_code = kExitPeerLost;
      break;
    }
    const drive::TickEvents events = loop_.end_tick(monotonic_ns(), !voltage_level_);
    if (loop_.watchdog_armed() != watchdog_armed_) {
      watchdog_armed_ = loop_.watchdog_armed();
      if (watchdog_armed_) {
        std::printf("plant_sim: watchdog armed at tick %llu (%u ticks answered in their own tick)\n",
                    static_cast<unsigned long long>(k), opt_.watchdog_arm_ticks);
      }
    }
    if (events.watchdog_tripped) {
      // The wall time the force went off (the trip may have come at the tick's start).
      const std::int64_t tripped_wall_ns = wall_time_ns() - (monotonic_ns() - events.tripped_mono_ns);
      std::fprintf(stderr,
                   "plant_sim: watchdog: tick %llu unanswered for %.1f ms at tick %llu: fault 0x%04x, zero force "
                   "[wall %.6f s]\n",
                   static_cast<unsigned long long>(events.unanswered_tick), opt_.watchdog_ms,
                   static_cast<unsigned long long>(k), backend_.error_code(), static_cast<double>(tripped_wall_ns) * 1e-9);
      rt_.status.publish(node_state::STATE_SAFE, k, period_s_, "watchdog: feedback unanswered, fault, zero force");
      char reason[128];
      std::snprintf(reason, sizeof reason, "watchdog: feedback of tick %llu unanswered for %.1f ms (tick %llu)",
                    static_cast<unsigned long long>(events.unanswered_tick), opt_.watchdog_ms,
                    static_cast<unsigned long long>(k));
      drive_state_.fault_reason(reason);
    }
    if (events.controller_lost) {
      std::fprintf(stderr, "plant_sim: no acceptable ForceCommand for %.0f ms at tick %llu: controller lost [wall %.6f s]\n",
                   loop_.any_command() ? opt_.controller_lost_ms : common_.peer_timeout_s * 1e3,
                   static_cast<unsigned long long>(k), static_cast<double>(wall_time_ns()) * 1e-9);
      rt_.status.publish(node_state::STATE_SAFE, k, period_s_, "controller lost");
      if (backend_.power_state() == drive::PowerState::kOperationEnabled) loop_.request(drive::DriveCommand::kQuickStop, monotonic_ns());
      if (opt_.on_controller_lost == "exit") {
        exit_code = kExitPeerLost;
        ++k;
        break;
      }
    }
    if (backend_.power_state() != published_state_) publish_drive_state(k);
    if (clock_.wait_next_tick()) loop_.statistics().record_deadline_miss();
    if (k % 1000 == 999) {
      auto& s = rt_.status.status();
      s.late(loop_.counters().late);
      s.rejected(loop_.counters().rejected + loop_.counters().foreign);
      s.deadline_misses(loop_.statistics().deadline_misses());
      rt_.status.publish(backend_.power_state() == drive::PowerState::kOperationEnabled ? node_state::STATE_RUNNING
                                                                                         : node_state::STATE_SAFE,
                         k, period_s_);
      publish_drive_state(k);
    }
  }
  const double loop_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - loop_start).count();
  return finish(k, exit_code, loop_s);
}

int PlantSimNode::finish(std::uint64_t k, int exit_code, double loop_s) {
  const drive::DriveCounters& c = loop_.counters();
  auto& s = rt_.status.status();
  s.late(c.late);
  s.rejected(c.rejected + c.foreign);
  s.deadline_misses(loop_.statistics().deadline_misses());
  publish_drive_state(k);
  rt_.status.publish(node_state::STATE_STOPPING, k, period_s_, "done");
  feedback_writer_.wait_for_acknowledgments(node::kFlushTimeout);
  truth_writer_.wait_for_acknowledgments(node::kFlushTimeout);
  state_writer_.wait_for_acknowledgments(node::kFlushTimeout);
  if (voltage_level_) current_writer_.wait_for_acknowledgments(node::kFlushTimeout);
  if (realtime_ && k > 1) {
    const double mean_period = loop_.statistics().mean_period_s();
    std::printf("plant_sim: mean tick period %.3f us (nominal %.3f us, %+.1f ppm)\n", mean_period * 1e6,
                period_s_ * 1e6, (mean_period / period_s_ - 1.0) * 1e6);
  }
  const drive::LatencySummary latency = loop_.statistics().latency();
  if (latency.count > 0) {
    std::printf("plant_sim: chain latency feedback -> command over %zu ticks: p50 %.1f us, p99 %.1f us, max %.1f us\n",
                latency.count, latency.p50_us, latency.p99_us, latency.max_us);
  }
  if (c.uncommanded_ticks > 0) {
    std::printf("plant_sim: %llu of %llu ticks got no acceptable command\n",
                static_cast<unsigned long long>(c.uncommanded_ticks), static_cast<unsigned long long>(k));
  }
  std::printf("plant_sim: %llu ticks in %.3f s (%.1fx real time), late %llu, rejected %llu, foreign %llu, "
              "deadline misses %llu, safe ticks %llu, drive stalls %llu, drive %s\n",
              static_cast<unsigned long long>(k), loop_s, static_cast<double>(k) * period_s_ / loop_s,
              static_cast<unsigned long long>(c.late + stale_voltages_),
              static_cast<unsigned long long>(c.rejected + rejected_voltages_), static_cast<unsigned long long>(c.foreign),
              static_cast<unsigned long long>(loop_.statistics().deadline_misses()),
              static_cast<unsigned long long>(c.safe_ticks), static_cast<unsigned long long>(c.drive_stalls),
              drive::to_string(backend_.power_state()));
  if (exit_code != kExitOk || pdds::stop_requested()) return exit_code;
  if (!loop_.ever_enabled()) {
    std::fprintf(stderr, "plant_sim: the drive was never enabled: no force was applied; run not valid\n");
    return kExitSafeState;
  }
  if (c.safe_ticks > 0) {
    std::fprintf(stderr, "plant_sim: force was off for %llu of %llu ticks (fault 0x%04x): run not valid\n",
                 static_cast<unsigned long long>(c.safe_ticks), static_cast<unsigned long long>(k),
                 backend_.error_code());
    return kExitSafeState;
  }
  return kExitOk;
}

int run(int argc, char** argv) {
  CLI::App app{"Simulated PMLSM servo drive (plant + drive current loop) on DDS"};
  node::CommonOptions common;
  common.spin_us = 200.0;
  PlantOptions opt;
  node::add_common_options(app, common);
  app.add_option("--peers", opt.peers, "MotorFeedback readers to wait for before tick 0")
      ->check(CLI::Range(1, 64));
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
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  node::NodeRuntime rt("plant_sim", common);
  if (opt.wake_early_us * 1e-6 >= rt.period_s) {
    throw ConfigError("--wake-early-us " + std::to_string(opt.wake_early_us) +
                      ": must be shorter than the control period (" + std::to_string(rt.period_s * 1e6) + " us)");
  }
  if (opt.watchdog_ms * 1e-3 < rt.period_s) {
    throw ConfigError("--watchdog-ms " + std::to_string(opt.watchdog_ms) + ": must be at least one control period (" +
                      std::to_string(rt.period_s * 1e3) + " ms)");
  }
  if (common.wake_batch_us > 0.0) {
    throw ConfigError("--wake-batch-us " + std::to_string(common.wake_batch_us) +
                      ": plant_sim is on the control chain; batching would pace the loop");
  }
  PlantSimNode node(common, opt, rt);
  return node.run();
}

}  // namespace

int main(int argc, char** argv) {
  return pmlsm::node::run_node("plant_sim", [&] { return run(argc, argv); });
}

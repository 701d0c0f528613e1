// What every drive node (plant_sim, drive_bridge) does on DDS around the drive loop
// (common/drive/drive_loop.hpp), whatever its backend: waits for its peers, publishes
// MotorFeedback and DriveState, applies ForceCommand, serves DriveControl, steps the tick
// (lockstep or realtime) as a cycle (cycle_component.hpp: the executor owns the waits and the
// clock's sleep), reports the watchdog and a lost controller, prints the summary and decides the
// exit code. A node adds its own parts through DriveNodeHooks (plant_sim: PlantTruth and the
// voltage level; drive_bridge: the CANopen boot and enable walk).
//
// Exit codes: 0 the scenario ran with force on throughout; 4 the controller was lost (lockstep
// timeout; realtime with --on-controller-lost exit); 5 the drive spent ticks with force off
// after it was first enabled (fault, quick stop, disabled; also when stopped by a signal) or was
// never enabled (a run that ran to its end).
#pragma once

#include <cstdint>
#include <string>

#include "DriveControlPubSubTypes.h"
#include "DriveStatePubSubTypes.h"
#include "ForceCommandPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "cycle_component.hpp"
#include "node_support.hpp"
#include "pmlsm/drive/drive_loop.hpp"
#include "pmlsm/drive/tick_clock.hpp"

namespace pmlsm::node {

struct DriveNodeOptions {
  int peers = 2;
  double watchdog_ms = 3.0;
  std::uint32_t watchdog_arm_ticks = 3;
  double controller_lost_ms = 50.0;
  std::string on_controller_lost = "exit";
  double command_deadline_us = 500.0;
  double wake_early_us = 0.0;
  bool auto_enable = true;
};

/// --peers, --watchdog-ms, --watchdog-arm-ticks, --controller-lost-ms, --on-controller-lost,
/// --command-deadline-us, --wake-early-us, --auto-enable.
void add_drive_node_options(CLI::App& app, DriveNodeOptions& options);
/// The checks against the control period. @throws ConfigError naming the option.
void check_drive_node_options(const char* node_name, const DriveNodeOptions& options, const CommonOptions& common,
                              const NodeRuntime& rt);

class DriveNode;

/// A node's own parts of the tick. Every default does nothing.
class DriveNodeHooks {
 public:
  virtual ~DriveNodeHooks() = default;
  /// Besides the MotorFeedback readers and a ForceCommand writer.
  virtual bool peers_ready() { return true; }
  /// Once the peers are there, before tick 0 (a bridge boots its drive here).
  virtual void before_run(DriveNode& /*node*/) {}
  /// Walks the drive to operation enabled (--auto-enable). Default: the loop's requests,
  /// which a backend with an immediate state machine (the simulation) takes at once.
  virtual void enable_at_start(DriveNode& node);
  /// Tick k's feedback is filled (stamp set), not yet written.
  virtual void before_publish(std::uint64_t /*k*/, const drive::TickReport& /*report*/) {}
  /// Tick k's feedback was written.
  virtual void after_publish(std::uint64_t /*k*/) {}
  /// After tick k's command is in, the node's own exchange within the tick, without waiting:
  /// kFinished when it is done, kWorked when it moved on, kWaiting for an input (named by
  /// awaited(); not coming within the peer timeout, it ends the run as a lost controller).
  virtual Progress exchange(std::uint64_t /*k*/) { return Progress::kFinished; }
  /// What exchange() waits for ("VoltageCommand").
  virtual const char* awaited() const { return ""; }
  /// Whether end_tick applies the force (false: the node drove the period itself).
  virtual bool apply_force() { return true; }
  /// After end_tick and the loop's own reports.
  virtual void after_tick(DriveNode& /*node*/, std::uint64_t /*k*/) {}
  /// The run ended well (at its last tick, once its command is out and before the wait for a
  /// next tick; or stopped by a signal), before the summary: a
  /// backend behind a bus may hand the drive over cleanly (the bridge disables it before its
  /// SYNC stops, so the drive does not fault for the SYNC it no longer gets).
  virtual void at_end(DriveNode& /*node*/) {}
  /// Waits for the node's own writers at the end, at most `timeout` each (node::flush_timeout).
  virtual void flush(std::chrono::seconds /*timeout*/) {}
  /// After flush: false when something the run was asked to write (a bus capture) is not whole; a
  /// run that went well otherwise then exits kExitError.
  virtual bool outputs_complete() { return true; }
  /// Added to the summary's late and rejected counts.
  virtual std::uint64_t extra_late() const { return 0; }
  virtual std::uint64_t extra_rejected() const { return 0; }
};

class DriveNode {
 public:
  /// `backend` and `hooks` must outlive the node.
  DriveNode(std::string name, const CommonOptions& common, const DriveNodeOptions& options, NodeRuntime& rt,
            drive::Drive& backend, DriveNodeHooks& hooks);

  // Its cycle (CycleComponent's, forwarded by DriveComponent): waits for its peers, then a tick is
  // its feedback out, its command in (lockstep: waiting for it; realtime: until the command
  // deadline), the node's exchange, the drive stepped; realtime, then asleep to the next tick.
  void activate();
  CycleStep update();
  std::chrono::duration<double> input_timeout() const;
  int inputs_lost();
  int finish(int exit_code);

  const std::string& name() const { return name_; }
  drive::DriveLoop& loop() { return loop_; }
  drive::Drive& backend() { return backend_; }
  const pmlsm_msgs::msg::MotorFeedback& feedback() const { return feedback_; }
  double period_s() const { return period_s_; }
  bool realtime() const { return realtime_; }
  NodeRuntime& runtime() { return rt_; }
  /// DriveState's fault_reason (at most 127 characters).
  void set_fault_reason(const std::string& reason) { drive_state_.fault_reason(reason.substr(0, 127)); }
  /// NodeStatus now, with `message` (running or safe, as the drive is).
  void report(const std::string& message);
  void publish_drive_state(std::uint64_t tick);

 private:
  enum class Phase {
    kPeers,     ///< waiting for its peers (before tick 0)
    kFeedback,  ///< tick k_ is due: its feedback goes out
    kCommand,   ///< tick k_'s command
    kExchange,  ///< the node's own exchange (the voltage level's)
  };

  drive::DriveLoopParams loop_params() const;
  bool peers_ready();
  /// Takes DriveControl requests addressed to this drive and answers each on DriveState.
  void serve_drive_control();
  /// Offers what ForceCommands arrived to the loop; true when tick k_ is answered.
  bool take_commands();
  /// Tick k_ after its command and exchange: the drive stepped, reports; then the next tick.
  CycleStep end_tick();
  /// Peers missing before tick 0: says which; kExitPeerMissing (kExitOk when stopped meanwhile).
  int report_missing_peers();
  /// What runs, then the hooks' start (boot, enable) and DriveState and NodeStatus of tick 0.
  void start_run();
  /// Tick k's MotorFeedback out.
  void publish_feedback(std::uint64_t k);
  /// The watchdog's arming and trip and a new drive fault, on stdout/stderr and NodeStatus.
  void report_tick_events(std::uint64_t k, const drive::TickEvents& events, std::uint64_t& faults_seen);
  void report_watchdog_trip(std::uint64_t k, const drive::TickEvents& events);
  /// A lost controller: says so, quick-stops an enabled drive; true with --on-controller-lost exit.
  bool controller_lost_ends_run(std::uint64_t k);
  /// NodeStatus with the counts, and DriveState (every 1000 ticks).
  void publish_periodic_status(std::uint64_t k);
  /// The run's summary; the exit code.
  int summary(int exit_code, double loop_s);

  std::string name_;
  const CommonOptions& common_;
  DriveNodeOptions opt_;
  NodeRuntime& rt_;
  drive::Drive& backend_;
  DriveNodeHooks& hooks_;
  double period_s_;
  std::uint64_t ticks_;
  bool voltage_level_;
  bool realtime_;
  dds::Writer<pmlsm_msgs::msg::MotorFeedbackPubSubType> feedback_writer_;
  dds::Reader<pmlsm_msgs::msg::ForceCommandPubSubType> command_reader_;
  dds::Reader<pmlsm_msgs::msg::DriveControlPubSubType> control_reader_;
  dds::Writer<pmlsm_msgs::msg::DriveStatePubSubType> state_writer_;
  drive::DriveLoop loop_;
  drive::TickClock clock_;
  std::uint64_t run_id_;

  pmlsm_msgs::msg::MotorFeedback feedback_;
  pmlsm_msgs::msg::ForceCommand command_;
  pmlsm_msgs::msg::DriveControl control_;
  pmlsm_msgs::msg::DriveState drive_state_;
  eprosima::fastdds::dds::SampleInfo info_;
  drive::PowerState published_state_ = drive::PowerState::kNotReadyToSwitchOn;
  std::uint64_t refused_requests_ = 0;
  bool watchdog_armed_ = false;
  std::uint64_t faults_at_start_ = 0;  ///< backend faults before tick 0: later ones make the run not valid
  std::uint64_t faults_seen_ = 0;
  double cpu_at_start_s_ = 0.0;  ///< the process's CPU time when the loop started
  std::int64_t loop_start_ns_ = 0;
  Phase phase_ = Phase::kPeers;
  std::uint64_t k_ = 0;  ///< the tick in hand; at the end, the ticks done
  std::int64_t command_deadline_ns_ = 0;
  bool ended_in_order_ = false;  ///< at_end ran on the last tick
};

/// A drive node's component: the subclass makes its runtime, hooks and DriveNode and hands the
/// node over in its constructor (drive_with); this hands the cycle to the node.
class DriveComponent : public CycleComponent {
 public:
  void activate() override { node_->activate(); }
  Update update() override { return node_->update(); }
  std::chrono::duration<double> input_timeout() const override { return node_->input_timeout(); }
  int inputs_lost() override { return node_->inputs_lost(); }
  int finish(int exit_code) override { return node_->finish(exit_code); }
  dds::Wakeup& wakeup() override { return node_->runtime().wakeup; }

 protected:
  void drive_with(DriveNode& node) { node_ = &node; }

 private:
  DriveNode* node_ = nullptr;
};

}  // namespace pmlsm::node

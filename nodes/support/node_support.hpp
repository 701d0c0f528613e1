// What every node shares: the common command-line options, config loading
// with the exit codes the launcher reports, stamps, and the NodeStatus
// heartbeat. Nodes stay thin: parse, load, wire topics, run the loop.
#pragma once

#include "pmlsm/util/data_files.hpp"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "NodeStatusPubSubTypes.h"
#include "StampPubSubTypes.h"
#include "component.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/dds/participant.hpp"
#include "pmlsm/dds/shutdown.hpp"
#include "pmlsm/util/clock.hpp"
#include "pmlsm/util/exit_codes.hpp"
#include "realtime_setup.hpp"
#include "input_end.hpp"
#include "tick_filter.hpp"

// Only declared: <CLI/CLI.hpp> (CLI11 2.1.2, header-only) costs 5-9 s of CPU in every file that
// includes it, so only the files that declare options include it (see nodes/support/CMakeLists.txt).
namespace CLI {
class App;
}  // namespace CLI

namespace pmlsm::node {

/// How long a node waits at exit for its last samples to be acknowledged: an
/// observer may be seconds behind a fast lockstep run. (Destroying a writer whose dead
/// reader is still matched does not hang: dds::Participant empties the histories first,
/// see ~Participant.)
inline constexpr std::chrono::seconds kFlushTimeout{15};
/// After a lost peer (kExitPeerLost) the lost one's readers stay matched until its
/// lease (20 s, configs/dds/profiles.xml) runs out and would never acknowledge: the
/// live readers get this long.
inline constexpr std::chrono::seconds kFlushAfterLostPeer{1};

/// The exit-time flush's timeout for a run ending with `exit_code`.
constexpr std::chrono::seconds flush_timeout(int exit_code) {
  return exit_code == kExitPeerLost ? kFlushAfterLostPeer : kFlushTimeout;
}

enum class Clock { kLockstep, kRealtime };
enum class CommandLevel { kForce, kVoltage };

struct CommonOptions {
  std::string config_path = pmlsm::data_file("configs/system.yaml");
  std::string scenario_path = pmlsm::data_file("configs/scenarios/pulse.yaml");
  std::vector<std::string> overrides;
  dds::ParticipantOptions dds;
  std::string clock = "lockstep";
  std::string command_level = "force";
  double peer_timeout_s = 10.0;
  /// How long the loop thread polls for an answer before it sleeps: worth it
  /// on the control chain (plant, controller), wasted CPU for observers.
  double spin_us = 0.0;
  /// Observers off the chain: wake every this many microseconds and take what
  /// arrived, instead of on every sample (0: on every sample).
  double wake_batch_us = 0.0;
  /// Realtime, on the chain: once the plant ticks, no MotorFeedback for this long means it is
  /// gone (a drive sends feedback every tick, in its safe state too).
  double plant_lost_ms = 50.0;
  /// Realtime: reliable or best_effort reading of the chain's inputs from other processes
  /// (chain_input_profile).
  std::string realtime_inputs = "reliable";
  /// Real-time priority, PM QoS latency request (--rt-priority, --cpu-dma-latency-us).
  RealtimeOptions realtime;
};

/// Adds --config, --scenario, --set, --profiles, --participant-profile, --domain, --clock,
/// --peer-timeout-s, --spin-us and --wake-batch-us (their defaults are what `options` holds),
/// --rt-priority, --cpu-dma-latency-us.
void add_common_options(CLI::App& app, CommonOptions& options);

struct LoadedConfig {
  SystemParams params;
  Scenario scenario;
  Clock clock = Clock::kLockstep;
  CommandLevel command_level = CommandLevel::kForce;
  /// Realtime with --realtime-inputs best_effort.
  bool best_effort_inputs = false;
};

/// @throws ConfigError naming the file, key path and value.
LoadedConfig load_config(const CommonOptions& options);

/// Parses the command line: an exit code to end with (help printed: 0, bad
/// options: 2), or nothing when the node should go on.
std::optional<int> parse_command_line(CLI::App& app, int argc, char** argv);

/// The drive run a node follows (Stamp.run_id, drawn anew by every start of a drive node).
/// A sample of another run means the drive restarted: the node resets its state and follows
/// the new run from its first tick; the run it left is never taken up again (late samples of
/// it are rejected).
class RunFollower {
 public:
  /// True when `run_id` starts a run this node has not followed before (the first one too).
  bool is_new(std::uint64_t run_id) const { return run_id != current_ && (!any_ || run_id != previous_); }
  bool is_abandoned(std::uint64_t run_id) const { return any_ && run_id == previous_ && run_id != current_; }
  void follow(std::uint64_t run_id) {
    previous_ = current_;
    current_ = run_id;
    if (any_) ++restarts_;
    any_ = true;
  }
  std::uint64_t current() const { return current_; }
  std::uint64_t previous() const { return previous_; }
  /// Runs followed after the first: drive restarts seen.
  std::uint64_t restarts() const { return restarts_; }

 private:
  std::uint64_t current_ = 0;
  std::uint64_t previous_ = 0;
  std::uint64_t restarts_ = 0;
  bool any_ = false;
};

/// After a wait for a peer failed: kExitOk when a stop was requested (the loop just
/// ends), else one line naming what stopped arriving ("controller: no
/// MotorFeedback for tick 812 within 10.0 s: plant lost") and kExitPeerLost.
int end_of_failed_wait(const char* node_name, const char* missing, const char* peer, std::uint64_t tick,
                       double timeout_s);

/// How long a chain node waits for the next MotorFeedback: realtime, once the plant ticks,
/// plant_lost_ms; at the start and in lockstep (a tick may take as long as the slowest node) the
/// peer timeout.
std::chrono::duration<double> feedback_timeout(const CommonOptions& options, Clock clock, bool any_feedback);

/// After that wait failed: kExitOk on a stop request; realtime after the first feedback, one
/// line "<node>: no MotorFeedback for 50 ms after tick N: plant lost [wall 1763...s]", NodeStatus
/// in error and kExitPeerLost; otherwise as end_of_failed_wait.
int end_of_feedback_wait(const char* node_name, const CommonOptions& options, Clock clock, bool any_feedback,
                         std::uint64_t next_tick, double control_period_s, class StatusPublisher& status);

/// Runs a node's body and maps its failures to exit codes with a one-line
/// message on stderr: ConfigError and dds::SecurityConfigError -> 2, anything else -> 1.
int run_node(const std::string& node_name, const std::function<int()>& body);

/// `options` for the participant of node `node_name` (its NodeStatus and discovery name).
dds::ParticipantOptions named(dds::ParticipantOptions options, const std::string& node_name);

std::chrono::nanoseconds spin_time(const CommonOptions& options);

/// The reader profile of a chain input that may come from another process or host: with
/// --realtime-inputs best_effort in realtime dds::kRealtimeInputProfile (a late repair is worth
/// nothing, a lost sample is a gap the node counts), else `reliable_profile` (lockstep: every tick
/// waited for).
inline const char* chain_input_profile(const LoadedConfig& cfg, const char* reliable_profile) {
  return cfg.best_effort_inputs ? dds::kRealtimeInputProfile : reliable_profile;
}

/// Only the DDS options (--profiles, --participant-profile, --domain, --data-sharing, and
/// the security options), for programs that are not part of the control loop (trainer, workers).
void add_dds_options(CLI::App& app, dds::ParticipantOptions& options);

/// --keystore DIR (else $PMLSM_KEYSTORE; "none": open) and --identity NAME.
void add_security_options(CLI::App& app, dds::ParticipantOptions& options);

/// A stamp for tick `tick` of the run `run_id` (the drive's run this node follows; 0: none yet).
pmlsm_msgs::msg::Stamp make_stamp(std::uint64_t tick, double control_period_s, std::uint64_t run_id = 0);

/// A new run id: non-zero, different for every start of a drive node (wall time, pid and a
/// monotonic reading mixed by splitmix64), so a restarted drive is told from the old one.
std::uint64_t new_run_id();

/// 64 bits identifying the writer of a sample (FNV-1a over its GUID).
std::uint64_t writer_id(const eprosima::fastdds::dds::SampleInfo& info);

/// Publishes NodeStatus with this node's counters.
class StatusPublisher {
 public:
  StatusPublisher(dds::Participant& participant, const std::string& node_name);
  pmlsm_msgs::msg::NodeStatus& status() { return status_; }
  void publish(std::uint8_t state, std::uint64_t tick, double control_period_s, const std::string& message = "");

 private:
  dds::Writer<pmlsm_msgs::msg::NodeStatusPubSubType> writer_;
  pmlsm_msgs::msg::NodeStatus status_;
};

/// How a node on the chain (controller, estimator) takes MotorFeedback: in order (TickFilter),
/// following the drive's run (RunFollower); its cycle waits the peer timeout at the start and in
/// lockstep and, in realtime once the plant ticks, the plant-lost timeout (timeout()).
class FeedbackFollower {
 public:
  enum class Next {
    kTick,    ///< the next tick's feedback is in the sample
    kNewRun,  ///< so is the first tick of a restarted drive: reset state (said on stdout and NodeStatus)
    kNone,    ///< not arrived yet
    kEnded,   ///< the run is over or the wait failed: the reason is printed, end with exit_code()
  };

  /// `run_ticks` and `control_period_s`: the run's length, to tell a drive that ran to the end
  /// from one that stopped early when its writer leaves (InputEndWatch).
  FeedbackFollower(const char* node_name, const CommonOptions& options, Clock clock, std::uint64_t run_ticks,
                   double control_period_s)
      : node_name_(node_name),
        options_(options),
        clock_(clock),
        end_watch_(run_ticks, control_period_s, clock == Clock::kRealtime) {}

  /// Takes the feedback after tick `next_tick` - 1 if it has arrived, without waiting, counting the
  /// samples it passes over (duplicates, out of order, implausible jumps, a run already left) in
  /// `rejected`. kEnded (exit 0): the drive's writer left after running to the end and the last
  /// ticks were lost.
  template <typename ReaderT, typename Message>
  Next try_next(ReaderT& reader, Message& sample, std::uint64_t next_tick, double control_period_s,
                StatusPublisher& status, std::uint64_t& rejected) {
    bool got = false, new_run = false;
    while (!got && reader.take(sample)) {
      const std::uint64_t run_id = sample.stamp().run_id();
      if (run_.is_abandoned(run_id)) {
        ++rejected;
        continue;
      }
      if (run_.is_new(run_id)) {
        run_.follow(run_id);
        ticks_ = TickFilter();
        new_run = run_.restarts() > 0;
      }
      if (!ticks_.accept(sample.stamp().tick())) {
        ++rejected;
        continue;
      }
      got = true;
    }
    if (!got) {
      if (!end_watch_.tail_lost(reader.matched_writers(), next_tick, monotonic_ns())) return Next::kNone;
      report_tail_lost(next_tick);
      exit_code_ = kExitOk;
      return Next::kEnded;
    }
    any_feedback_ = true;
    end_watch_.taken(monotonic_ns());
    if (!new_run) return Next::kTick;
    report_new_run(sample.stamp().tick(), control_period_s, status);
    return Next::kNewRun;
  }

  /// How long the next feedback may take: the peer timeout at the start and in lockstep, realtime
  /// once the plant ticks the plant-lost timeout.
  std::chrono::duration<double> timeout() const { return feedback_timeout(options_, clock_, any_feedback_); }

  /// The feedback did not come within timeout(): says so (end_of_feedback_wait) and returns the exit code.
  int lost(std::uint64_t next_tick, double control_period_s, StatusPublisher& status) {
    exit_code_ = end_of_feedback_wait(node_name_, options_, clock_, any_feedback_, next_tick, control_period_s, status);
    return exit_code_;
  }

  const RunFollower& run() const { return run_; }
  int exit_code() const { return exit_code_; }

 private:
  void report_new_run(std::uint64_t tick, double control_period_s, StatusPublisher& status);
  void report_tail_lost(std::uint64_t next_tick) const;

  const char* node_name_;
  const CommonOptions& options_;
  Clock clock_;
  TickFilter ticks_;
  RunFollower run_;
  InputEndWatch end_watch_;
  bool any_feedback_ = false;
  int exit_code_ = kExitOk;
};

/// What every node builds once its command line is parsed: the loaded config,
/// its participant, the wake-up its readers signal and its NodeStatus writer.
/// Declared in this order, so they are made in it (and torn down in reverse).
struct NodeRuntime {
  /// In a container (`context` with its bus), the participant's endpoints also take the
  /// in-process path and the wakeup hands the chain thread on instead of blocking it.
  /// @throws ConfigError (exit 2) or std::runtime_error from DDS (exit 1).
  NodeRuntime(const std::string& node_name, CommonOptions& options, const ComponentContext& context = {});

  /// monotonic_ns() before anything else: what start-up costs (a secure participant's
  /// handshakes among it) is measured from here.
  std::int64_t start_ns;
  LoadedConfig cfg;
  double period_s;
  /// Before the participant, so Fast DDS's threads inherit priority and timer slack.
  RealtimeSetup realtime;
  /// Before the participant: its readers' listeners signal the wakeup until the participant
  /// is gone, so the wakeup must outlive it.
  dds::Wakeup wakeup;
  dds::Participant participant;
  StatusPublisher status;
};

}  // namespace pmlsm::node

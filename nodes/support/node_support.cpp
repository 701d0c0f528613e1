#include "pmlsm/util/data_files.hpp"
#include <CLI/CLI.hpp>
#include "node_support.hpp"

#include <unistd.h>

#include <cstdio>
#include <ctime>
#include <stdexcept>
#include <exception>

#include "pmlsm/dds/shutdown.hpp"
#include "system_file_options.hpp"

namespace pmlsm::node {

void add_dds_options(CLI::App& app, dds::ParticipantOptions& o) {
  o.profiles_file = pmlsm::data_file(o.profiles_file);  // installed programs find theirs (pmlsm/util/data_files.hpp)
  app.add_option("--profiles", o.profiles_file, "Fast DDS XML profiles")->check(CLI::ExistingFile);
  app.add_option("--participant-profile", o.participant_profile, "Participant profile in --profiles");
  app.add_option("--domain", o.domain_id, "DDS domain id")->check(CLI::Range(0, 232));
  app.add_flag("--data-sharing", o.data_sharing,
               "Turn Fast DDS data-sharing on (zero-copy between processes of one host; off by default; "
               "not with --keystore)");
  add_security_options(app, o);
}

void add_security_options(CLI::App& app, dds::ParticipantOptions& o) {
  // A function option, so that an empty value (a launch file's default) also falls back to the
  // environment variable, and "none" overrides it.
  o.keystore = dds::resolve_keystore("");
  app.add_option_function<std::string>(
      "--keystore", [&o](const std::string& value) { o.keystore = dds::resolve_keystore(value); },
      "DDS Security keystore (`pmlsm security create`): authenticate, obey the identity's permissions, "
      "encrypt; 'none': open even when $PMLSM_KEYSTORE is set (default: $PMLSM_KEYSTORE, else open)");
  app.add_option("--identity", o.identity, "The identity in the keystore (default: the node's name)");
}

void add_common_options(CLI::App& app, CommonOptions& o) {
  add_system_file_options(app, o.config_path, o.overrides);
  app.add_option("-s,--scenario", o.scenario_path, "Scenario (YAML)")->check(CLI::ExistingFile);
  add_dds_options(app, o.dds);
  app.add_option("--clock", o.clock, "lockstep (deterministic, as fast as possible) or realtime")
      ->check(CLI::IsMember({"lockstep", "realtime"}));
  app.add_option("--command-level", o.command_level,
                 "force (the drive runs the current loop) or voltage (the controller does, 32 kHz, lockstep only)")
      ->check(CLI::IsMember({"force", "voltage"}));
  app.add_option("--peer-timeout-s", o.peer_timeout_s,
                 "How long to wait for a peer, at start and between lockstep ticks")
      ->check(CLI::PositiveNumber);
  app.add_option("--spin-us", o.spin_us, "Poll this long for an answer before sleeping (latency vs CPU)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10000.0));
  app.add_option("--wake-batch-us", o.wake_batch_us,
                 "Off the control chain: wake every this many us and take a batch of samples instead of "
                 "waking for each (0: wake for each; never on the chain: it paces the loop)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 100000.0));
  app.add_option("--plant-lost-ms", o.plant_lost_ms,
                 "realtime, chain nodes: no MotorFeedback this long after the first -> plant lost, exit 4")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--realtime-inputs", o.realtime_inputs,
                 "realtime: how chain inputs from other processes are read (the estimator's feedback, the "
                 "compensators' estimate and reference, the controller's compensation): reliable, or best_effort "
                 "where they cross a network (a lost sample costs its own tick, not five behind it)")
      ->capture_default_str()
      ->check(CLI::IsMember({"reliable", "best_effort"}));
  app.add_option("--rt-priority", o.realtime.rt_priority,
                 "SCHED_FIFO priority 1..99 for the node and its DDS threads, memory locked (0: normal scheduling)")
      ->check(CLI::Range(0, 99));
  app.add_option("--cpu-dma-latency-us", o.realtime.cpu_dma_latency_us,
                 "While the node runs, keep the cores out of idle states slower to leave than this "
                 "(/dev/cpu_dma_latency; 0: never halt; -1: no request; needs root)")
      ->check(CLI::Range(-1, 10000000));
}

std::chrono::nanoseconds spin_time(const CommonOptions& o) {
  return std::chrono::nanoseconds(static_cast<std::int64_t>(o.spin_us * 1e3));
}

LoadedConfig load_config(const CommonOptions& o) {
  std::vector<ConfigOverride> overrides;
  for (const auto& text : o.overrides) overrides.push_back(ConfigOverride::parse(text));
  LoadedConfig c;
  c.params = load_system_params(o.config_path, overrides);
  c.scenario = load_scenario(o.scenario_path, c.params.timing.control_period_s);
  c.clock = o.clock == "realtime" ? Clock::kRealtime : Clock::kLockstep;
  c.command_level = o.command_level == "voltage" ? CommandLevel::kVoltage : CommandLevel::kForce;
  // Lockstep waits for every tick: its inputs stay reliable whatever is asked.
  c.best_effort_inputs = c.clock == Clock::kRealtime && o.realtime_inputs == "best_effort";
  if (c.command_level == CommandLevel::kVoltage && c.clock == Clock::kRealtime) {
    throw ConfigError(
        "--command-level voltage: runs in lockstep only (a 32 kHz exchange over DDS is a simulation device), got "
        "--clock realtime");
  }
  return c;
}

std::optional<int> parse_command_line(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? kExitOk : kExitBadConfig;
  }
  return std::nullopt;
}

int end_of_failed_wait(const char* node_name, const char* missing, const char* peer, std::uint64_t tick,
                       double timeout_s) {
  if (dds::stop_requested()) return kExitOk;
  std::fprintf(stderr, "%s: no %s for tick %llu within %.1f s: %s lost\n", node_name, missing,
               static_cast<unsigned long long>(tick), timeout_s, peer);
  return kExitPeerLost;
}

std::chrono::duration<double> feedback_timeout(const CommonOptions& o, Clock clock, bool any_feedback) {
  if (clock == Clock::kRealtime && any_feedback) return std::chrono::duration<double>(o.plant_lost_ms * 1e-3);
  return std::chrono::duration<double>(o.peer_timeout_s);
}

int end_of_feedback_wait(const char* node_name, const CommonOptions& o, Clock clock, bool any_feedback,
                         std::uint64_t next_tick, double control_period_s, StatusPublisher& status) {
  if (clock != Clock::kRealtime || !any_feedback || dds::stop_requested()) {
    return end_of_failed_wait(node_name, "MotorFeedback", "plant", next_tick, o.peer_timeout_s);
  }
  std::fprintf(stderr, "%s: no MotorFeedback for %.0f ms after tick %llu: plant lost [wall %.6f s]\n", node_name,
               o.plant_lost_ms, static_cast<unsigned long long>(next_tick == 0 ? 0 : next_tick - 1),
               static_cast<double>(wall_time_ns()) * 1e-9);
  status.publish(pmlsm_msgs::msg::NodeStatus_Constants::STATE_ERROR, next_tick, control_period_s, "plant lost");
  return kExitPeerLost;
}

void FeedbackFollower::report_tail_lost(std::uint64_t next_tick) const {
  std::printf(
      "%s: the drive's MotorFeedback writer left after running to the end; the run's last %llu tick(s) "
      "never arrived (lost on a best-effort input)\n",
      node_name_, static_cast<unsigned long long>(end_watch_.missing(next_tick)));
}

void FeedbackFollower::report_new_run(std::uint64_t tick, double control_period_s, StatusPublisher& status) {
  std::printf("%s: the drive restarted (run %016llx -> %016llx) at its tick %llu: following the new run\n", node_name_,
              static_cast<unsigned long long>(run_.previous()), static_cast<unsigned long long>(run_.current()),
              static_cast<unsigned long long>(tick));
  status.publish(pmlsm_msgs::msg::NodeStatus_Constants::STATE_RUNNING, tick, control_period_s,
                 "drive restarted: new run followed");
}

int run_node(const std::string& node_name, const std::function<int()>& body) {
  dds::install_shutdown_handlers();
  // Line-buffered even into the launcher's pipe, so lines appear as they happen.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  try {
    return body();
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "%s: config error: %s\n", node_name.c_str(), e.what());
    return kExitBadConfig;
  } catch (const dds::SecurityConfigError& e) {
    std::fprintf(stderr, "%s: security error: %s\n", node_name.c_str(), e.what());
    return kExitBadConfig;
  } catch (const std::invalid_argument& e) {
    // A component refused its parameters at construction: they come from the config or the
    // command line, so this is bad input too (loops never throw once running).
    std::fprintf(stderr, "%s: config error: parameters refused: %s\n", node_name.c_str(), e.what());
    return kExitBadConfig;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: error: %s\n", node_name.c_str(), e.what());
    return kExitError;
  }
}

pmlsm_msgs::msg::Stamp make_stamp(std::uint64_t tick, double control_period_s, std::uint64_t run_id) {
  pmlsm_msgs::msg::Stamp s;
  s.run_id(run_id);
  s.tick(tick);
  s.sim_time_ns(static_cast<std::int64_t>(static_cast<double>(tick) * control_period_s * 1e9 + 0.5));
  s.source_time_ns(wall_time_ns());
  return s;
}

dds::ParticipantOptions named(dds::ParticipantOptions options, const std::string& node_name) {
  options.node_name = node_name;
  return options;
}

namespace {
/// A runtime's participant: named, and in a container on its in-process path (paced toward
/// outside readers in lockstep).
dds::ParticipantOptions runtime_participant(dds::ParticipantOptions options, const std::string& node_name,
                                            const ComponentContext& context, Clock clock) {
  options = named(std::move(options), node_name);
  options.local_bus = context.local_bus;
  options.shared = context.participant;
  options.pace_remote_readers = context.local_bus != nullptr && clock == Clock::kLockstep;
  return options;
}
}  // namespace

int run_standalone(const char* node_name, ComponentFactory make, int argc, char** argv) {
  return run_node(node_name, [&] {
    MadeComponent made = make(ComponentContext{}, argc, argv);
    return made.component ? made.component->run() : made.exit_code;
  });
}

NodeRuntime::NodeRuntime(const std::string& node_name, CommonOptions& options, const ComponentContext& context)
    : start_ns(monotonic_ns()),
      cfg(load_config(options)),
      period_s(cfg.params.timing.control_period_s),
      // In a container the container sets up its chain thread (container --rt-priority).
      realtime(context.local_bus == nullptr ? options.realtime : RealtimeOptions{}),
      wakeup(spin_time(options), std::chrono::nanoseconds(static_cast<std::int64_t>(options.wake_batch_us * 1e3)),
             context.local_bus != nullptr ? &context.local_bus->scheduler() : nullptr),
      participant(runtime_participant(options.dds, node_name, context, cfg.clock)),
      status(participant, node_name) {
  if (options.realtime.rt_priority > 0 || options.realtime.cpu_dma_latency_us >= 0) {
    if (context.local_bus != nullptr) {
      std::printf(
          "%s: in a container: --rt-priority and --cpu-dma-latency-us are the container's (its chain "
          "thread's)\n",
          node_name.c_str());
    } else {
      std::printf("%s: real-time setup: %s\n", node_name.c_str(), realtime.summary().c_str());
    }
  }
}

StatusPublisher::StatusPublisher(dds::Participant& participant, const std::string& node_name)
    : writer_(participant.make_writer(dds::topics::kNodeStatus)) {
  char host[64] = {};
  gethostname(host, sizeof host - 1);
  status_.node_name(node_name);
  status_.host_name(host);
  status_.pid(static_cast<std::uint32_t>(getpid()));
}

void StatusPublisher::publish(std::uint8_t state, std::uint64_t tick, double control_period_s,
                              const std::string& message) {
  status_.stamp(make_stamp(tick, control_period_s));
  status_.state(state);
  status_.ticks(tick);
  if (!message.empty()) status_.message(message);
  writer_.write(status_);
}

namespace {

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

}  // namespace

std::uint64_t new_run_id() {
  std::uint64_t id =
      splitmix64(static_cast<std::uint64_t>(wall_time_ns()) ^ (static_cast<std::uint64_t>(getpid()) << 32) ^
                 splitmix64(static_cast<std::uint64_t>(monotonic_ns())));
  return id == 0 ? 1 : id;
}

std::uint64_t writer_id(const eprosima::fastdds::dds::SampleInfo& info) {
  const auto& guid = info.sample_identity.writer_guid();
  std::uint64_t h = 1469598103934665603ULL;
  const auto mix = [&h](std::uint8_t byte) {
    h ^= byte;
    h *= 1099511628211ULL;
  };
  for (auto b : guid.guidPrefix.value) mix(b);
  for (auto b : guid.entityId.value) mix(b);
  return h;
}

}  // namespace pmlsm::node

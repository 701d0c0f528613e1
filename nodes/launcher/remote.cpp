#include "remote.hpp"

#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <map>
#include <set>

#include "AgentAnnouncePubSubTypes.h"
#include "LaunchRequestPubSubTypes.h"
#include "NodeExitPubSubTypes.h"
#include "NodeOutputPubSubTypes.h"
#include "node_support.hpp"
#include "pmlsm/agent/agent.hpp"
#include "pmlsm/dds/shutdown.hpp"

namespace pmlsm::launch {
namespace {

namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;
using SteadyClock = std::chrono::steady_clock;
using Kind = agent::LaunchCoordinator::Action::Kind;

std::string requester() {
  char host[128] = {};
  gethostname(host, sizeof(host) - 1);
  const char* user = std::getenv("USER");
  return std::string(user != nullptr ? user : "launcher") + "@" + host + ":" + std::to_string(::getpid());
}

void say(const std::string& text) { std::cerr << "[launcher] " << text << std::endl; }

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& i : items) out += (out.empty() ? "" : ", ") + i;
  return out;
}

/// Each host's slice of the launch, the hosts in file order.
struct HostSlices {
  std::vector<std::string> hosts;
  std::map<std::string, std::string> yaml;  // host -> its slice as a launch description
  std::vector<agent::LaunchCoordinator::HostSlice> coordinator_slices;
};

/// The slices of the hosts with nodes; false (said) when one is too large for a launch request.
bool make_host_slices(const LaunchDescription& launch, const std::vector<NodeSpec>& nodes, HostSlices& out) {
  std::map<std::string, std::vector<NodeSpec>> nodes_of;
  for (const auto& n : nodes) {
    if (nodes_of.count(n.host) == 0) out.hosts.push_back(n.host);
    nodes_of[n.host].push_back(n);
  }
  for (const auto& h : out.hosts) {
    bool ends = false;
    for (const auto& n : nodes_of[h]) ends = ends || n.ends_launch;
    out.coordinator_slices.push_back({h, ends});
    const std::string& text = out.yaml[h] = slice_yaml(launch.name, h, nodes_of[h]);
    if (text.size() > 16384) {
      say("error: the slice of host " + h + " is " + std::to_string(text.size()) +
          " bytes; a launch request holds at most 16384");
      return false;
    }
  }
  return true;
}

pdds::ParticipantOptions launcher_participant_options(const RemoteOptions& options) {
  pdds::ParticipantOptions dds_options = options.dds;
  dds_options.node_name = "launcher";
  if (dds_options.identity.empty()) dds_options.identity = "launcher";
  return dds_options;
}

/// One launch over the hosts' agents: DDS in and out; the decisions are the coordinator's.
class AgentLaunch {
 public:
  AgentLaunch(const HostSlices& slices, const RemoteOptions& options, SteadyClock::time_point start)
      : slices_(slices),
        options_(options),
        start_(start),
        participant_(launcher_participant_options(options)),
        request_writer_(participant_.make_writer(pdds::topics::kLaunchRequest)),
        announce_reader_(participant_.make_reader(pdds::topics::kAgentAnnounce, wakeup_)),
        output_reader_(participant_.make_reader(pdds::topics::kNodeOutput, wakeup_)),
        exit_reader_(participant_.make_reader(pdds::topics::kNodeExit, wakeup_)),
        launch_id_(node::new_run_id()),
        requester_(requester()),
        coordinator_(slices.coordinator_slices, options.agent_wait, options.lease, start),
        keepalive_(options.lease / 4),
        next_send_(start),
        next_keepalive_(start) {}

  std::uint64_t launch_id() const { return launch_id_; }

  /// Until every slice ended (or was stopped); the launch's exit code.
  int run();

 private:
  using Phase = agent::LaunchCoordinator::Phase;

  void send(const std::string& host, std::uint8_t command);
  void act(const agent::LaunchCoordinator::Action& a, SteadyClock::time_point now);
  void take_announcements(SteadyClock::time_point now);
  /// The nodes' output lines, prefixed with host and node, on the launcher's stdout or stderr.
  void print_node_output();
  void take_node_events(SteadyClock::time_point now);
  void send_due_requests(Phase phase, SteadyClock::time_point now);

  const HostSlices& slices_;
  const RemoteOptions& options_;
  SteadyClock::time_point start_;
  pdds::Wakeup wakeup_;  // outlives the participant, whose listeners signal it
  pdds::Participant participant_;
  pdds::Writer<msg::LaunchRequestPubSubType> request_writer_;
  pdds::Reader<msg::AgentAnnouncePubSubType> announce_reader_;
  pdds::Reader<msg::NodeOutputPubSubType> output_reader_;
  pdds::Reader<msg::NodeExitPubSubType> exit_reader_;
  std::uint64_t launch_id_;
  std::string requester_;
  agent::LaunchCoordinator coordinator_;
  std::map<std::string, std::string> agent_of_;  // host -> agent id
  std::set<std::string> confirmed_;              // hosts whose agent answered the start (started or refused)
  static constexpr std::chrono::milliseconds kResend{250};
  std::chrono::milliseconds keepalive_;
  SteadyClock::time_point next_send_;
  SteadyClock::time_point next_keepalive_;
  msg::AgentAnnounce announce_;
  msg::NodeOutput output_;
  msg::NodeExit event_;
};

void AgentLaunch::send(const std::string& host, std::uint8_t command) {
  msg::LaunchRequest r;
  r.stamp(node::make_stamp(0, 1e-3));
  r.launch_id(launch_id_);
  r.host_name(host);
  r.command(command);
  r.requester(requester_.substr(0, 64));
  r.lease_ms(static_cast<std::uint32_t>(options_.lease.count()));
  r.start_grace_ms(static_cast<std::uint32_t>(options_.start_grace_ms));
  r.stop_timeout_ms(static_cast<std::uint32_t>(options_.stop_timeout_ms));
  if (command == msg::LaunchRequest_Constants::COMMAND_START) r.slice_yaml(slices_.yaml.at(host));
  request_writer_.write(r);
}

void AgentLaunch::act(const agent::LaunchCoordinator::Action& a, SteadyClock::time_point now) {
  if (a.kind == Kind::kStartAll) {
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now - start_).count();
    say("agents of all " + std::to_string(slices_.hosts.size()) + " hosts found " + std::to_string(ms) +
        " ms after the launch command; sending the slices");
    next_send_ = now;
  } else if (a.kind == Kind::kStopAll) {
    say("stopping every host: " + a.reason);
    next_send_ = now;
  }
}

void AgentLaunch::take_announcements(SteadyClock::time_point now) {
  while (announce_reader_.take(announce_)) {
    const std::string host = announce_.host_name().to_string();
    if (slices_.yaml.count(host) == 0) continue;
    auto& known = agent_of_[host];
    if (known != announce_.agent_id().to_string()) {
      known = announce_.agent_id().to_string();
      say("agent " + known + " serves host " + host + (announce_.secure() ? "" : " (INSECURE: no keystore)"));
    }
    coordinator_.on_announce(host, now);
  }
}

void AgentLaunch::print_node_output() {
  while (output_reader_.take(output_)) {
    if (output_.launch_id() != launch_id_) continue;
    const std::string node_name = output_.node_name().to_string();
    const std::string prefix =
        "[" + output_.host_name().to_string() + "/" + (node_name.empty() ? std::string("launcher") : node_name) + "] ";
    if (output_.stream() == msg::NodeOutput_Constants::STREAM_STDOUT) {
      std::cout << prefix << output_.line().to_string() << std::endl;
    } else {
      std::cerr << prefix << output_.line().to_string() << std::endl;
    }
  }
}

void AgentLaunch::take_node_events(SteadyClock::time_point now) {
  while (exit_reader_.take(event_)) {
    if (event_.launch_id() != launch_id_) continue;
    const std::string host = event_.host_name().to_string();
    confirmed_.insert(host);
    switch (event_.event()) {
      case msg::NodeExit_Constants::EVENT_STARTED: {
        act(coordinator_.on_started(host), now);
        break;
      }
      case msg::NodeExit_Constants::EVENT_REFUSED:
        say("host " + host + " refused its slice: " + event_.message().to_string());
        act(coordinator_.on_refused(host, event_.message().to_string()), now);
        break;
      case msg::NodeExit_Constants::EVENT_ENDED:
        say("host " + host + ": " + event_.message().to_string());
        act(coordinator_.on_ended(host, event_.exit_code(), event_.message().to_string()), now);
        break;
      default: break;
    }
  }
}

void AgentLaunch::send_due_requests(Phase phase, SteadyClock::time_point now) {
  // Requests are repeated until answered: an agent's reader may match a moment after its
  // announcement arrived; an agent ignores a request it already acted on.
  if (now >= next_send_) {
    next_send_ = now + kResend;
    for (const auto& host : coordinator_.unfinished_hosts()) {
      if (phase == Phase::kRunning && confirmed_.count(host) == 0)
        send(host, msg::LaunchRequest_Constants::COMMAND_START);
      if (phase == Phase::kStopping) send(host, msg::LaunchRequest_Constants::COMMAND_STOP);
    }
  }
  if (phase != Phase::kWaitingForAgents && now >= next_keepalive_) {
    next_keepalive_ = now + keepalive_;
    for (const auto& host : coordinator_.unfinished_hosts())
      send(host, msg::LaunchRequest_Constants::COMMAND_KEEPALIVE);
  }
}

int AgentLaunch::run() {
  bool interrupted = false;
  while (coordinator_.phase() != Phase::kDone) {
    const auto now = SteadyClock::now();
    if (pdds::stop_requested() && !interrupted) {
      interrupted = true;
      say("got a stop request (Ctrl-C or SIGTERM)");
      act(coordinator_.on_interrupt(), now);
    }
    take_announcements(now);
    print_node_output();
    take_node_events(now);
    act(coordinator_.step(now), now);
    const auto phase = coordinator_.phase();
    if (phase == Phase::kDone) break;
    send_due_requests(phase, now);
    const std::uint64_t seen = wakeup_.generation();
    wakeup_.wait_for(seen, std::chrono::milliseconds(20));
  }

  const int code = coordinator_.exit_code();
  if (code == kExitOk) {
    say("all " + std::to_string(slices_.hosts.size()) + " hosts' slices ended cleanly");
  } else {
    say("launch failed with exit code " + std::to_string(code) + " (" + exit_code_meaning(code) +
        "): " + join(coordinator_.failures()));
  }
  request_writer_.wait_for_acknowledgments(std::chrono::seconds(1));
  return code;
}

}  // namespace

int run_over_agents(const LaunchDescription& launch, const std::vector<NodeSpec>& nodes, const RemoteOptions& options) {
  HostSlices slices;
  if (!make_host_slices(launch, nodes, slices)) return kExitBadConfig;
  pdds::install_shutdown_handlers();
  AgentLaunch agent_launch(slices, options, SteadyClock::now());
  say(launch.name + ": " + std::to_string(nodes.size()) + " nodes on " + std::to_string(slices.hosts.size()) +
      " hosts (" + join(slices.hosts) + ") through their agents, launch " + std::to_string(agent_launch.launch_id()) +
      "; waiting up to " + std::to_string(options.agent_wait.count()) + " ms for every host's agent");
  return agent_launch.run();
}

}  // namespace pmlsm::launch

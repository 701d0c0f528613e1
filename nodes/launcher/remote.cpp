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

}  // namespace

int run_over_agents(const LaunchDescription& launch, const std::vector<NodeSpec>& nodes, const RemoteOptions& options) {
  // Hosts with nodes, in file order, and each one's slice.
  std::vector<std::string> hosts;
  std::map<std::string, std::vector<NodeSpec>> slices;
  for (const auto& n : nodes) {
    if (slices.count(n.host) == 0) hosts.push_back(n.host);
    slices[n.host].push_back(n);
  }
  std::vector<agent::LaunchCoordinator::HostSlice> host_slices;
  std::map<std::string, std::string> slice_text;
  for (const auto& h : hosts) {
    bool ends = false;
    for (const auto& n : slices[h]) ends = ends || n.ends_launch;
    host_slices.push_back({h, ends});
    slice_text[h] = slice_yaml(launch.name, h, slices[h]);
    if (slice_text[h].size() > 16384) {
      say("error: the slice of host " + h + " is " + std::to_string(slice_text[h].size()) +
          " bytes; a launch request holds at most 16384");
      return kExitBadConfig;
    }
  }

  pdds::install_shutdown_handlers();
  const auto t_start = SteadyClock::now();
  pdds::ParticipantOptions dds_options = options.dds;
  dds_options.node_name = "launcher";
  if (dds_options.identity.empty()) dds_options.identity = "launcher";
  pdds::Wakeup wakeup;
  pdds::Participant participant(dds_options);
  auto request_writer = participant.make_writer(pdds::topics::kLaunchRequest);
  auto announce_reader = participant.make_reader(pdds::topics::kAgentAnnounce, wakeup);
  auto output_reader = participant.make_reader(pdds::topics::kNodeOutput, wakeup);
  auto exit_reader = participant.make_reader(pdds::topics::kNodeExit, wakeup);

  const std::uint64_t launch_id = node::new_run_id();
  const std::string me = requester();
  agent::LaunchCoordinator coordinator(host_slices, options.agent_wait, options.lease, t_start);
  say(launch.name + ": " + std::to_string(nodes.size()) + " nodes on " + std::to_string(hosts.size()) + " hosts (" +
      join(hosts) + ") through their agents, launch " + std::to_string(launch_id) + "; waiting up to " +
      std::to_string(options.agent_wait.count()) + " ms for every host's agent");

  std::map<std::string, std::string> agent_of;  // host -> agent id
  std::set<std::string> confirmed;              // hosts whose agent answered the start (started or refused)
  const auto resend = std::chrono::milliseconds(250);
  const auto keepalive = options.lease / 4;
  auto next_send = t_start;
  auto next_keepalive = t_start;
  bool interrupted = false;

  const auto send = [&](const std::string& host, std::uint8_t command) {
    msg::LaunchRequest r;
    r.stamp(node::make_stamp(0, 1e-3));
    r.launch_id(launch_id);
    r.host_name(host);
    r.command(command);
    r.requester(me.substr(0, 64));
    r.lease_ms(static_cast<std::uint32_t>(options.lease.count()));
    r.start_grace_ms(static_cast<std::uint32_t>(options.start_grace_ms));
    r.stop_timeout_ms(static_cast<std::uint32_t>(options.stop_timeout_ms));
    if (command == msg::LaunchRequest_Constants::COMMAND_START) r.slice_yaml(slice_text[host]);
    request_writer.write(r);
  };
  const auto act = [&](const agent::LaunchCoordinator::Action& a, SteadyClock::time_point now) {
    if (a.kind == Kind::kStartAll) {
      const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now - t_start).count();
      say("agents of all " + std::to_string(hosts.size()) + " hosts found " + std::to_string(ms) +
          " ms after the launch command; sending the slices");
      next_send = now;
    } else if (a.kind == Kind::kStopAll) {
      say("stopping every host: " + a.reason);
      next_send = now;
    }
  };

  msg::AgentAnnounce announce;
  msg::NodeOutput output;
  msg::NodeExit event;
  while (coordinator.phase() != agent::LaunchCoordinator::Phase::kDone) {
    auto now = SteadyClock::now();
    if (pdds::stop_requested() && !interrupted) {
      interrupted = true;
      say("got a stop request (Ctrl-C or SIGTERM)");
      act(coordinator.on_interrupt(), now);
    }
    while (announce_reader.take(announce)) {
      const std::string host = announce.host_name().to_string();
      if (slices.count(host) == 0) continue;
      auto& known = agent_of[host];
      if (known != announce.agent_id().to_string()) {
        known = announce.agent_id().to_string();
        say("agent " + known + " serves host " + host + (announce.secure() ? "" : " (INSECURE: no keystore)"));
      }
      coordinator.on_announce(host, now);
    }
    while (output_reader.take(output)) {
      if (output.launch_id() != launch_id) continue;
      const std::string node_name = output.node_name().to_string();
      const std::string prefix =
          "[" + output.host_name().to_string() + "/" + (node_name.empty() ? std::string("launcher") : node_name) + "] ";
      if (output.stream() == msg::NodeOutput_Constants::STREAM_STDOUT) {
        std::cout << prefix << output.line().to_string() << std::endl;
      } else {
        std::cerr << prefix << output.line().to_string() << std::endl;
      }
    }
    while (exit_reader.take(event)) {
      if (event.launch_id() != launch_id) continue;
      const std::string host = event.host_name().to_string();
      confirmed.insert(host);
      switch (event.event()) {
        case msg::NodeExit_Constants::EVENT_STARTED: {
          act(coordinator.on_started(host), now);
          break;
        }
        case msg::NodeExit_Constants::EVENT_REFUSED:
          say("host " + host + " refused its slice: " + event.message().to_string());
          act(coordinator.on_refused(host, event.message().to_string()), now);
          break;
        case msg::NodeExit_Constants::EVENT_ENDED:
          say("host " + host + ": " + event.message().to_string());
          act(coordinator.on_ended(host, event.exit_code(), event.message().to_string()), now);
          break;
        default: break;
      }
    }
    act(coordinator.step(now), now);
    const auto phase = coordinator.phase();
    if (phase == agent::LaunchCoordinator::Phase::kDone) break;
    // Requests are repeated until answered: an agent's reader may match a moment after its
    // announcement arrived; an agent ignores a request it already acted on.
    if (now >= next_send) {
      next_send = now + resend;
      for (const auto& host : coordinator.unfinished_hosts()) {
        if (phase == agent::LaunchCoordinator::Phase::kRunning && confirmed.count(host) == 0)
          send(host, msg::LaunchRequest_Constants::COMMAND_START);
        if (phase == agent::LaunchCoordinator::Phase::kStopping) send(host, msg::LaunchRequest_Constants::COMMAND_STOP);
      }
    }
    if (phase != agent::LaunchCoordinator::Phase::kWaitingForAgents && now >= next_keepalive) {
      next_keepalive = now + keepalive;
      for (const auto& host : coordinator.unfinished_hosts())
        send(host, msg::LaunchRequest_Constants::COMMAND_KEEPALIVE);
    }
    const std::uint64_t seen = wakeup.generation();
    wakeup.wait_for(seen, std::chrono::milliseconds(20));
  }

  const int code = coordinator.exit_code();
  if (code == kExitOk) {
    say("all " + std::to_string(hosts.size()) + " hosts' slices ended cleanly");
  } else {
    say("launch failed with exit code " + std::to_string(code) + " (" + exit_code_meaning(code) +
        "): " + join(coordinator.failures()));
  }
  request_writer.wait_for_acknowledgments(std::chrono::seconds(1));
  return code;
}

}  // namespace pmlsm::launch

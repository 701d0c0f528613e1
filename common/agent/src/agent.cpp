#include "pmlsm/agent/agent.hpp"

#include <algorithm>
#include <set>
#include <stdexcept>

#include "pmlsm/util/exit_codes.hpp"

namespace pmlsm::agent {

std::vector<std::string> node_programs(const std::vector<std::string>& components) {
  std::vector<std::string> names{"closed_loop", "container"};
  for (const std::string& name : components) {
    if (name == "launcher" || name == "launch_agent" || name == "pmlsm") {
      throw std::invalid_argument("'" + name + "' starts programs itself: never one an agent starts for a launch");
    }
    names.push_back(name);
  }
  return names;
}

// ---------------------------------------------------------------------------------------------
LeaseTracker::LeaseTracker(Millis lease) : lease_(lease) {
  if (lease.count() <= 0)
    throw std::invalid_argument("LeaseTracker: lease must be above 0 ms, got " + std::to_string(lease.count()));
}

void LeaseTracker::heard(const std::string& id, TimePoint now) {
  last_heard_[id] = now;
  reported_[id] = false;
}

bool LeaseTracker::alive(const std::string& id, TimePoint now) const {
  const auto it = last_heard_.find(id);
  return it != last_heard_.end() && now - it->second < lease_;
}

std::vector<std::string> LeaseTracker::expired(TimePoint now) {
  std::vector<std::string> out;
  for (const auto& [id, when] : last_heard_) {
    if (now - when >= lease_ && !reported_[id]) {
      reported_[id] = true;
      out.push_back(id);
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
ExecutablePolicy::ExecutablePolicy(std::vector<std::string> allowed) : allowed_(std::move(allowed)) {
  if (allowed_.empty()) throw std::invalid_argument("ExecutablePolicy: no allowed executable");
  for (const auto& path : allowed_) {
    if (path.empty() || path[0] != '/')
      throw std::invalid_argument("ExecutablePolicy: allowed executable '" + path + "' is not an absolute path");
  }
}

std::string ExecutablePolicy::refusal(const std::string& node, const std::string& executable,
                                      const std::string& resolved) const {
  if (resolved.empty()) return "node '" + node + "': executable '" + executable + "' not found";
  if (std::find(allowed_.begin(), allowed_.end(), resolved) != allowed_.end()) return "";
  std::set<std::string> dirs;
  for (const auto& path : allowed_) dirs.insert(path.substr(0, path.rfind('/')));
  std::string where;
  for (const auto& d : dirs) where += (where.empty() ? "" : ", ") + d;
  return "node '" + node + "': executable '" + executable + "' (" + resolved +
         ") is not one of the pmlsm programs this agent may start (in " + where + ")";
}

// ---------------------------------------------------------------------------------------------
AgentAction AgentMachine::on_start(std::uint64_t launch_id, const std::string& requester, Millis launcher_lease,
                                   const std::string& refusal, TimePoint now) {
  if (state_ != State::kIdle) {
    if (launch_id == launch_id_) return {};  // the same request again
    return {AgentAction::Kind::kRefuse, "busy: running launch " + std::to_string(launch_id_) + " for " + requester_};
  }
  if (launch_id == 0) return {AgentAction::Kind::kRefuse, "launch id 0 is not valid"};
  if (!refusal.empty()) return {AgentAction::Kind::kRefuse, refusal};
  state_ = State::kRunning;
  launch_id_ = launch_id;
  requester_ = requester;
  launcher_lease_ = launcher_lease;
  last_request_ = now;
  return {AgentAction::Kind::kStart, ""};
}

void AgentMachine::on_keepalive(std::uint64_t launch_id, TimePoint now) {
  if (state_ != State::kIdle && launch_id == launch_id_) last_request_ = now;
}

AgentAction AgentMachine::on_stop(std::uint64_t launch_id) {
  if (state_ != State::kRunning || launch_id != launch_id_) return {};
  state_ = State::kStopping;
  return {AgentAction::Kind::kStop, "stop requested by " + requester_};
}

AgentAction AgentMachine::step(TimePoint now) {
  // Without a lease (0) the launcher is trusted to stop the slice itself.
  if (state_ != State::kRunning || launcher_lease_.count() <= 0 || now - last_request_ < launcher_lease_) return {};
  state_ = State::kStopping;
  return {AgentAction::Kind::kStop,
          "launcher " + requester_ + " silent for " + std::to_string(launcher_lease_.count()) + " ms: it is gone"};
}

void AgentMachine::on_slice_ended() {
  state_ = State::kIdle;
  launch_id_ = 0;
  requester_.clear();
}

// ---------------------------------------------------------------------------------------------
LaunchCoordinator::LaunchCoordinator(std::vector<HostSlice> hosts, Millis agent_deadline, Millis lease, TimePoint now)
    : hosts_(std::move(hosts)), deadline_(agent_deadline), leases_(lease), started_(now) {
  if (hosts_.empty()) throw std::invalid_argument("LaunchCoordinator: no host");
  if (agent_deadline.count() <= 0)
    throw std::invalid_argument("LaunchCoordinator: agent deadline must be above 0 ms, got " +
                                std::to_string(agent_deadline.count()));
  for (const auto& h : hosts_) {
    if (!host_state_.emplace(h.name, HostState{}).second)
      throw std::invalid_argument("LaunchCoordinator: host '" + h.name + "' twice");
  }
}

void LaunchCoordinator::on_announce(const std::string& host, TimePoint now) {
  if (host_state_.count(host) != 0 && !host_state_[host].lost) leases_.heard(host, now);
}

void LaunchCoordinator::fail(const std::string& host, int code, const std::string& what) {
  if (failures_.empty()) exit_code_ = code;
  failures_.push_back(host + ": " + what);
}

LaunchCoordinator::Action LaunchCoordinator::stop_all(const std::string& reason) {
  if (phase_ != Phase::kRunning) return {};
  phase_ = Phase::kStopping;
  finish_if_all_ended();
  return {Action::Kind::kStopAll, reason};
}

void LaunchCoordinator::finish_if_all_ended() {
  const bool all = std::all_of(host_state_.begin(), host_state_.end(), [](const auto& kv) { return kv.second.ended; });
  if (all && phase_ != Phase::kWaitingForAgents) phase_ = Phase::kDone;
}

LaunchCoordinator::Action LaunchCoordinator::on_started(const std::string& host) {
  (void)host;  // the slice is followed from here by its agent's lease and its end
  return {};
}

LaunchCoordinator::Action LaunchCoordinator::on_refused(const std::string& host, const std::string& reason) {
  auto it = host_state_.find(host);
  if (it == host_state_.end() || it->second.ended || phase_ == Phase::kWaitingForAgents) return {};
  it->second.ended = true;
  fail(host, kExitBadConfig, "refused: " + reason);
  Action a = stop_all("host " + host + " refused its slice");
  finish_if_all_ended();
  return a;
}

LaunchCoordinator::Action LaunchCoordinator::on_ended(const std::string& host, int exit_code,
                                                      const std::string& summary) {
  auto it = host_state_.find(host);
  if (it == host_state_.end() || it->second.ended || phase_ == Phase::kWaitingForAgents) return {};
  it->second.ended = true;
  Action a;
  if (exit_code != kExitOk) {
    fail(host, exit_code, summary);
    a = stop_all("host " + host + "'s slice failed (exit code " + std::to_string(exit_code) + ")");
  } else {
    const auto slice = std::find_if(hosts_.begin(), hosts_.end(), [&](const HostSlice& h) { return h.name == host; });
    if (slice->ends_launch) a = stop_all("host " + host + "'s slice ended the launch");
  }
  finish_if_all_ended();
  return a;
}

LaunchCoordinator::Action LaunchCoordinator::on_interrupt() {
  interrupted_ = true;
  if (phase_ == Phase::kWaitingForAgents) {
    phase_ = Phase::kDone;
    fail("launcher", kExitError, "interrupted before every host had an agent; nothing started");
    return {};
  }
  return stop_all("interrupted");
}

LaunchCoordinator::Action LaunchCoordinator::step(TimePoint now) {
  if (phase_ == Phase::kWaitingForAgents) {
    if (missing_hosts(now).empty()) {
      phase_ = Phase::kRunning;
      all_agents_at_ = now;
      return {Action::Kind::kStartAll, ""};
    }
    if (now - started_ >= deadline_) {
      for (const auto& host : missing_hosts(now))
        fail(host, kExitPeerMissing,
             "no agent announced this host within " + std::to_string(deadline_.count()) + " ms; nothing started");
      phase_ = Phase::kDone;
    }
    return {};
  }
  Action a;
  for (const auto& host : leases_.expired(now)) {
    auto& state = host_state_[host];
    if (state.ended) continue;
    state.ended = true;
    state.lost = true;
    fail(host, kExitPeerLost,
         "agent lost (no announcement for " + std::to_string(leases_.lease().count()) +
             " ms): its nodes' fate is unknown");
    if (a.kind == Action::Kind::kNone) a = stop_all("the agent of host " + host + " was lost");
  }
  finish_if_all_ended();
  return a;
}

std::vector<std::string> LaunchCoordinator::missing_hosts(TimePoint now) const {
  std::vector<std::string> out;
  for (const auto& h : hosts_)
    if (!leases_.alive(h.name, now)) out.push_back(h.name);
  return out;
}

std::vector<std::string> LaunchCoordinator::unfinished_hosts() const {
  std::vector<std::string> out;
  for (const auto& h : hosts_)
    if (!host_state_.at(h.name).ended) out.push_back(h.name);
  return out;
}

}  // namespace pmlsm::agent

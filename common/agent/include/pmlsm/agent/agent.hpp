// Launch agents: the policy an agent (`pmlsm agent`) and a launcher follow, without DDS or
// processes, so every decision is tested directly (tests/unit/agent/agent_test.cpp).
//   LeaseTracker     who was heard from within its lease (agents by the launcher, the
//                    launcher by an agent)
//   ExecutablePolicy which executables an agent may start: the installed or built pmlsm
//                    programs only
//   AgentMachine     an agent's state: idle, running one launch's slice, stopping it
//   LaunchCoordinator the launcher's side: waits for every host's agent (with a deadline),
//                    starts, follows each slice, stops all when one fails or is lost, and
//                    gives the launch's exit code
// Times are steady_clock points passed in by the caller.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace pmlsm::agent {

using TimePoint = std::chrono::steady_clock::time_point;
using Millis = std::chrono::milliseconds;

/// The programs an agent may start: the registered components (`components`), the container and
/// closed_loop; never a shell, the launcher, the agent itself or the `pmlsm` tool (each of which
/// could start anything: `pmlsm launch`).
/// @throws std::invalid_argument when `components` names one of those.
std::vector<std::string> node_programs(const std::vector<std::string>& components);

/// Peers heard from within `lease` are alive; each that falls silent is reported once.
class LeaseTracker {
 public:
  /// @throws std::invalid_argument for a lease not above 0
  explicit LeaseTracker(Millis lease);
  void heard(const std::string& id, TimePoint now);
  bool alive(const std::string& id, TimePoint now) const;
  /// Peers whose lease ran out at `now` and were not reported before, in name order.
  std::vector<std::string> expired(TimePoint now);
  Millis lease() const { return lease_; }

 private:
  Millis lease_;
  std::map<std::string, TimePoint> last_heard_;
  std::map<std::string, bool> reported_;
};

/// An agent starts only executables whose resolved path is one of `allowed` (absolute paths,
/// compared after resolving symbolic links by the caller).
class ExecutablePolicy {
 public:
  /// @throws std::invalid_argument for an empty list or a path that is not absolute
  explicit ExecutablePolicy(std::vector<std::string> allowed);
  /// Empty when node `node` may run `resolved` (what `executable` resolved to; empty: not
  /// found); otherwise why not, naming the node, the executable and the allowed set.
  std::string refusal(const std::string& node, const std::string& executable, const std::string& resolved) const;
  const std::vector<std::string>& allowed() const { return allowed_; }

 private:
  std::vector<std::string> allowed_;
};

/// What an agent does with a request or with the passing of time.
struct AgentAction {
  enum class Kind {
    kNone,    ///< nothing (a repeated request, a request for another host or launch)
    kStart,   ///< start the slice
    kRefuse,  ///< report EVENT_REFUSED with `reason`, start nothing
    kStop,    ///< stop the running slice (SIGINT, then SIGKILL), `reason` says why
  };
  Kind kind = Kind::kNone;
  std::string reason;
};

/// An agent runs one launch's slice at a time.
class AgentMachine {
 public:
  enum class State { kIdle, kRunning, kStopping };

  State state() const { return state_; }
  std::uint64_t launch_id() const { return launch_id_; }

  /// A start request. `refusal`: what the executable policy or the slice's parser said (empty: fine).
  AgentAction on_start(std::uint64_t launch_id, const std::string& requester, Millis launcher_lease,
                       const std::string& refusal, TimePoint now);
  /// A keepalive or any other request of the running launch.
  void on_keepalive(std::uint64_t launch_id, TimePoint now);
  AgentAction on_stop(std::uint64_t launch_id);
  /// The launcher silent for its lease: stop the slice.
  AgentAction step(TimePoint now);
  /// The slice's supervisor exited: idle again.
  void on_slice_ended();

 private:
  State state_ = State::kIdle;
  std::uint64_t launch_id_ = 0;
  std::string requester_;
  Millis launcher_lease_{0};
  TimePoint last_request_{};
};

/// The launcher's side of a launch over agents.
class LaunchCoordinator {
 public:
  enum class Phase {
    kWaitingForAgents,  ///< not every host has a live agent yet
    kRunning,           ///< slices sent; following them
    kStopping,          ///< stop sent to every host; waiting for the slices to end
    kDone,              ///< every slice ended (or nothing was started): exit_code() holds
  };
  struct Action {
    enum class Kind { kNone, kStartAll, kStopAll };
    Kind kind = Kind::kNone;
    std::string reason;  ///< kStopAll: why (printed)
  };

  struct HostSlice {
    std::string name;
    bool ends_launch = false;  ///< it holds an ends_launch node: its end stops every host
  };
  /// hosts: those with nodes in the launch; agent_deadline: how long to wait for their agents
  /// (then nothing is started); lease: an agent silent that long is lost.
  /// @throws std::invalid_argument for no hosts, a duplicate host, or deadlines not above 0
  LaunchCoordinator(std::vector<HostSlice> hosts, Millis agent_deadline, Millis lease, TimePoint now);

  void on_announce(const std::string& host, TimePoint now);
  /// EVENT_STARTED, EVENT_REFUSED (code 2) and EVENT_ENDED of a host's slice.
  Action on_started(const std::string& host);
  Action on_refused(const std::string& host, const std::string& reason);
  Action on_ended(const std::string& host, int exit_code, const std::string& summary);
  /// The user's Ctrl-C (or SIGTERM).
  Action on_interrupt();
  /// Deadlines: the agents' discovery, their leases.
  Action step(TimePoint now);

  Phase phase() const { return phase_; }
  /// Hosts without a live agent (while waiting, and after the deadline).
  std::vector<std::string> missing_hosts(TimePoint now) const;
  /// Hosts whose slice has not ended (running or not yet confirmed).
  std::vector<std::string> unfinished_hosts() const;
  /// 0 only when every slice ended with 0 and nothing was lost or interrupted badly; otherwise
  /// the first failure's code: a slice's own code, 2 refused, 3 no agent, 4 an agent lost.
  int exit_code() const { return exit_code_; }
  /// Each failure, in order ("rig: agent lost (silent for 2000 ms)").
  const std::vector<std::string>& failures() const { return failures_; }
  /// When every host had an agent (for the matched-time figure).
  std::optional<TimePoint> all_agents_at() const { return all_agents_at_; }

 private:
  struct HostState {
    bool ended = false;
    bool lost = false;
  };
  void fail(const std::string& host, int code, const std::string& what);
  Action stop_all(const std::string& reason);
  void finish_if_all_ended();

  std::vector<HostSlice> hosts_;
  Millis deadline_;
  LeaseTracker leases_;
  TimePoint started_;
  Phase phase_ = Phase::kWaitingForAgents;
  std::map<std::string, HostState> host_state_;
  std::vector<std::string> failures_;
  int exit_code_ = 0;
  bool interrupted_ = false;
  std::optional<TimePoint> all_agents_at_;
};

}  // namespace pmlsm::agent

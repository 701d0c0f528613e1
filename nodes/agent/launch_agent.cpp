// launch_agent (`pmlsm agent`): starts launch slices on this host when a launcher asks. It
// announces its host over DDS (AgentAnnounce, every lease/4), takes LaunchRequests addressed to
// its host, checks every executable of a slice against its allowed set (the pmlsm programs
// beside it), and runs the slice under the launcher's own supervisor (the `launcher` program
// beside it, as a child), relaying each output line (NodeOutput) and the slice's end (NodeExit).
// A launcher silent for its lease, a STOP request, SIGINT or SIGTERM stop the slice. Without a
// keystore it refuses to start unless --insecure: anyone on the domain could then make it run
// programs. Decisions: launch_agent (common/agent); processes: the launcher's supervisor.
//
// A component (made from its command line: checks, participant, endpoints; then run once). It
// supervises a child process and polls its pipes, so it runs alone in its process, never on a
// container's chain thread.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "AgentAnnouncePubSubTypes.h"
#include "LaunchRequestPubSubTypes.h"
#include "NodeExitPubSubTypes.h"
#include "launch_agent.hpp"
#include "NodeOutputPubSubTypes.h"
#include "launch_agent_command_line.hpp"
#include "launch_file.hpp"
#include "node_support.hpp"
#include "pmlsm/agent/agent.hpp"
#include "pmlsm/components/registered_names.hpp"
#include "pmlsm/util/data_files.hpp"
#include "supervisor.hpp"

extern char** environ;

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;
namespace fs = std::filesystem;
using SteadyClock = std::chrono::steady_clock;

// The pmlsm programs present in bin_dir, by their resolved paths.
std::vector<std::string> allowed_programs(const std::string& bin_dir) {
  std::vector<std::string> out;
  const std::vector<std::string> registered(components::kRegisteredNames.begin(), components::kRegisteredNames.end());
  for (const auto& name : agent::node_programs(registered)) {
    std::error_code ec;
    const fs::path p = fs::canonical(fs::path(bin_dir) / name, ec);
    if (!ec && ::access(p.c_str(), X_OK) == 0) out.push_back(p.string());
  }
  return out;
}

// The slice's supervisor: the launcher program, a child in its own process group that gets
// SIGTERM should the agent die. Its stdout and stderr come back through two pipes.
class SliceProcess {
 public:
  SliceProcess(const std::string& launcher, const std::vector<std::string>& args) {
    int out[2], err[2];
    if (::pipe2(out, O_CLOEXEC) != 0 || ::pipe2(err, O_CLOEXEC) != 0)
      throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
    std::vector<std::string> argv_store{launcher};
    argv_store.insert(argv_store.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : argv_store) argv.push_back(a.data());
    argv.push_back(nullptr);
    const int dev_null = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
    const pid_t parent = ::getpid();
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
    if (pid_ == 0) {  // async-signal-safe calls only from here
      ::setpgid(0, 0);
      ::prctl(PR_SET_PDEATHSIG, SIGTERM);
      if (::getppid() != parent) ::_exit(127);
      ::dup2(dev_null, STDIN_FILENO);
      ::dup2(out[1], STDOUT_FILENO);
      ::dup2(err[1], STDERR_FILENO);
      sigset_t none;
      sigemptyset(&none);
      ::sigprocmask(SIG_SETMASK, &none, nullptr);
      ::execve(argv[0], argv.data(), environ);
      ::_exit(127);
    }
    ::setpgid(pid_, pid_);
    ::close(dev_null);
    ::close(out[1]);
    ::close(err[1]);
    fds_[0] = out[0];
    fds_[1] = err[0];
    for (int fd : fds_) ::fcntl(fd, F_SETFL, O_NONBLOCK);
  }
  ~SliceProcess() {
    if (running()) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    for (int fd : fds_)
      if (fd >= 0) ::close(fd);
  }
  SliceProcess(const SliceProcess&) = delete;
  SliceProcess& operator=(const SliceProcess&) = delete;

  bool running() const { return pid_ > 0; }
  // To the child only while it is not reaped, so the PID is ours.
  void signal(int sig) const {
    if (running()) ::kill(pid_, sig);
  }
  // Reads what is there; whole lines go to on_line(is_stderr, line), cut by the supervisor's
  // LineRelay (a runaway line in 64 KiB pieces).
  template <typename OnLine>
  void read(OnLine&& on_line) {
    char buffer[8192];
    for (int i = 0; i < 2; ++i) {
      while (fds_[i] >= 0) {
        const ssize_t n = ::read(fds_[i], buffer, sizeof buffer);
        if (n > 0) {
          relays_[i].feed(buffer, static_cast<std::size_t>(n));
          continue;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && errno == EAGAIN) break;
        relays_[i].finish();
        ::close(fds_[i]);
        fds_[i] = -1;
      }
    }
    for (const auto& [is_err, line] : lines_) on_line(is_err, line);
    lines_.clear();
  }
  // The exit status once it exited and both pipes are at their end.
  std::optional<int> reap() {
    if (!running() || fds_[0] >= 0 || fds_[1] >= 0) {
      if (running()) {  // a child gone while a grandchild keeps the pipes: the status still counts
        int status = 0;
        if (::waitpid(pid_, &status, WNOHANG) == pid_) {
          pid_ = -1;
          status_ = status;
        }
      }
      if (status_ && fds_[0] < 0 && fds_[1] < 0) return status_;
      return std::nullopt;
    }
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) != pid_) return std::nullopt;
    pid_ = -1;
    return status;
  }
  int out_fd() const { return fds_[0]; }
  int err_fd() const { return fds_[1]; }

 private:
  pid_t pid_ = -1;
  int fds_[2] = {-1, -1};
  std::vector<std::pair<bool, std::string>> lines_;  // (from stderr, line without its '\n')
  launch::LineRelay relays_[2] = {
      launch::LineRelay("", [this](const std::string& l) { lines_.emplace_back(false, l.substr(0, l.size() - 1)); }),
      launch::LineRelay("", [this](const std::string& l) { lines_.emplace_back(true, l.substr(0, l.size() - 1)); })};
  std::optional<int> status_;
};

// The slice's result from its supervisor's wait status. The supervisor ended by the SIGINT the
// agent sent to stop it counts as stopped cleanly, as the supervisor counts its own nodes: a stop
// that reaches it just as it ends (its nodes already done, its signals unblocked) kills it by
// that signal, though nothing failed. Any other signal, SIGKILL after the stop timeout included,
// is an error.
int slice_exit_code(int status, bool interrupted_by_agent) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (interrupted_by_agent && WIFSIGNALED(status) && WTERMSIG(status) == SIGINT) return kExitOk;
  return kExitError;
}

using AgentOptions = node::LaunchAgentOptions;

/// The agent's participant: its identity in a keystore is launch_agent unless given.
pdds::ParticipantOptions agent_participant(pdds::ParticipantOptions options) {
  if (options.identity.empty()) options.identity = "launch_agent";
  return node::named(std::move(options), "launch_agent");
}

class LaunchAgentComponent final : public node::Component {
 public:
  LaunchAgentComponent(AgentOptions options, std::vector<std::string> allowed)
      : opt_(std::move(options)),
        allowed_count_(allowed.size()),
        policy_(std::move(allowed)),
        launcher_((fs::path(opt_.bin_dir) / "launcher").string()),
        participant_(agent_participant(opt_.dds)),
        announce_writer_(participant_.make_writer(pdds::topics::kAgentAnnounce)),
        output_writer_(participant_.make_writer(pdds::topics::kNodeOutput)),
        exit_writer_(participant_.make_writer(pdds::topics::kNodeExit)),
        request_reader_(participant_.make_reader(pdds::topics::kLaunchRequest, wakeup_)),
        agent_id_(opt_.host + "-" + std::to_string(::getpid())),
        slice_dir_(fs::temp_directory_path() / ("launch_agent_" + std::to_string(::getpid()))) {}

  int run() override;

 private:
  void announce(SteadyClock::time_point now);
  void take_requests(SteadyClock::time_point now);
  /// The slice a START asks for, checked (every node for this host, every program allowed), as
  /// the YAML the supervisor runs; or the refusal.
  std::string checked_slice(const msg::LaunchRequest& r, std::string& refusal) const;
  void start_slice(const msg::LaunchRequest& r, SteadyClock::time_point now);
  void stop_slice(const std::string& why);
  /// Relays the slice's output, kills it after its stop time-out, reports its end.
  void pump_slice(SteadyClock::time_point now);
  void publish_output(std::uint64_t launch_id, const std::string& node, std::uint8_t stream, const std::string& line);
  void publish_event(std::uint64_t launch_id, std::uint8_t event, int code, const std::string& text);

  AgentOptions opt_;
  std::size_t allowed_count_;
  agent::ExecutablePolicy policy_;
  std::string launcher_;
  pdds::Wakeup wakeup_;  // outlives the participant, whose listeners signal it
  pdds::Participant participant_;
  pdds::Writer<msg::AgentAnnouncePubSubType> announce_writer_;
  pdds::Writer<msg::NodeOutputPubSubType> output_writer_;
  pdds::Writer<msg::NodeExitPubSubType> exit_writer_;
  pdds::Reader<msg::LaunchRequestPubSubType> request_reader_;
  std::string agent_id_;
  fs::path slice_dir_;

  agent::AgentMachine machine_;
  std::unique_ptr<SliceProcess> slice_;
  std::uint64_t line_number_ = 0;
  std::string message_ = "idle";
  std::uint32_t stop_timeout_ms_ = 5000;
  std::optional<SteadyClock::time_point> kill_at_;
  bool interrupted_ = false;  // the agent sent the slice's supervisor SIGINT
  SteadyClock::time_point next_announce_ = SteadyClock::now();
  msg::LaunchRequest request_;
};

int LaunchAgentComponent::run() {
  fs::create_directories(slice_dir_);
  std::cout << "launch_agent: host " << opt_.host << ", "
            << (opt_.insecure ? "INSECURE (no keystore)" : "identity " + participant_.identity()) << ", domain "
            << opt_.dds.domain_id << ", " << allowed_count_ << " programs allowed from " << opt_.bin_dir
            << ", nodes run in " << fs::current_path().string() << std::endl;
  while (!pdds::stop_requested() || slice_) {
    const auto now = SteadyClock::now();
    if (pdds::stop_requested() && slice_ && !kill_at_) stop_slice("the agent was asked to stop");
    if (now >= next_announce_) announce(now);
    take_requests(now);
    const auto a = machine_.step(now);
    if (a.kind == agent::AgentAction::Kind::kStop) stop_slice(a.reason);
    if (slice_) pump_slice(now);
    // Requests wake the loop; the slice's pipes are polled every 20 ms.
    const std::uint64_t seen = wakeup_.generation();
    if (slice_) {
      pollfd fds[2] = {{slice_->out_fd(), POLLIN, 0}, {slice_->err_fd(), POLLIN, 0}};
      ::poll(fds, 2, 20);
    } else {
      wakeup_.wait_for(seen, std::chrono::milliseconds(20));
    }
  }
  // Everything published reaches the launcher before the participant goes.
  output_writer_.wait_for_acknowledgments(std::chrono::seconds(2));
  exit_writer_.wait_for_acknowledgments(std::chrono::seconds(2));
  std::error_code ec;
  fs::remove_all(slice_dir_, ec);
  return kExitOk;
}

void LaunchAgentComponent::announce(SteadyClock::time_point now) {
  msg::AgentAnnounce a;
  a.stamp(node::make_stamp(0, 1e-3));
  a.host_name(opt_.host);
  a.agent_id(agent_id_);
  a.pid(static_cast<std::uint32_t>(::getpid()));
  a.secure(!opt_.insecure);
  a.launch_id(machine_.launch_id());
  a.lease_ms(static_cast<std::uint32_t>(opt_.lease_ms));
  a.message(message_.substr(0, 128));
  announce_writer_.write(a);
  next_announce_ = now + std::chrono::milliseconds(opt_.lease_ms / 4);
}

void LaunchAgentComponent::take_requests(SteadyClock::time_point now) {
  while (request_reader_.take(request_)) {
    if (request_.host_name().to_string() != opt_.host) continue;
    switch (request_.command()) {
      case msg::LaunchRequest_Constants::COMMAND_START:
        if (!pdds::stop_requested()) start_slice(request_, now);
        break;
      case msg::LaunchRequest_Constants::COMMAND_KEEPALIVE: machine_.on_keepalive(request_.launch_id(), now); break;
      case msg::LaunchRequest_Constants::COMMAND_STOP: {
        const auto a = machine_.on_stop(request_.launch_id());
        if (a.kind == agent::AgentAction::Kind::kStop) stop_slice(a.reason);
        break;
      }
      default: break;
    }
  }
}

std::string LaunchAgentComponent::checked_slice(const msg::LaunchRequest& r, std::string& refusal) const {
  try {
    auto launch = launch::parse_launch(r.slice_yaml().to_string(), "slice of launch " + std::to_string(r.launch_id()));
    for (auto& node : launch.nodes) {
      if (node.host != opt_.host) throw launch::LaunchFileError("node '" + node.name + "' is for host " + node.host);
      std::string resolved;
      try {
        resolved = fs::canonical(launch::resolve_executable(node.executable, opt_.bin_dir, "")).string();
      } catch (const std::exception&) {
      }
      refusal = policy_.refusal(node.name, node.executable, resolved);
      if (!refusal.empty()) return "";
      node.executable = resolved;  // the supervisor runs exactly what was checked
    }
    return launch::slice_yaml(launch.name, opt_.host, launch.nodes);
  } catch (const launch::LaunchFileError& e) {
    refusal = std::string("bad slice: ") + e.what();
    return "";
  }
}

void LaunchAgentComponent::start_slice(const msg::LaunchRequest& r, SteadyClock::time_point now) {
  std::string refusal;
  const std::string yaml_text = checked_slice(r, refusal);
  const auto action = machine_.on_start(r.launch_id(), r.requester().to_string(),
                                        std::chrono::milliseconds(r.lease_ms()), refusal, now);
  if (action.kind == agent::AgentAction::Kind::kRefuse) {
    publish_output(r.launch_id(), "", msg::NodeOutput_Constants::STREAM_SUPERVISOR, "refused: " + action.reason);
    publish_event(r.launch_id(), msg::NodeExit_Constants::EVENT_REFUSED, kExitBadConfig, "refused: " + action.reason);
    return;
  }
  if (action.kind != agent::AgentAction::Kind::kStart) return;
  const fs::path file = slice_dir_ / ("launch_" + std::to_string(r.launch_id()) + ".yaml");
  std::ofstream(file) << yaml_text;
  stop_timeout_ms_ = r.stop_timeout_ms();
  kill_at_.reset();
  interrupted_ = false;
  line_number_ = 0;
  slice_ = std::make_unique<SliceProcess>(
      launcher_, std::vector<std::string>{file.string(), "--start-grace-ms", std::to_string(r.start_grace_ms()),
                                          "--stop-timeout-ms", std::to_string(r.stop_timeout_ms())});
  message_ = "running launch " + std::to_string(r.launch_id()) + " for " + r.requester().to_string();
  publish_event(r.launch_id(), msg::NodeExit_Constants::EVENT_STARTED, 0, "started for " + r.requester().to_string());
}

void LaunchAgentComponent::stop_slice(const std::string& why) {
  if (!slice_) return;
  publish_output(machine_.launch_id(), "", msg::NodeOutput_Constants::STREAM_SUPERVISOR, "stopping: " + why);
  std::cout << "launch_agent: stopping launch " << machine_.launch_id() << ": " << why << std::endl;
  slice_->signal(SIGINT);  // the supervisor stops its nodes: SIGINT, SIGKILL after its stop timeout
  interrupted_ = true;
  kill_at_ = SteadyClock::now() + std::chrono::milliseconds(stop_timeout_ms_ + 2000);
}

void LaunchAgentComponent::pump_slice(SteadyClock::time_point now) {
  const std::uint64_t launch_id = machine_.launch_id();
  slice_->read([&](bool is_err, const std::string& line) {
    // "[node] text" from the supervisor; its own messages are "[launcher] text".
    std::string node, text = line;
    if (line.size() > 2 && line[0] == '[') {
      const auto close = line.find("] ");
      if (close != std::string::npos) {
        node = line.substr(1, close - 1);
        text = line.substr(close + 2);
      }
    }
    if (node == "launcher") {
      publish_output(launch_id, "", msg::NodeOutput_Constants::STREAM_SUPERVISOR, text);
    } else {
      publish_output(launch_id, node,
                     is_err ? msg::NodeOutput_Constants::STREAM_STDERR : msg::NodeOutput_Constants::STREAM_STDOUT,
                     text);
    }
  });
  if (kill_at_ && now >= *kill_at_) {
    slice_->signal(SIGKILL);
    kill_at_.reset();
  }
  if (const auto status = slice_->reap()) {
    const int code = slice_exit_code(*status, interrupted_);
    publish_event(launch_id, msg::NodeExit_Constants::EVENT_ENDED, code,
                  "slice ended with exit code " + std::to_string(code) + " (" + exit_code_meaning(code) + ")");
    slice_.reset();
    machine_.on_slice_ended();
    message_ = "idle";
    std::error_code ec;
    fs::remove(slice_dir_ / ("launch_" + std::to_string(launch_id) + ".yaml"), ec);
  }
}

void LaunchAgentComponent::publish_output(std::uint64_t launch_id, const std::string& node, std::uint8_t stream,
                                          const std::string& line) {
  msg::NodeOutput out;
  out.stamp(node::make_stamp(0, 1e-3));
  out.launch_id(launch_id);
  out.host_name(opt_.host);
  out.node_name(node.substr(0, 64));
  out.stream(stream);
  for (std::size_t pos = 0; pos == 0 || pos < line.size(); pos += 1024) {  // long lines in pieces
    out.line_number(++line_number_);
    out.line(line.substr(pos, 1024));
    output_writer_.write(out);
  }
}

void LaunchAgentComponent::publish_event(std::uint64_t launch_id, std::uint8_t event, int code,
                                         const std::string& text) {
  msg::NodeExit e;
  e.stamp(node::make_stamp(0, 1e-3));
  e.launch_id(launch_id);
  e.host_name(opt_.host);
  e.event(event);
  e.exit_code(code);
  e.message(text.substr(0, 256));
  exit_writer_.write(e);
  std::cout << "launch_agent: launch " << launch_id << ": " << text << std::endl;
}

}  // namespace

namespace pmlsm::node {

MadeComponent make_launch_agent(const ComponentContext& /*context*/, int argc, char** argv) {
  AgentOptions opt;
  if (const auto code = parse_launch_agent_command_line(argc, argv, opt)) return {nullptr, *code};
  if (opt.dds.keystore.empty() && !opt.insecure) {
    std::cerr << "launch_agent: refusing to start without a keystore: any participant on DDS domain "
              << opt.dds.domain_id
              << " could make this agent start programs on this host. Give --keystore DIR (or set PMLSM_KEYSTORE) "
                 "with the identity launch_agent (`pmlsm security create`), or --insecure on a network you trust.\n";
    return {nullptr, kExitBadConfig};
  }
  if (opt.host.empty() || opt.host.size() > 64) throw ConfigError("--host: 1 to 64 characters, got '" + opt.host + "'");
  // Installed (the .deb), started where there is no configs/: the nodes' relative paths
  // (configs/...) are the shipped files'.
  if (opt.work_dir.empty() && !fs::exists("configs")) opt.work_dir = installed_data_dir();
  if (!opt.work_dir.empty()) fs::current_path(opt.work_dir);
  auto allowed = allowed_programs(opt.bin_dir);
  if (allowed.empty()) throw ConfigError("--bin-dir " + opt.bin_dir + ": none of the pmlsm programs is there");
  if (::access((fs::path(opt.bin_dir) / "launcher").c_str(), X_OK) != 0) {
    throw ConfigError("--bin-dir " + opt.bin_dir + ": no launcher program there (the agent runs slices with it)");
  }
  return {std::make_unique<LaunchAgentComponent>(std::move(opt), std::move(allowed))};
}

}  // namespace pmlsm::node

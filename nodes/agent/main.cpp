// launch_agent (`pmlsm agent`): starts launch slices on this host when a launcher asks. It
// announces its host over DDS (AgentAnnounce, every lease/4), takes LaunchRequests addressed to
// its host, checks every executable of a slice against its allowed set (the pmlsm programs
// beside it), and runs the slice under the launcher's own supervisor (the `launcher` program
// beside it, as a child), relaying each output line (NodeOutput) and the slice's end (NodeExit).
// A launcher silent for its lease, a STOP request, SIGINT or SIGTERM stop the slice. Without a
// keystore it refuses to start unless --insecure: anyone on the domain could then make it run
// programs. Decisions: launch_agent (common/agent); processes: the launcher's supervisor.
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
#include "NodeOutputPubSubTypes.h"
#include "launch_file.hpp"
#include "node_support.hpp"
#include "pmlsm/agent/agent.hpp"
#include "pmlsm/util/data_files.hpp"
#include "supervisor.hpp"

extern char** environ;

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;
namespace fs = std::filesystem;
using SteadyClock = std::chrono::steady_clock;


std::string host_name() {
  char host[128] = {};
  gethostname(host, sizeof(host) - 1);
  return host;
}

// The pmlsm programs present in bin_dir, by their resolved paths.
std::vector<std::string> allowed_programs(const std::string& bin_dir) {
  std::vector<std::string> out;
  for (const auto& name : agent::node_programs()) {
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

int run(int argc, char** argv) {
  CLI::App app{
      "Launch agent: announces this host over DDS and starts the slices of launch descriptions that a "
      "launcher (`launcher FILE --agents`) sends it; only the pmlsm programs beside it."};
  pdds::ParticipantOptions dds_options;
  node::add_dds_options(app, dds_options);
  std::string host = host_name();
  std::string bin_dir = pmlsm::program_dir();
  std::string work_dir;
  int lease_ms = 2000;
  bool insecure = false;
  app.add_option("--host", host, "The host name launch files use for this machine (default: its host name)")
      ->capture_default_str();
  app.add_option("--bin-dir", bin_dir, "Where the programs it may start are (default: its own folder)")
      ->check(CLI::ExistingDirectory)
      ->capture_default_str();
  app.add_option("--work-dir", work_dir, "Folder the nodes run in, where relative paths in their args start "
                                         "(default: the current folder; without configs/ there, the installed "
                                         "share/pmlsm beside its bin folder)")
      ->check(CLI::ExistingDirectory);
  app.add_option("--lease-ms", lease_ms, "Announce every lease/4; a launcher takes it as gone after a lease")
      ->check(CLI::Range(200, 60000))
      ->capture_default_str();
  app.add_flag("--insecure", insecure,
               "Run without a keystore: anyone on the DDS domain may then make it start pmlsm programs");
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  if (dds_options.keystore.empty() && !insecure) {
    std::cerr << "launch_agent: refusing to start without a keystore: any participant on DDS domain "
              << dds_options.domain_id
              << " could make this agent start programs on this host. Give --keystore DIR (or set PMLSM_KEYSTORE) "
                 "with the identity launch_agent (`pmlsm security create`), or --insecure on a network you trust.\n";
    return kExitBadConfig;
  }
  if (host.empty() || host.size() > 64) throw ConfigError("--host: 1 to 64 characters, got '" + host + "'");
  // Installed (the .deb), started where there is no configs/: the nodes' relative paths
  // (configs/...) are the shipped files'.
  if (work_dir.empty() && !fs::exists("configs")) work_dir = installed_data_dir();
  if (!work_dir.empty()) fs::current_path(work_dir);
  const auto allowed = allowed_programs(bin_dir);
  if (allowed.empty()) throw ConfigError("--bin-dir " + bin_dir + ": none of the pmlsm programs is there");
  const agent::ExecutablePolicy policy(allowed);
  const std::string launcher = (fs::path(bin_dir) / "launcher").string();
  if (::access(launcher.c_str(), X_OK) != 0)
    throw ConfigError("--bin-dir " + bin_dir + ": no launcher program there (the agent runs slices with it)");

  dds_options.node_name = "launch_agent";
  if (dds_options.identity.empty()) dds_options.identity = "launch_agent";
  pdds::Wakeup wakeup;
  pdds::Participant participant(dds_options);
  auto announce_writer = participant.make_writer<msg::AgentAnnouncePubSubType>(pdds::topics::kAgentAnnounce);
  auto output_writer = participant.make_writer<msg::NodeOutputPubSubType>(pdds::topics::kNodeOutput);
  auto exit_writer = participant.make_writer<msg::NodeExitPubSubType>(pdds::topics::kNodeExit);
  auto request_reader = participant.make_reader<msg::LaunchRequestPubSubType>(pdds::topics::kLaunchRequest, wakeup);

  const std::string agent_id = host + "-" + std::to_string(::getpid());
  const fs::path slice_dir = fs::temp_directory_path() / ("launch_agent_" + std::to_string(::getpid()));
  fs::create_directories(slice_dir);
  std::cout << "launch_agent: host " << host << ", " << (insecure ? "INSECURE (no keystore)" : "identity " + participant.identity())
            << ", domain " << dds_options.domain_id << ", " << allowed.size() << " programs allowed from " << bin_dir
            << ", nodes run in " << fs::current_path().string() << std::endl;

  agent::AgentMachine machine;
  std::unique_ptr<SliceProcess> slice;
  std::uint64_t line_number = 0;
  std::string message = "idle";
  std::uint32_t stop_timeout_ms = 5000;
  std::optional<SteadyClock::time_point> kill_at;
  bool interrupted = false;  // the agent sent the slice's supervisor SIGINT
  const auto announce_period = std::chrono::milliseconds(lease_ms / 4);
  auto next_announce = SteadyClock::now();

  const auto publish_output = [&](std::uint64_t launch_id, const std::string& node, std::uint8_t stream,
                                  const std::string& line) {
    msg::NodeOutput out;
    out.stamp(node::make_stamp(0, 1e-3));
    out.launch_id(launch_id);
    out.host_name(host);
    out.node_name(node.substr(0, 64));
    out.stream(stream);
    for (std::size_t pos = 0; pos == 0 || pos < line.size(); pos += 1024) {  // long lines in pieces
      out.line_number(++line_number);
      out.line(line.substr(pos, 1024));
      output_writer.write(out);
    }
  };
  const auto publish_event = [&](std::uint64_t launch_id, std::uint8_t event, int code, const std::string& text) {
    msg::NodeExit e;
    e.stamp(node::make_stamp(0, 1e-3));
    e.launch_id(launch_id);
    e.host_name(host);
    e.event(event);
    e.exit_code(code);
    e.message(text.substr(0, 256));
    exit_writer.write(e);
    std::cout << "launch_agent: launch " << launch_id << ": " << text << std::endl;
  };
  const auto stop_slice = [&](const std::string& why) {
    if (!slice) return;
    publish_output(machine.launch_id(), "", msg::NodeOutput_Constants::STREAM_SUPERVISOR, "stopping: " + why);
    std::cout << "launch_agent: stopping launch " << machine.launch_id() << ": " << why << std::endl;
    slice->signal(SIGINT);  // the supervisor stops its nodes: SIGINT, SIGKILL after its stop timeout
    interrupted = true;
    kill_at = SteadyClock::now() + std::chrono::milliseconds(stop_timeout_ms + 2000);
  };

  const auto start = [&](const msg::LaunchRequest& r, SteadyClock::time_point now) {
    std::string refusal;
    std::string yaml_text;
    try {
      auto launch = launch::parse_launch(r.slice_yaml().to_string(), "slice of launch " + std::to_string(r.launch_id()));
      for (auto& node : launch.nodes) {
        if (node.host != host) throw launch::LaunchFileError("node '" + node.name + "' is for host " + node.host);
        std::string resolved;
        try {
          resolved = fs::canonical(launch::resolve_executable(node.executable, bin_dir, "")).string();
        } catch (const std::exception&) {
        }
        refusal = policy.refusal(node.name, node.executable, resolved);
        if (!refusal.empty()) break;
        node.executable = resolved;  // the supervisor runs exactly what was checked
      }
      if (refusal.empty()) yaml_text = launch::slice_yaml(launch.name, host, launch.nodes);
    } catch (const launch::LaunchFileError& e) {
      refusal = std::string("bad slice: ") + e.what();
    }
    const auto action = machine.on_start(r.launch_id(), r.requester().to_string(), std::chrono::milliseconds(r.lease_ms()),
                                         refusal, now);
    if (action.kind == agent::AgentAction::Kind::kRefuse) {
      publish_output(r.launch_id(), "", msg::NodeOutput_Constants::STREAM_SUPERVISOR, "refused: " + action.reason);
      publish_event(r.launch_id(), msg::NodeExit_Constants::EVENT_REFUSED, kExitBadConfig, "refused: " + action.reason);
      return;
    }
    if (action.kind != agent::AgentAction::Kind::kStart) return;
    const fs::path file = slice_dir / ("launch_" + std::to_string(r.launch_id()) + ".yaml");
    std::ofstream(file) << yaml_text;
    stop_timeout_ms = r.stop_timeout_ms();
    kill_at.reset();
    interrupted = false;
    line_number = 0;
    slice = std::make_unique<SliceProcess>(
        launcher, std::vector<std::string>{file.string(), "--start-grace-ms", std::to_string(r.start_grace_ms()),
                                           "--stop-timeout-ms", std::to_string(r.stop_timeout_ms())});
    message = "running launch " + std::to_string(r.launch_id()) + " for " + r.requester().to_string();
    publish_event(r.launch_id(), msg::NodeExit_Constants::EVENT_STARTED, 0, "started for " + r.requester().to_string());
  };

  msg::LaunchRequest request;
  while (!pdds::stop_requested() || slice) {
    const auto now = SteadyClock::now();
    if (pdds::stop_requested() && slice && !kill_at) stop_slice("the agent was asked to stop");
    if (now >= next_announce) {
      msg::AgentAnnounce a;
      a.stamp(node::make_stamp(0, 1e-3));
      a.host_name(host);
      a.agent_id(agent_id);
      a.pid(static_cast<std::uint32_t>(::getpid()));
      a.secure(!insecure);
      a.launch_id(machine.launch_id());
      a.lease_ms(static_cast<std::uint32_t>(lease_ms));
      a.message(message.substr(0, 128));
      announce_writer.write(a);
      next_announce = now + announce_period;
    }
    while (request_reader.take(request)) {
      if (request.host_name().to_string() != host) continue;
      switch (request.command()) {
        case msg::LaunchRequest_Constants::COMMAND_START:
          if (!pdds::stop_requested()) start(request, now);
          break;
        case msg::LaunchRequest_Constants::COMMAND_KEEPALIVE: machine.on_keepalive(request.launch_id(), now); break;
        case msg::LaunchRequest_Constants::COMMAND_STOP: {
          const auto a = machine.on_stop(request.launch_id());
          if (a.kind == agent::AgentAction::Kind::kStop) stop_slice(a.reason);
          break;
        }
        default: break;
      }
    }
    const auto a = machine.step(now);
    if (a.kind == agent::AgentAction::Kind::kStop) stop_slice(a.reason);
    if (slice) {
      const std::uint64_t launch_id = machine.launch_id();
      slice->read([&](bool is_err, const std::string& line) {
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
      if (kill_at && now >= *kill_at) {
        slice->signal(SIGKILL);
        kill_at.reset();
      }
      if (const auto status = slice->reap()) {
        const int code = slice_exit_code(*status, interrupted);
        publish_event(launch_id, msg::NodeExit_Constants::EVENT_ENDED, code,
                      "slice ended with exit code " + std::to_string(code) + " (" + exit_code_meaning(code) + ")");
        slice.reset();
        machine.on_slice_ended();
        message = "idle";
        std::error_code ec;
        fs::remove(slice_dir / ("launch_" + std::to_string(launch_id) + ".yaml"), ec);
      }
    }
    // Requests wake the loop; the slice's pipes are polled every 20 ms.
    const std::uint64_t seen = wakeup.generation();
    if (slice) {
      pollfd fds[2] = {{slice->out_fd(), POLLIN, 0}, {slice->err_fd(), POLLIN, 0}};
      ::poll(fds, 2, 20);
    } else {
      wakeup.wait_for(seen, std::chrono::milliseconds(20));
    }
  }
  // Everything published reaches the launcher before the participant goes.
  output_writer.wait_for_acknowledgments(std::chrono::seconds(2));
  exit_writer.wait_for_acknowledgments(std::chrono::seconds(2));
  std::error_code ec;
  fs::remove_all(slice_dir, ec);
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  pmlsm::dds::install_shutdown_handlers();
  return pmlsm::node::run_node("launch_agent", [&] { return run(argc, argv); });
}

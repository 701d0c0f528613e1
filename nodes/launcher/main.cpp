// launcher: starts the nodes of a launch description (all of them, or one
// host's slice) and supervises them until the run is over. See launch/README.md.
#include <CLI/CLI.hpp>
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "launch_file.hpp"
#include "pmlsm/util/data_files.hpp"
#include "node_support.hpp"
#include "pmlsm/util/exit_codes.hpp"
#include "remote.hpp"
#include "supervisor.hpp"

namespace {

using pmlsm::launch::ProcessSpec;

constexpr int kMaxMs = 24 * 3600 * 1000;

std::string quoted_command(const ProcessSpec& p) {
  std::string out;
  for (const auto& word : p.argv) out += (out.empty() ? "" : " ") + pmlsm::launch::shell_quote(word);
  return out;
}

void print_dry_run(const pmlsm::launch::NodeSpec& node, const ProcessSpec& process, const std::string& not_found) {
  std::cout << node.name << " (host " << node.host << (node.ends_launch ? ", ends the launch" : "") << ")\n";
  if (!node.components.empty()) {
    std::cout << "  container of:";
    for (const auto& c : node.components) std::cout << " " << c;
    std::cout << "\n";
  }
  for (const auto& [key, value] : node.env) {
    std::cout << "  env: " << key << "=" << pmlsm::launch::shell_quote(value) << "\n";
  }
  if (not_found.empty()) {
    std::cout << "  cmd: " << quoted_command(process) << "\n";
  } else {
    std::cout << "  cmd: <" << not_found << ">\n";
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Starts the nodes of a launch description and supervises them: output prefixed "
      "with the node's name, SIGINT/SIGTERM forwarded, every exit reported."};
  std::string file;
  std::string host;
  std::string bin_dir;
  bool dry_run = false;
  int start_grace_ms = 1000;
  int stop_timeout_ms = 5000;
  std::vector<std::string> arg_texts;
  app.add_option("file", file, "Launch description (YAML)")->required();
  auto* host_option = app.add_option("--host", host, "Start only the nodes of this host");
  app.add_option("--bin-dir", bin_dir, "Where node executables are looked up first (default: the launcher's folder)")
      ->check(CLI::ExistingDirectory);
  app.add_flag("--dry-run", dry_run, "Print each node's command line and environment, start nothing");
  app.add_option("--start-grace-ms", start_grace_ms,
                 "A node failing this soon after its start fails the launch (0: off)")
      ->check(CLI::Range(0, kMaxMs))
      ->capture_default_str();
  app.add_option("--stop-timeout-ms", stop_timeout_ms, "Time from SIGINT to SIGKILL when stopping nodes")
      ->check(CLI::Range(0, kMaxMs))
      ->capture_default_str();
  app.add_option("--arg", arg_texts, "Set a launch arg: NAME=VALUE (repeatable)")
      ->type_size(1)
      ->allow_extra_args(false);
  bool agents = false;
  int agent_wait_ms = 10000;
  int agent_lease_ms = 2000;
  pmlsm::launch::RemoteOptions remote;
  auto* agents_flag = app.add_flag("--agents", agents,
                                   "Send each host's slice to that host's launch agent (`pmlsm agent`) over DDS "
                                   "instead of starting the nodes here");
  app.add_option("--agent-wait-ms", agent_wait_ms,
                 "--agents: every host's agent must be found within this, or nothing starts")
      ->check(CLI::Range(1, kMaxMs))
      ->capture_default_str();
  app.add_option("--agent-lease-ms", agent_lease_ms,
                 "--agents: an agent silent this long is lost (the launch stops the rest); agents stop "
                 "their slice when the launcher is silent this long")
      ->check(CLI::Range(200, 60000))
      ->capture_default_str();
  pmlsm::node::add_dds_options(app, remote.dds);
  host_option->excludes(agents_flag);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : pmlsm::kExitBadConfig;
  }

  pmlsm::launch::LaunchDescription launch;
  std::vector<pmlsm::launch::NodeSpec> nodes;
  try {
    pmlsm::launch::ArgOverrides overrides;
    for (const auto& text : arg_texts) {
      const auto [key, value] = pmlsm::launch::parse_arg_override(text);
      overrides[key] = value;
    }
    launch = pmlsm::launch::load_launch_file(file, overrides);
    std::optional<std::string> selected_host;
    if (host_option->count() > 0) selected_host = host;
    nodes = pmlsm::launch::select_nodes(launch, selected_host);
  } catch (const pmlsm::launch::LaunchFileError& e) {
    std::cerr << "[launcher] error: " << e.what() << "\n";
    return pmlsm::kExitBadConfig;
  }
  const std::string slice = host_option->count() > 0 ? "host " + host : "all hosts";
  if (!launch.left_out.empty()) {
    std::cout << "[launcher] left out by their 'if':";
    for (const auto& name : launch.left_out) std::cout << " " << name;
    std::cout << "\n";
  }

  if (agents) {
    if (dry_run) {
      std::vector<std::string> hosts;
      for (const auto& n : nodes)
        if (std::find(hosts.begin(), hosts.end(), n.host) == hosts.end()) hosts.push_back(n.host);
      for (const auto& h : hosts) {
        std::vector<pmlsm::launch::NodeSpec> slice;
        for (const auto& n : nodes)
          if (n.host == h) slice.push_back(n);
        std::cout << "# slice for the agent of host " << h << "\n" << pmlsm::launch::slice_yaml(launch.name, h, slice);
      }
      return 0;
    }
    remote.agent_wait = std::chrono::milliseconds(agent_wait_ms);
    remote.lease = std::chrono::milliseconds(agent_lease_ms);
    remote.start_grace_ms = start_grace_ms;
    remote.stop_timeout_ms = stop_timeout_ms;
    return pmlsm::node::run_node("launcher", [&] { return pmlsm::launch::run_over_agents(launch, nodes, remote); });
  }

  if (bin_dir.empty()) bin_dir = pmlsm::program_dir();
  const char* path_env = std::getenv("PATH");
  // Without PATH, the system default search path (as the shell uses).
  const std::string search_path = path_env != nullptr ? path_env : "/usr/bin:/bin";
  std::vector<ProcessSpec> processes;
  std::vector<std::string> not_found(nodes.size());  // empty when found
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const auto& node = nodes[i];
    ProcessSpec p;
    try {
      p.path = pmlsm::launch::resolve_executable(node.executable, bin_dir, search_path);
    } catch (const pmlsm::launch::ExecutableNotFound& e) {
      not_found[i] = e.what();
      std::cerr << "[launcher] node '" << node.name << "': " << not_found[i] << "\n";
    }
    p.name = node.name;
    p.argv.push_back(p.path);
    p.argv.insert(p.argv.end(), node.args.begin(), node.args.end());
    p.env = node.env;
    p.ends_launch = node.ends_launch;
    processes.push_back(std::move(p));
  }
  const bool any_missing = std::any_of(not_found.begin(), not_found.end(), [](const auto& m) { return !m.empty(); });

  if (dry_run) {
    std::cout << "# " << launch.name << " (" << launch.source << "), " << slice << ": " << nodes.size()
              << (nodes.size() == 1 ? " node\n" : " nodes\n");
    for (std::size_t i = 0; i < nodes.size(); ++i) print_dry_run(nodes[i], processes[i], not_found[i]);
    return any_missing ? 1 : 0;
  }
  if (any_missing) {
    std::cerr << "[launcher] " << launch.name << ": nothing started\n";
    return 1;
  }
  if (processes.empty()) {
    std::cerr << "[launcher] " << launch.name << ": no nodes on " << slice << "; nothing to start\n";
    return 0;
  }
  std::cerr << "[launcher] " << launch.name << ": starting " << processes.size()
            << (processes.size() == 1 ? " node" : " nodes") << " (" << slice << ")" << std::endl;

  pmlsm::launch::SupervisorOptions options;
  options.start_grace = std::chrono::milliseconds(start_grace_ms);
  options.stop_timeout = std::chrono::milliseconds(stop_timeout_ms);
  // The stop signals stay blocked once the supervisor is done (it restores this mask): a stop
  // that arrives just as the last node ends would otherwise kill the program by that signal
  // after "ended cleanly" (seen 17 times in 300 SIGINTs timed at a node's end), and a launch
  // agent would report the slice as failed. The program returns the supervisor's code at once.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&stop_signals, sig);
  ::sigprocmask(SIG_BLOCK, &stop_signals, nullptr);
  return pmlsm::launch::supervise(processes, options);
}

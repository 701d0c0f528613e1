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

using pmlsm::launch::LaunchDescription;
using pmlsm::launch::NodeSpec;
using pmlsm::launch::ProcessSpec;

constexpr int kMaxMs = 24 * 3600 * 1000;

std::string quoted_command(const ProcessSpec& p) {
  std::string out;
  for (const auto& word : p.argv) out += (out.empty() ? "" : " ") + pmlsm::launch::shell_quote(word);
  return out;
}

void print_dry_run(const NodeSpec& node, const ProcessSpec& process, const std::string& not_found) {
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

struct LauncherOptions {
  std::string file;
  std::string host;
  bool host_given = false;  // --host was given: only that host's slice
  std::string bin_dir;
  bool dry_run = false;
  int start_grace_ms = 1000;
  int stop_timeout_ms = 5000;
  std::vector<std::string> arg_texts;
  bool agents = false;
  int agent_wait_ms = 10000;
  int agent_lease_ms = 2000;
  pmlsm::launch::RemoteOptions remote;
};

/// Every option of the launcher into `o`; returns --host (whether it was given is known after parsing).
CLI::Option* add_launcher_options(CLI::App& app, LauncherOptions& o) {
  app.add_option("file", o.file, "Launch description (YAML)")->required();
  auto* host_option = app.add_option("--host", o.host, "Start only the nodes of this host");
  app.add_option("--bin-dir", o.bin_dir, "Where node executables are looked up first (default: the launcher's folder)")
      ->check(CLI::ExistingDirectory);
  app.add_flag("--dry-run", o.dry_run, "Print each node's command line and environment, start nothing");
  app.add_option("--start-grace-ms", o.start_grace_ms,
                 "A node failing this soon after its start fails the launch (0: off)")
      ->check(CLI::Range(0, kMaxMs))
      ->capture_default_str();
  app.add_option("--stop-timeout-ms", o.stop_timeout_ms, "Time from SIGINT to SIGKILL when stopping nodes")
      ->check(CLI::Range(0, kMaxMs))
      ->capture_default_str();
  app.add_option("--arg", o.arg_texts, "Set a launch arg: NAME=VALUE (repeatable)")
      ->type_size(1)
      ->allow_extra_args(false);
  auto* agents_flag = app.add_flag("--agents", o.agents,
                                   "Send each host's slice to that host's launch agent (`pmlsm agent`) over DDS "
                                   "instead of starting the nodes here");
  app.add_option("--agent-wait-ms", o.agent_wait_ms,
                 "--agents: every host's agent must be found within this, or nothing starts")
      ->check(CLI::Range(1, kMaxMs))
      ->capture_default_str();
  app.add_option("--agent-lease-ms", o.agent_lease_ms,
                 "--agents: an agent silent this long is lost (the launch stops the rest); agents stop "
                 "their slice when the launcher is silent this long")
      ->check(CLI::Range(200, 60000))
      ->capture_default_str();
  pmlsm::node::add_dds_options(app, o.remote.dds);
  host_option->excludes(agents_flag);
  return host_option;
}

/// The launch file with the --arg overrides, and its nodes on the selected host; false (said
/// on stderr) when the file or an option is wrong.
bool load_launch_nodes(const LauncherOptions& o, LaunchDescription& launch, std::vector<NodeSpec>& nodes) {
  try {
    pmlsm::launch::ArgOverrides overrides;
    for (const auto& text : o.arg_texts) {
      const auto [key, value] = pmlsm::launch::parse_arg_override(text);
      overrides[key] = value;
    }
    launch = pmlsm::launch::load_launch_file(o.file, overrides);
    std::optional<std::string> selected_host;
    if (o.host_given) selected_host = o.host;
    nodes = pmlsm::launch::select_nodes(launch, selected_host);
  } catch (const pmlsm::launch::LaunchFileError& e) {
    std::cerr << "[launcher] error: " << e.what() << "\n";
    return false;
  }
  return true;
}

/// --agents --dry-run: the slice each host's agent would get.
void print_agent_slices(const LaunchDescription& launch, const std::vector<NodeSpec>& nodes) {
  std::vector<std::string> hosts;
  for (const auto& n : nodes)
    if (std::find(hosts.begin(), hosts.end(), n.host) == hosts.end()) hosts.push_back(n.host);
  for (const auto& h : hosts) {
    std::vector<NodeSpec> slice;
    for (const auto& n : nodes)
      if (n.host == h) slice.push_back(n);
    std::cout << "# slice for the agent of host " << h << "\n" << pmlsm::launch::slice_yaml(launch.name, h, slice);
  }
}

int launch_through_agents(LauncherOptions& o, const LaunchDescription& launch, const std::vector<NodeSpec>& nodes) {
  if (o.dry_run) {
    print_agent_slices(launch, nodes);
    return 0;
  }
  o.remote.agent_wait = std::chrono::milliseconds(o.agent_wait_ms);
  o.remote.lease = std::chrono::milliseconds(o.agent_lease_ms);
  o.remote.start_grace_ms = o.start_grace_ms;
  o.remote.stop_timeout_ms = o.stop_timeout_ms;
  return pmlsm::node::run_node("launcher", [&] { return pmlsm::launch::run_over_agents(launch, nodes, o.remote); });
}

/// A process per node; not_found[i] says why node i's executable was not found ("" when it was).
std::vector<ProcessSpec> make_process_specs(const std::vector<NodeSpec>& nodes, const std::string& bin_dir,
                                            std::vector<std::string>& not_found) {
  const char* path_env = std::getenv("PATH");
  // Without PATH, the system default search path (as the shell uses).
  const std::string search_path = path_env != nullptr ? path_env : "/usr/bin:/bin";
  std::vector<ProcessSpec> processes;
  not_found.assign(nodes.size(), "");
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
  return processes;
}

// The stop signals stay blocked once the supervisor is done (it restores this mask): a stop
// that arrives just as the last node ends would otherwise kill the program by that signal
// after "ended cleanly" (seen 17 times in 300 SIGINTs timed at a node's end), and a launch
// agent would report the slice as failed. The program returns the supervisor's code at once.
void block_stop_signals() {
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&stop_signals, sig);
  ::sigprocmask(SIG_BLOCK, &stop_signals, nullptr);
}

/// Starts the nodes here and supervises them (or, with --dry-run, prints their command lines).
int launch_here(LauncherOptions& o, const LaunchDescription& launch, const std::vector<NodeSpec>& nodes) {
  const std::string slice = o.host_given ? "host " + o.host : "all hosts";
  if (o.bin_dir.empty()) o.bin_dir = pmlsm::program_dir();
  std::vector<std::string> not_found;  // empty when found
  const std::vector<ProcessSpec> processes = make_process_specs(nodes, o.bin_dir, not_found);
  const bool any_missing = std::any_of(not_found.begin(), not_found.end(), [](const auto& m) { return !m.empty(); });

  if (o.dry_run) {
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
  options.start_grace = std::chrono::milliseconds(o.start_grace_ms);
  options.stop_timeout = std::chrono::milliseconds(o.stop_timeout_ms);
  block_stop_signals();
  return pmlsm::launch::supervise(processes, options);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Starts the nodes of a launch description and supervises them: output prefixed "
      "with the node's name, SIGINT/SIGTERM forwarded, every exit reported."};
  LauncherOptions options;
  const CLI::Option* host_option = add_launcher_options(app, options);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : pmlsm::kExitBadConfig;
  }
  options.host_given = host_option->count() > 0;

  LaunchDescription launch;
  std::vector<NodeSpec> nodes;
  if (!load_launch_nodes(options, launch, nodes)) return pmlsm::kExitBadConfig;
  if (!launch.left_out.empty()) {
    std::cout << "[launcher] left out by their 'if':";
    for (const auto& name : launch.left_out) std::cout << " " << name;
    std::cout << "\n";
  }
  return options.agents ? launch_through_agents(options, launch, nodes) : launch_here(options, launch, nodes);
}

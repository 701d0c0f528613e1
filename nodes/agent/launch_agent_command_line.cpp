#include "launch_agent_command_line.hpp"

#include <unistd.h>

#include <CLI/CLI.hpp>

namespace pmlsm::node {

std::string default_agent_host() {
  char host[128] = {};
  gethostname(host, sizeof(host) - 1);
  return host;
}

std::optional<int> parse_launch_agent_command_line(int argc, char** argv, LaunchAgentOptions& opt) {
  CLI::App app{
      "Launch agent: announces this host over DDS and starts the slices of launch descriptions that a "
      "launcher (`launcher FILE --agents`) sends it; only the pmlsm programs beside it."};
  add_dds_options(app, opt.dds);
  app.add_option("--host", opt.host, "The host name launch files use for this machine (default: its host name)")
      ->capture_default_str();
  app.add_option("--bin-dir", opt.bin_dir, "Where the programs it may start are (default: its own folder)")
      ->check(CLI::ExistingDirectory)
      ->capture_default_str();
  app.add_option("--work-dir", opt.work_dir,
                 "Folder the nodes run in, where relative paths in their args start "
                 "(default: the current folder; without configs/ there, the installed "
                 "share/pmlsm beside its bin folder)")
      ->check(CLI::ExistingDirectory);
  app.add_option("--lease-ms", opt.lease_ms, "Announce every lease/4; a launcher takes it as gone after a lease")
      ->check(CLI::Range(200, 60000))
      ->capture_default_str();
  app.add_flag("--insecure", opt.insecure,
               "Run without a keystore: anyone on the DDS domain may then make it start pmlsm programs");
  return parse_command_line(app, argc, argv);
}

}  // namespace pmlsm::node

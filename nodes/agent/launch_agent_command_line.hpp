// launch_agent's command line, apart from the component so that only the parser includes CLI11
// (see nodes/support/CMakeLists.txt: the nodes' parsers are compiled together in pmlsm_node_support).
#pragma once

#include <optional>
#include <string>

#include "node_support.hpp"
#include "pmlsm/util/data_files.hpp"

namespace pmlsm::node {

/// This machine's host name (gethostname).
std::string default_agent_host();

struct LaunchAgentOptions {
  dds::ParticipantOptions dds;
  std::string host = default_agent_host();
  std::string bin_dir = pmlsm::program_dir();
  std::string work_dir;
  int lease_ms = 2000;
  bool insecure = false;
};

/// Parses launch_agent's command line into `opt` (its values are the defaults shown): an exit
/// code to end with (help: 0, bad options: 2), or nothing when it should go on.
std::optional<int> parse_launch_agent_command_line(int argc, char** argv, LaunchAgentOptions& opt);

}  // namespace pmlsm::node

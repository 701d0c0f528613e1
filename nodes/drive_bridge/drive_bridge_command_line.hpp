// drive_bridge's command line, apart from the node so that only the parser includes CLI11 (see
// nodes/support/CMakeLists.txt: the nodes' parsers are compiled together in pmlsm_node_support).
#pragma once

#include <optional>

#include "can_options.hpp"
#include "drive_node.hpp"
#include "ethercat_options.hpp"
#include "node_support.hpp"

namespace pmlsm::node {

struct DriveBridgeOptions {
  CommonOptions common;
  DriveNodeOptions drive;
  CanOptions can;
  EthercatOptions ethercat;
  bool no_reset = false;
};

/// Parses drive_bridge's command line into `opt` (its values are the defaults shown): an exit
/// code to end with (help: 0, bad options: 2), or nothing when it should go on.
std::optional<int> parse_drive_bridge_command_line(int argc, char** argv, DriveBridgeOptions& opt);

}  // namespace pmlsm::node

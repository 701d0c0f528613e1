// plant_sim's command line, apart from the node so that only the parser includes CLI11 (see
// nodes/support/CMakeLists.txt: the nodes' parsers are compiled together in pmlsm_node_support).
#pragma once

#include <optional>

#include "drive_node.hpp"
#include "node_support.hpp"

namespace pmlsm::node {

/// Parses plant_sim's command line into `common` and `drive` (their values are the defaults
/// shown): an exit code to end with (help: 0, bad options: 2), or nothing when it should go on.
std::optional<int> parse_plant_sim_command_line(int argc, char** argv, CommonOptions& common, DriveNodeOptions& drive);

}  // namespace pmlsm::node

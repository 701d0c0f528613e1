// controller's command line, apart from the node so that only the parser includes CLI11 (see
// nodes/support/CMakeLists.txt: the nodes' parsers are compiled together in pmlsm_node_support).
#pragma once

#include <optional>
#include <string>

#include "node_support.hpp"

namespace pmlsm::node {

struct ControllerOptions {
  std::string compensation = "none";
  // Readers of the commands to wait for before the first answer: a sample written before a
  // reader matched is lost to it, and a lockstep drive that never enables itself steps 300
  // ticks in 30 ms, before an observer (the evaluator) may have matched the controller.
  int command_readers = 0;    ///< ForceCommand readers (the drive, the evaluator, a recorder)
  int reference_readers = 0;  ///< VelocityReference readers (the evaluator, a compensator)
};

/// Parses controller's command line into `common` and `opt` (their values are the defaults
/// shown): an exit code to end with (help: 0, bad options: 2), or nothing when it should go on.
std::optional<int> parse_controller_command_line(int argc, char** argv, CommonOptions& common, ControllerOptions& opt);

}  // namespace pmlsm::node

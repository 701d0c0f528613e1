// kalman_estimator's command line, apart from the node so that only the parser includes CLI11
// (see nodes/support/CMakeLists.txt: the nodes' parsers are compiled together in pmlsm_node_support).
#pragma once

#include <optional>

#include "node_support.hpp"

namespace pmlsm::node {

/// Parses kalman_estimator's command line into `common` and `estimate_readers` (their values are
/// the defaults shown): an exit code to end with (help: 0, bad options: 2), or nothing.
std::optional<int> parse_kalman_estimator_command_line(int argc, char** argv, CommonOptions& common,
                                                       int& estimate_readers);

}  // namespace pmlsm::node

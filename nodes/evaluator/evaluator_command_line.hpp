// evaluator's command line, apart from the node so that only the parser includes CLI11 (see
// nodes/support/CMakeLists.txt: the nodes' parsers are compiled together in pmlsm_node_support).
#pragma once

#include <optional>
#include <string>

#include "node_support.hpp"

namespace pmlsm::node {

struct EvaluatorOptions {
  std::string out_dir = "out";
  bool print_header = true;
  std::string label;
  bool truth_optional = false;  ///< --truth optional
};

/// Parses evaluator's command line into `common` and `opt` (their values are the defaults
/// shown): an exit code to end with (help: 0, bad options: 2), or nothing when it should go on.
std::optional<int> parse_evaluator_command_line(int argc, char** argv, CommonOptions& common, EvaluatorOptions& opt);

}  // namespace pmlsm::node

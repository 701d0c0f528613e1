// The compensators' command lines, apart from the nodes so that only the parsers include CLI11
// (see nodes/support/CMakeLists.txt: the nodes' parsers are compiled together in pmlsm_node_support).
// Each parses into options whose values are the defaults shown, and returns an exit code to end
// with (help: 0, bad options: 2), or nothing when the node should go on.
#pragma once

#include <optional>
#include <string>

#include "node_support.hpp"

namespace pmlsm::node {

struct RnnOptions {
  CommonOptions common;
  std::string weights_path;
  bool online_learning = false;
  bool ignore_topic = false;
};

std::optional<int> parse_rnn_compensator_command_line(int argc, char** argv, RnnOptions& opt);
std::optional<int> parse_accel_feedback_command_line(int argc, char** argv, CommonOptions& common);
std::optional<int> parse_state_feedback_command_line(int argc, char** argv, CommonOptions& common);
/// A law added in its own folder (law_compensator.hpp): the common options; `summary` heads --help.
std::optional<int> parse_law_compensator_command_line(int argc, char** argv, const char* summary,
                                                      CommonOptions& common);

}  // namespace pmlsm::node

// foxglove_bridge's command line, apart from the component so that only the parser includes CLI11
// (see nodes/support/CMakeLists.txt: the nodes' parsers are compiled together in pmlsm_node_support).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "node_support.hpp"

namespace pmlsm::node {

/// The name of the bridge's built-in reader profile (foxglove_bridge.cpp has its XML), the
/// default of --reader-profile.
inline constexpr const char* kLiveReaderProfile = "pmlsm_bridge_live";

struct FoxgloveBridgeOptions {
  dds::ParticipantOptions dds;
  std::string address = "0.0.0.0";
  int port = 8765;
  std::vector<std::string> topics;  // empty: every catalog topic
  std::string reader_profile = kLiveReaderProfile;
  std::size_t queue_frames = 1024;
  std::size_t client_buffer_kib = 1024;
  std::size_t max_clients = 8;
  double status_period_s = 1.0;
  double batch_ms = 5.0;
  int nice = 10;
};

/// Parses foxglove_bridge's command line into `opt` (its values are the defaults shown): an exit
/// code to end with (help: 0, bad options: 2), or nothing when it should go on.
std::optional<int> parse_foxglove_bridge_command_line(int argc, char** argv, FoxgloveBridgeOptions& opt);

}  // namespace pmlsm::node

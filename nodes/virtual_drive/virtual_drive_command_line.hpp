// virtual_drive's command line, apart from the node so that only the parser includes CLI11 (see
// nodes/support/CMakeLists.txt: the nodes' parsers are compiled together in pmlsm_node_support).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "can_options.hpp"
#include "ethercat_options.hpp"
#include "node_support.hpp"
#include "pmlsm/util/data_files.hpp"

namespace pmlsm::node {

struct VirtualDriveOptions {
  CommonOptions common;
  CanOptions can;
  EthercatOptions ethercat;
  std::string dictionary_path = pmlsm::data_file("configs/canopen/virtual_drive_od.yaml");
  std::optional<std::uint64_t> inject_fault_at_tick;
  bool publish_truth = false;
  /// --bus ethercat: the virtual drive's clock crystal's rate error [ppm].
  double dc_drift_ppm = 0.0;
};

/// Parses virtual_drive's command line into `opt` (its values are the defaults shown): an exit
/// code to end with (help: 0, bad options: 2), or nothing when it should go on.
std::optional<int> parse_virtual_drive_command_line(int argc, char** argv, VirtualDriveOptions& opt);

}  // namespace pmlsm::node

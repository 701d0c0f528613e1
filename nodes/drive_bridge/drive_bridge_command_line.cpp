#include "drive_bridge_command_line.hpp"

#include <CLI/CLI.hpp>

namespace pmlsm::node {

std::optional<int> parse_drive_bridge_command_line(int argc, char** argv, DriveBridgeOptions& opt) {
  CLI::App app{"Bridge from DDS to a CiA 402 servo drive on CAN or EtherCAT (cyclic synchronous torque)"};
  add_common_options(app, opt.common);
  add_drive_node_options(app, opt.drive);
  add_can_options(app, opt.can);
  add_ethercat_options(app, opt.ethercat, true);
  app.add_flag("--no-reset-communication", opt.no_reset,
               "do not start the boot with NMT reset communication: wait for the drive's own boot-up or heartbeat");
  return parse_command_line(app, argc, argv);
}

}  // namespace pmlsm::node

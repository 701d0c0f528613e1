#include "virtual_drive_command_line.hpp"

#include <CLI/CLI.hpp>

namespace pmlsm::node {

std::optional<int> parse_virtual_drive_command_line(int argc, char** argv, VirtualDriveOptions& opt) {
  CLI::App app{"virtual_drive: the simulated PMLSM drive behind a CiA 402 slave on CANopen or EtherCAT"};
  add_common_options(app, opt.common);
  add_can_options(app, opt.can);
  add_ethercat_options(app, opt.ethercat, false);
  app.add_option("--ethercat-dc-drift-ppm", opt.dc_drift_ppm,
                 "--bus ethercat: the drive's distributed clock runs this many ppm fast (negative: slow)")
      ->check(CLI::Range(-1000.0, 1000.0))
      ->capture_default_str();
  app.add_option("--dictionary", opt.dictionary_path,
                 "the device's part of the object dictionary (identity, manufacturer objects, PDO defaults), EDS-like")
      ->capture_default_str();
  app.add_option("--inject-fault-at-tick", opt.inject_fault_at_tick,
                 "fault 0x5000 (device hardware) at this period; cleared by fault reset and enable");
  app.add_flag(
      "--publish-truth", opt.publish_truth,
      "lockstep: publish PlantTruth on DDS (for the evaluator), stamped with the bridge's run (realtime: none)");
  return parse_command_line(app, argc, argv);
}

}  // namespace pmlsm::node

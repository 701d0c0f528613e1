#include "plant_sim_command_line.hpp"

#include <CLI/CLI.hpp>

namespace pmlsm::node {

std::optional<int> parse_plant_sim_command_line(int argc, char** argv, CommonOptions& common, DriveNodeOptions& drive) {
  CLI::App app{"Simulated PMLSM servo drive (plant + drive current loop) on DDS"};
  add_common_options(app, common);
  add_drive_node_options(app, drive);
  return parse_command_line(app, argc, argv);
}

}  // namespace pmlsm::node

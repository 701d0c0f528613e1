#include "controller_command_line.hpp"

#include <CLI/CLI.hpp>

namespace pmlsm::node {

std::optional<int> parse_controller_command_line(int argc, char** argv, CommonOptions& common, ControllerOptions& opt) {
  CLI::App app{"Velocity loop (reference model + PI) of the PMLSM on DDS"};
  add_common_options(app, common);
  app.add_option(
         "--compensation", opt.compensation,
         "none (PI only) or topic (add CompensatorOutput to the PI output); accel, rnn and state are topic, named "
         "after the compensator that publishes it (launch files pass their compensator arg)")
      ->check(CLI::IsMember({"none", "topic", "accel", "rnn", "state"}))
      ->capture_default_str();
  app.add_option("--command-readers", opt.command_readers,
                 "ForceCommand readers to wait for before the first answer (0: answer at once)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  app.add_option("--reference-readers", opt.reference_readers,
                 "VelocityReference readers to wait for before the first answer (0: answer at once)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  return parse_command_line(app, argc, argv);
}

}  // namespace pmlsm::node

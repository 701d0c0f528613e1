#include "kalman_estimator_command_line.hpp"

#include <CLI/CLI.hpp>

namespace pmlsm::node {

std::optional<int> parse_kalman_estimator_command_line(int argc, char** argv, CommonOptions& common,
                                                       int& estimate_readers) {
  CLI::App app{"Kalman estimator of the load velocity and spring force on DDS"};
  add_common_options(app, common);
  app.add_option("--estimate-readers", estimate_readers,
                 "EstimatedState readers to wait for before the first estimate (0: estimate at once)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  return parse_command_line(app, argc, argv);
}

}  // namespace pmlsm::node

#include "compensator_command_lines.hpp"

#include <CLI/CLI.hpp>

namespace pmlsm::node {

std::optional<int> parse_rnn_compensator_command_line(int argc, char** argv, RnnOptions& opt) {
  CLI::App app{"Jordan RNN vibration compensator on DDS"};
  add_common_options(app, opt.common);
  app.add_option("-w,--weights", opt.weights_path, "Weights file (from de_trainer)")->check(CLI::ExistingFile);
  app.add_flag("--online-learning", opt.online_learning, "Refine the weights online, eqs. (16)-(19)");
  app.add_flag("--no-weights-topic", opt.ignore_topic, "Do not take weight sets from the NetworkWeights topic");
  return parse_command_line(app, argc, argv);
}

std::optional<int> parse_accel_feedback_command_line(int argc, char** argv, CommonOptions& common) {
  CLI::App app{"Load-acceleration feedback compensator F = -K_a a_L on DDS (the RNN's baseline)"};
  add_common_options(app, common);
  return parse_command_line(app, argc, argv);
}

std::optional<int> parse_state_feedback_command_line(int argc, char** argv, CommonOptions& common) {
  CLI::App app{"Model-following state feedback compensator on DDS (inverse-model feedforward, estimated spring force)"};
  add_common_options(app, common);
  return parse_command_line(app, argc, argv);
}

std::optional<int> parse_law_compensator_command_line(int argc, char** argv, const char* summary,
                                                      CommonOptions& common) {
  CLI::App app{summary};
  add_common_options(app, common);
  return parse_command_line(app, argc, argv);
}

}  // namespace pmlsm::node

// state_feedback: model-following state feedback with feedforward through the two-mass
// model's inverse (pmlsm/compensation/state_feedback.hpp), on the same topics as
// accel_feedback and rnn_compensator, so any of them can be launched in another's place.
#include <cstdio>

#include "compensator_node.hpp"
#include "pmlsm/compensation/state_feedback.hpp"

namespace {

using namespace pmlsm;

int run(int argc, char** argv) {
  CLI::App app{"Model-following state feedback compensator on DDS (inverse-model feedforward, estimated spring force)"};
  node::CommonOptions common;
  node::add_common_options(app, common);
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  node::NodeRuntime rt("state_feedback", common);
  const StateFeedbackParams params = rt.cfg.params.state_feedback_params();
  StateFeedback feedback(params);
  node::CompensatorInputs inputs(rt.participant, rt.wakeup);
  const node::CompensatorLoopResult result =
      node::run_fixed_law("state_feedback", rt, common, inputs, params.force_limit_n,
                          [&](const CompensatorView& view) { return feedback.step(state_feedback_input(view)); });
  const std::uint64_t answered = result.answered;
  const StateFeedbackCounters& counters = feedback.counters();
  rt.status.status().rejected(inputs.rejected() + counters.rejected_inputs + counters.model_resets);
  rt.status.publish(pmlsm_msgs::msg::NodeStatus_Constants::STATE_STOPPING, answered, rt.period_s, "done");
  std::printf(
      "state_feedback: model %.1f/%.1f kg, %.0f N/m, %llu ticks answered, %llu saturated, %llu rejected, "
      "%llu model restarts, %llu skipped\n",
      params.motor_mass_kg, params.load_mass_kg, params.spring_n_per_m, static_cast<unsigned long long>(answered),
      static_cast<unsigned long long>(counters.saturated),
      static_cast<unsigned long long>(inputs.rejected() + counters.rejected_inputs),
      static_cast<unsigned long long>(counters.model_resets), static_cast<unsigned long long>(inputs.skipped()));
  return result.exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  return pmlsm::node::run_node("state_feedback", [&] { return run(argc, argv); });
}

// accel_feedback: the classical baseline, F_c = -K_a a_L from the Kalman
// estimate (pmlsm/compensation/accel_feedback.hpp), on the same topics as rnn_compensator,
// so either can be launched in the other's place.
#include <cstdio>

#include "compensator_node.hpp"
#include "pmlsm/compensation/accel_feedback.hpp"

namespace {

using namespace pmlsm;

int run(int argc, char** argv) {
  CLI::App app{"Load-acceleration feedback compensator F = -K_a a_L on DDS (the RNN's baseline)"};
  node::CommonOptions common;
  node::add_common_options(app, common);
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  node::NodeRuntime rt("accel_feedback", common);
  const AccelFeedbackParams params = rt.cfg.params.accel_feedback_params();
  AccelFeedback feedback(params);
  node::CompensatorInputs inputs(rt.participant, rt.wakeup);
  const node::CompensatorLoopResult result =
      node::run_fixed_law("accel_feedback", rt, common, inputs, params.force_limit_n,
                          [&](const CompensatorView& view) { return feedback.step(accel_feedback_input(view)); });
  const std::uint64_t answered = result.answered;
  rt.status.status().rejected(inputs.rejected() + feedback.counters().rejected_inputs);
  rt.status.publish(pmlsm_msgs::msg::NodeStatus_Constants::STATE_STOPPING, answered, rt.period_s, "done");
  std::printf("accel_feedback: K_a %.1f kg (x %.3f on the model's load)%s, %llu ticks answered, %llu saturated, "
              "%llu rejected, %llu skipped\n",
              params.gain_kg, rt.cfg.params.compensator_gain_scale(),
              params.on_reference_error ? " on the error to the reference" : "", static_cast<unsigned long long>(answered),
              static_cast<unsigned long long>(feedback.counters().saturated),
              static_cast<unsigned long long>(inputs.rejected() + feedback.counters().rejected_inputs),
              static_cast<unsigned long long>(inputs.skipped()));
  return result.exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  return pmlsm::node::run_node("accel_feedback", [&] { return run(argc, argv); });
}

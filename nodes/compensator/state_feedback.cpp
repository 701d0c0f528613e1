// state_feedback: model-following state feedback with feedforward through the two-mass
// model's inverse (pmlsm/compensation/state_feedback.hpp), on the same topics as
// accel_feedback and rnn_compensator, so any of them can be launched in another's place.
#include <cstdio>

#include "compensator_node.hpp"
#include "pmlsm/compensation/state_feedback.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;

int run(int argc, char** argv) {
  CLI::App app{"Model-following state feedback compensator on DDS (inverse-model feedforward, estimated spring force)"};
  node::CommonOptions common;
  node::add_common_options(app, common);
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  node::NodeRuntime rt("state_feedback", common);
  const StateFeedbackParams params = rt.cfg.params.state_feedback_params();
  StateFeedback feedback(params);
  node::CompensatorInputs inputs(rt.participant, rt.wakeup);
  auto writer = rt.participant.make_writer<msg::CompensatorOutputPubSubType>(pdds::topics::kCompensatorOutput);
  const std::uint64_t ticks = scenario_ticks(rt.cfg.scenario, rt.period_s);
  rt.status.publish(pmlsm_msgs::msg::NodeStatus_Constants::STATE_RUNNING, 0, rt.period_s, "running");

  msg::CompensatorOutput out;
  out.flags(msg::CompensatorOutput_Constants::FLAG_ENABLED);
  std::uint64_t tick = 0, answered = 0;
  CompensatorView view;
  int exit_code = kExitOk;
  while (answered < ticks && !pdds::stop_requested()) {
    if (!inputs.next(std::chrono::duration<double>(common.peer_timeout_s), tick, view)) {
      exit_code = node::end_of_failed_wait("state_feedback", "EstimatedState and VelocityReference",
                                           "estimator or controller", answered, common.peer_timeout_s);
      break;
    }
    const double force_n = feedback.step(state_feedback_input(view));
    out.stamp(node::make_stamp(tick, rt.period_s, inputs.run_id()));
    out.estimate_tick(tick);
    out.force_n(force_n);
    out.u_n(force_n / params.force_limit_n);
    out.training_error_mps(view.v_ref_mps - view.v_load_mps);
    writer.write(out);
    answered = tick + 1;
  }
  const StateFeedbackCounters& counters = feedback.counters();
  rt.status.status().rejected(inputs.rejected() + counters.rejected_inputs + counters.model_resets);
  rt.status.publish(pmlsm_msgs::msg::NodeStatus_Constants::STATE_STOPPING, answered, rt.period_s, "done");
  writer.wait_for_acknowledgments(node::kFlushTimeout);
  std::printf(
      "state_feedback: model %.1f/%.1f kg, %.0f N/m, %llu ticks answered, %llu saturated, %llu rejected, "
      "%llu model restarts, %llu skipped\n",
      params.motor_mass_kg, params.load_mass_kg, params.spring_n_per_m, static_cast<unsigned long long>(answered),
      static_cast<unsigned long long>(counters.saturated),
      static_cast<unsigned long long>(inputs.rejected() + counters.rejected_inputs),
      static_cast<unsigned long long>(counters.model_resets), static_cast<unsigned long long>(inputs.skipped()));
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  return pmlsm::node::run_node("state_feedback", [&] { return run(argc, argv); });
}

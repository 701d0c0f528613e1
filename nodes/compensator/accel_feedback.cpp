// accel_feedback: the classical baseline, F_c = -K_a a_L from the Kalman
// estimate (pmlsm/compensation/accel_feedback.hpp), on the same topics as rnn_compensator,
// so either can be launched in the other's place.
#include <cstdio>

#include "compensator_node.hpp"
#include "pmlsm/compensation/accel_feedback.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;

int run(int argc, char** argv) {
  CLI::App app{"Load-acceleration feedback compensator F = -K_a a_L on DDS (the RNN's baseline)"};
  node::CommonOptions common;
  node::add_common_options(app, common);
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  node::NodeRuntime rt("accel_feedback", common);
  AccelFeedback feedback(rt.cfg.params.accel_feedback_params());
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
      exit_code = node::end_of_failed_wait("accel_feedback", "EstimatedState and VelocityReference", "estimator or controller",
                                           answered, common.peer_timeout_s);
      break;
    }
    const double force_n = feedback.step(view.load_accel_mps2);
    out.stamp(node::make_stamp(tick, rt.period_s, inputs.run_id()));
    out.estimate_tick(tick);
    out.force_n(force_n);
    out.u_n(force_n / rt.cfg.params.accel_feedback_params().force_limit_n);
    out.training_error_mps(view.v_ref_mps - view.v_load_mps);
    writer.write(out);
    answered = tick + 1;
  }
  rt.status.status().rejected(inputs.rejected() + feedback.counters().rejected_inputs);
  rt.status.publish(pmlsm_msgs::msg::NodeStatus_Constants::STATE_STOPPING, answered, rt.period_s, "done");
  writer.wait_for_acknowledgments(node::kFlushTimeout);
  std::printf("accel_feedback: K_a %.1f kg, %llu ticks answered, %llu saturated, %llu rejected, %llu skipped\n",
              rt.cfg.params.compensator.accel_feedback_gain_kg, static_cast<unsigned long long>(answered),
              static_cast<unsigned long long>(feedback.counters().saturated),
              static_cast<unsigned long long>(inputs.rejected() + feedback.counters().rejected_inputs),
              static_cast<unsigned long long>(inputs.skipped()));
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  return pmlsm::node::run_node("accel_feedback", [&] { return run(argc, argv); });
}

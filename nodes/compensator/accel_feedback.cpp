// accel_feedback: the classical baseline, F_c = -K_a a_L from the Kalman
// estimate (pmlsm/compensation/accel_feedback.hpp), on the same topics as rnn_compensator,
// so either can be launched in the other's place.
#include <cstdio>

#include "compensator_command_lines.hpp"
#include "compensator_node.hpp"
#include "pmlsm/compensation/accel_feedback.hpp"

namespace {

using namespace pmlsm;

class AccelFeedbackComponent final : public node::Component {
 public:
  AccelFeedbackComponent(const node::ComponentContext& context, node::CommonOptions common)
      : common_(std::move(common)),
        rt_("accel_feedback", common_, context),
        params_(rt_.cfg.params.accel_feedback_params()),
        law_(params_),
        inputs_(rt_.participant, rt_.wakeup, rt_.cfg),
        writer_(rt_.participant.make_writer(pmlsm::dds::topics::kCompensatorOutput)),
        live_(rt_.cfg.params, live_keys("accel_feedback")),
        parameters_(rt_, "accel_feedback", live_) {}

  int run() override {
    const node::CompensatorLoopResult result = node::run_fixed_law(
        "accel_feedback", rt_, common_, inputs_, writer_, params_.force_limit_n, parameters_, live_, nullptr,
        [&](const CompensatorView& view) { return law_.step(accel_feedback_input(view)); },
        [&](const SystemParams& changed) { law_.set_params(changed.accel_feedback_params()); });
    const std::uint64_t answered = result.answered;
    rt_.status.status().rejected(inputs_.rejected() + law_.counters().rejected_inputs);
    rt_.status.publish(pmlsm_msgs::msg::NodeStatus_Constants::STATE_STOPPING, answered, rt_.period_s, "done");
    std::printf(
        "accel_feedback: K_a %.1f kg (x %.3f on the model's load)%s, %llu ticks answered, %llu saturated, "
        "%llu rejected, %llu skipped\n",
        law_.params().gain_kg, rt_.cfg.params.compensator_gain_scale(),
        params_.on_reference_error ? " on the error to the reference" : "", static_cast<unsigned long long>(answered),
        static_cast<unsigned long long>(law_.counters().saturated),
        static_cast<unsigned long long>(inputs_.rejected() + law_.counters().rejected_inputs),
        static_cast<unsigned long long>(inputs_.skipped()));
    return result.exit_code;
  }

 private:
  node::CommonOptions common_;
  node::NodeRuntime rt_;
  AccelFeedbackParams params_;
  AccelFeedback law_;
  node::CompensatorInputs inputs_;
  node::CompensatorWriter writer_;
  LiveParameters live_;
  node::ParameterService parameters_;
};

}  // namespace

namespace pmlsm::node {

PMLSM_COMPONENT(accel_feedback, make_accel_feedback, 1);

MadeComponent make_accel_feedback(const ComponentContext& context, int argc, char** argv) {
  CommonOptions common;
  if (const auto code = parse_accel_feedback_command_line(argc, argv, common)) return {nullptr, *code};
  return {std::make_unique<AccelFeedbackComponent>(context, std::move(common))};
}

}  // namespace pmlsm::node

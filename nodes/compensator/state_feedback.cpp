// state_feedback: model-following state feedback with feedforward through the two-mass
// model's inverse (pmlsm/compensation/state_feedback.hpp), on the same topics as
// accel_feedback and rnn_compensator, so any of them can be launched in another's place.
#include <cstdio>

#include "compensator_command_lines.hpp"
#include "compensator_node.hpp"
#include "pmlsm/compensation/state_feedback.hpp"

namespace {

using namespace pmlsm;

class StateFeedbackComponent final : public node::Component {
 public:
  StateFeedbackComponent(const node::ComponentContext& context, node::CommonOptions common)
      : common_(std::move(common)),
        rt_("state_feedback", common_, context),
        params_(rt_.cfg.params.state_feedback_params()),
        law_(params_),
        inputs_(rt_.participant, rt_.wakeup, rt_.cfg),
        writer_(rt_.participant.make_writer(pmlsm::dds::topics::kCompensatorOutput)),
        live_(rt_.cfg.params, live_keys("state_feedback")),
        parameters_(rt_, "state_feedback", live_),
        follower_(rt_, "state_feedback", "controller", rt_.cfg.params) {}

  int run() override {
    const node::CompensatorLoopResult result = node::run_fixed_law(
        "state_feedback", rt_, common_, inputs_, writer_, params_.force_limit_n, parameters_, live_, &follower_,
        [&](const CompensatorView& view) { return law_.step(state_feedback_input(view)); },
        [&](const SystemParams& changed) { law_.set_params(changed.state_feedback_params()); });
    const std::uint64_t answered = result.answered;
    const StateFeedbackCounters& counters = law_.counters();
    rt_.status.status().rejected(inputs_.rejected() + counters.rejected_inputs + counters.model_resets);
    rt_.status.publish(pmlsm_msgs::msg::NodeStatus_Constants::STATE_STOPPING, answered, rt_.period_s, "done");
    std::printf(
        "state_feedback: model %.1f/%.1f kg, %.0f N/m, %llu ticks answered, %llu saturated, %llu rejected, "
        "%llu model restarts, %llu skipped\n",
        params_.model.motor_mass_kg, params_.model.load_mass_kg, params_.model.spring_n_per_m,
        static_cast<unsigned long long>(answered), static_cast<unsigned long long>(counters.saturated),
        static_cast<unsigned long long>(inputs_.rejected() + counters.rejected_inputs),
        static_cast<unsigned long long>(counters.model_resets), static_cast<unsigned long long>(inputs_.skipped()));
    return result.exit_code;
  }

 private:
  node::CommonOptions common_;
  node::NodeRuntime rt_;
  StateFeedbackParams params_;
  StateFeedback law_;
  node::CompensatorInputs inputs_;
  node::CompensatorWriter writer_;
  LiveParameters live_;
  node::ParameterService parameters_;
  /// Its model's loop runs on the controller's Kp: a change there reaches it at the same tick.
  node::ParameterFollower follower_;
};

}  // namespace

namespace pmlsm::node {

PMLSM_COMPONENT(state_feedback, make_state_feedback, 1);

MadeComponent make_state_feedback(const ComponentContext& context, int argc, char** argv) {
  CommonOptions common;
  if (const auto code = parse_state_feedback_command_line(argc, argv, common)) return {nullptr, *code};
  return {std::make_unique<StateFeedbackComponent>(context, std::move(common))};
}

}  // namespace pmlsm::node

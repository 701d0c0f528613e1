// state_feedback: model-following state feedback with feedforward through the two-mass
// model's inverse (pmlsm/compensation/state_feedback.hpp), on the same topics as
// accel_feedback and rnn_compensator, so any of them can be launched in another's place.
#include <cstdio>

#include "compensator_command_lines.hpp"
#include "compensator_node.hpp"
#include "pmlsm/compensation/state_feedback.hpp"

namespace {

using namespace pmlsm;

class StateFeedbackComponent final : public node::FixedLawComponent {
 public:
  /// Its model's loop runs on the controller's Kp: it follows the controller's live changes, so a
  /// change there reaches it at the same tick.
  StateFeedbackComponent(const node::ComponentContext& context, node::CommonOptions common)
      : FixedLawComponent("state_feedback", context, std::move(common), "controller"),
        params_(rt_.cfg.params.state_feedback_params()),
        law_(params_) {}

 private:
  double force(const CompensatorView& view) override { return law_.step(state_feedback_input(view)); }
  void retune(const SystemParams& changed) override { law_.set_params(changed.state_feedback_params()); }
  void report(std::uint64_t answered) override {
    const StateFeedbackCounters& counters = law_.counters();
    rt_.status.status().rejected(inputs_.rejected() + counters.rejected_inputs + counters.model_resets);
    std::printf(
        "state_feedback: model %.1f/%.1f kg, %.0f N/m, %llu ticks answered, %llu saturated, %llu rejected, "
        "%llu model restarts, %llu skipped\n",
        params_.model.motor_mass_kg, params_.model.load_mass_kg, params_.model.spring_n_per_m,
        static_cast<unsigned long long>(answered), static_cast<unsigned long long>(counters.saturated),
        static_cast<unsigned long long>(inputs_.rejected() + counters.rejected_inputs),
        static_cast<unsigned long long>(counters.model_resets), static_cast<unsigned long long>(inputs_.skipped()));
  }

  StateFeedbackParams params_;
  StateFeedback law_;
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

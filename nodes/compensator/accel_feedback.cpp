// accel_feedback: the classical baseline, F_c = -K_a a_L from the Kalman
// estimate (pmlsm/compensation/accel_feedback.hpp), on the same topics as rnn_compensator,
// so either can be launched in the other's place.
#include <cstdio>

#include "compensator_command_lines.hpp"
#include "compensator_node.hpp"
#include "pmlsm/compensation/accel_feedback.hpp"

namespace {

using namespace pmlsm;

class AccelFeedbackComponent final : public node::FixedLawComponent {
 public:
  AccelFeedbackComponent(const node::ComponentContext& context, node::CommonOptions common)
      : FixedLawComponent("accel_feedback", context, std::move(common)),
        params_(rt_.cfg.params.accel_feedback_params()),
        law_(params_) {}

 private:
  double force(const CompensatorView& view) override { return law_.step(accel_feedback_input(view)); }
  void retune(const SystemParams& changed) override { law_.set_params(changed.accel_feedback_params()); }
  void report(std::uint64_t answered) override {
    rt_.status.status().rejected(inputs_.rejected() + law_.counters().rejected_inputs);
    std::printf(
        "accel_feedback: K_a %.1f kg (x %.3f on the model's load)%s, %llu ticks answered, %llu saturated, "
        "%llu rejected, %llu skipped\n",
        law_.params().gain_kg, rt_.cfg.params.compensator_gain_scale(),
        params_.on_reference_error ? " on the error to the reference" : "", static_cast<unsigned long long>(answered),
        static_cast<unsigned long long>(law_.counters().saturated),
        static_cast<unsigned long long>(inputs_.rejected() + law_.counters().rejected_inputs),
        static_cast<unsigned long long>(inputs_.skipped()));
  }

  AccelFeedbackParams params_;
  AccelFeedback law_;
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

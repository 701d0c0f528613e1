#include "pmlsm/analysis/compensated_run.hpp"

#include <stdexcept>

#include "pmlsm/compensation/accel_feedback.hpp"
#include "pmlsm/compensation/state_feedback.hpp"
#include "pmlsm/analysis/rnn_training.hpp"

namespace pmlsm {

namespace {
constexpr CompensatorKind kAllKinds[] = {CompensatorKind::kNone, CompensatorKind::kAccel, CompensatorKind::kRnn,
                                         CompensatorKind::kState};
}  // namespace

const char* to_string(CompensatorKind kind) {
  switch (kind) {
    case CompensatorKind::kNone: return "none";
    case CompensatorKind::kAccel: return "accel";
    case CompensatorKind::kRnn: return "rnn";
    case CompensatorKind::kState: return "state";
  }
  return "?";
}

std::string compensator_kind_names() {
  std::string names;
  for (CompensatorKind kind : kAllKinds) names += (names.empty() ? "" : ", ") + std::string(to_string(kind));
  return names;
}

CompensatorKind compensator_kind_from_string(const std::string& name) {
  for (CompensatorKind kind : kAllKinds) {
    if (name == to_string(kind)) return kind;
  }
  throw std::invalid_argument("compensator must be one of " + compensator_kind_names() + ", got '" + name + "'");
}

std::vector<TickRecord> run_with_compensator(const SystemParams& params, const Scenario& scenario,
                                             const CompensatorSetup& setup, std::uint64_t max_ticks) {
  switch (setup.kind) {
    case CompensatorKind::kNone:
      return run_compensated(
          params, scenario, [](const CompensatorView&) { return Compensation{}; }, max_ticks);
    case CompensatorKind::kAccel: {
      AccelFeedback feedback(params.accel_feedback_params());
      return run_compensated(
          params, scenario,
          [&](const CompensatorView& view) {
            return clamped_compensation(feedback.step(accel_feedback_input(view)), feedback.params().force_limit_n);
          },
          max_ticks);
    }
    case CompensatorKind::kRnn:
      return run_with_rnn(params, scenario, setup.rnn_weights, setup.online_learning, max_ticks);
    case CompensatorKind::kState: {
      StateFeedback feedback(params.state_feedback_params());
      return run_compensated(
          params, scenario,
          [&](const CompensatorView& view) {
            return clamped_compensation(feedback.step(state_feedback_input(view)), feedback.params().force_limit_n);
          },
          max_ticks);
    }
  }
  throw std::invalid_argument("run_with_compensator: unknown compensator kind");
}

}  // namespace pmlsm

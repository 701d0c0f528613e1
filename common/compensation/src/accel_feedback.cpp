#include "pmlsm/compensation/accel_feedback.hpp"

#include <algorithm>
#include <cmath>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

void AccelFeedbackParams::validate() const {
  check_declared_ranges(*this);
  require_positive("force_limit_n", force_limit_n);  // the velocity loop's
}

AccelFeedback::AccelFeedback(const AccelFeedbackParams& params) : params_(params) { params_.validate(); }

void AccelFeedback::set_params(const AccelFeedbackParams& params) {
  params.validate();
  params_ = params;
}

double AccelFeedback::step(const AccelFeedbackInput& in) {
  ++counters_.steps;
  const double accel_mps2 =
      params_.on_reference_error ? in.load_accel_mps2 - in.reference_accel_mps2 : in.load_accel_mps2;
  if (!std::isfinite(accel_mps2)) {
    ++counters_.rejected_inputs;
    return 0.0;
  }
  const double force_n = -params_.gain_kg * accel_mps2;
  if (std::abs(force_n) > params_.force_limit_n) ++counters_.saturated;
  return std::clamp(force_n, -params_.force_limit_n, params_.force_limit_n);
}

}  // namespace pmlsm

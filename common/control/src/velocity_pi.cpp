#include "pmlsm/control/velocity_pi.hpp"

#include <algorithm>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

void VelocityPiParams::validate() const {
  check_declared_ranges(*this);
  require_in_range("period_s", period_s, 1e-6, 1.0);
}

VelocityPi::VelocityPi(const VelocityPiParams& params) : params_(params) { params_.validate(); }

void VelocityPi::set_params(const VelocityPiParams& params) {
  params.validate();
  params_ = params;
}

void VelocityPi::reset() {
  integral_n_ = 0;
  last_output_ = VelocityPiOutput{};
}

VelocityPiOutput VelocityPi::step(const VelocityPiInput& in) {
  if (!all_finite(in.velocity_reference_mps, in.velocity_measured_mps, in.feedforward_force_n)) {
    ++counters_.rejected_inputs;
    return last_output_;
  }
  ++counters_.steps;
  const auto& p = params_;
  const double error = in.velocity_reference_mps - in.velocity_measured_mps;
  const double unlimited = p.kp_n_s_per_m * error + integral_n_ + in.feedforward_force_n;
  VelocityPiOutput out;
  out.force_n = std::clamp(unlimited, -p.force_limit_n, p.force_limit_n);
  out.saturated = out.force_n != unlimited;
  const bool winds_up = out.saturated && (error > 0) == (unlimited > 0);
  if (!winds_up) integral_n_ += p.ki_n_per_m * p.period_s * error;
  counters_.saturated += out.saturated ? 1 : 0;
  last_output_ = out;
  return out;
}

}  // namespace pmlsm

#include "pmlsm/control/reference_model.hpp"

#include <cmath>

#include "pmlsm/util/discretize.hpp"
#include "pmlsm/util/validate.hpp"

namespace pmlsm {

void ReferenceModelParams::validate() const {
  check_declared_ranges(*this);
  require_in_range("period_s", period_s, 1e-6, 1.0);
}

ReferenceModel::ReferenceModel(const ReferenceModelParams& params) : params_(params) {
  params_.validate();
  const double wn = params_.natural_frequency_rad_s;
  Eigen::MatrixXd a(2, 2);
  a << 0.0, 1.0, -wn * wn, -2.0 * params_.damping_ratio * wn;
  Eigen::MatrixXd b(2, 1);
  b << 0.0, wn * wn;
  const DiscreteModel d = discretize_zoh(a, b, params_.period_s);
  phi_ = d.phi;
  gamma_ = d.gamma;
}

void ReferenceModel::reset(double initial_velocity_mps) {
  state_ << initial_velocity_mps, 0.0;
  last_command_mps_ = initial_velocity_mps;
}

ReferenceSample ReferenceModel::step(double command_mps) {
  if (std::isfinite(command_mps)) {
    last_command_mps_ = command_mps;
  } else {
    ++rejected_inputs_;
  }
  state_ = phi_ * state_ + gamma_ * last_command_mps_;
  return ReferenceSample{state_(0), state_(1)};
}

}  // namespace pmlsm

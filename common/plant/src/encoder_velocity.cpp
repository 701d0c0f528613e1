#include "pmlsm/plant/encoder_velocity.hpp"

#include <cmath>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

EncoderVelocity::EncoderVelocity(double period_s) : period_s_(period_s) { require_positive("period_s", period_s); }

void EncoderVelocity::reset(double position_m) {
  last_position_m_ = position_m;
  last_velocity_mps_ = 0;
}

double EncoderVelocity::step(double position_m) {
  if (!std::isfinite(position_m)) {
    ++rejected_inputs_;
    return last_velocity_mps_;
  }
  last_velocity_mps_ = (position_m - last_position_m_) / period_s_;
  last_position_m_ = position_m;
  return last_velocity_mps_;
}

}  // namespace pmlsm

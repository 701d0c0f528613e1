// Motor velocity from the encoder, as a drive computes it: the backward
// difference of two position readings one control period apart,
//   v_k = (x_k - x_{k-1}) / T.
// With a 1 um encoder at T = 1 ms the velocity resolution is 1 mm/s.
#pragma once

#include <cstdint>

namespace pmlsm {

class EncoderVelocity {
 public:
  /// @throws std::invalid_argument if period_s is not finite and positive.
  explicit EncoderVelocity(double period_s);
  /// Starts from a reading, so the first step does not see a jump from zero.
  void reset(double position_m);
  /// A non-finite reading is rejected: the last velocity is returned and counted.
  double step(double position_m);
  std::uint64_t rejected_inputs() const { return rejected_inputs_; }

 private:
  double period_s_;
  double last_position_m_ = 0;
  double last_velocity_mps_ = 0;
  std::uint64_t rejected_inputs_ = 0;
};

}  // namespace pmlsm

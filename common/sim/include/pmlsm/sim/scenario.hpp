// A test scenario of the closed loop: the raw velocity command, the initial
// condition and how long to run. configs/scenarios/*.yaml hold the paper's two.
#pragma once

#include <string>

namespace pmlsm {

enum class CommandShape { kZero, kStep, kPulse, kSine };

struct Scenario {
  std::string name;
  double duration_s = 0;
  CommandShape shape = CommandShape::kZero;
  double amplitude_mps = 0;   ///< step height, pulse height, sine amplitude
  double frequency_hz = 0;    ///< pulse and sine frequency
  double duty_cycle = 0.5;    ///< pulse: fraction of each period at amplitude_mps
  double initial_load_displacement_m = 0;  ///< x_L - x_M at t = 0 (spring stretched, Fig. 10)
  double cost_window_s = 0;   ///< window of the cost (23): the first second in the paper
  double settling_band = 0;   ///< settling tolerance as a fraction (0.02: 2 %)

  /// @throws std::invalid_argument naming the first invalid field.
  void validate(double control_period_s) const;
  /// Raw command c(t) before the reference model.
  double command_mps(double time_s) const;
  /// True when the command jumps (step, pulse): the settling metric then works per constant segment.
  bool has_edges() const { return shape == CommandShape::kStep || shape == CommandShape::kPulse; }
};

const char* to_string(CommandShape shape);
/// @throws std::invalid_argument on an unknown name, listing the known ones.
CommandShape command_shape_from_string(const std::string& name);

}  // namespace pmlsm

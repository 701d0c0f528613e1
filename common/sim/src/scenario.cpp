#include "pmlsm/sim/scenario.hpp"

#include <cmath>
#include <stdexcept>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

const char* to_string(CommandShape shape) {
  switch (shape) {
    case CommandShape::kZero: return "zero";
    case CommandShape::kStep: return "step";
    case CommandShape::kPulse: return "pulse";
    case CommandShape::kSine: return "sine";
  }
  return "?";
}

CommandShape command_shape_from_string(const std::string& name) {
  for (CommandShape s : {CommandShape::kZero, CommandShape::kStep, CommandShape::kPulse,
                         CommandShape::kSine}) {
    if (name == to_string(s)) return s;
  }
  throw std::invalid_argument("must be one of zero, step, pulse, sine, got '" + name + "'");
}

void Scenario::validate(double control_period_s) const {
  require_in_range("duration_s", duration_s, control_period_s, 3600.0);
  require_in_range("command.amplitude_mps", amplitude_mps, -10.0, 10.0);
  if (shape == CommandShape::kPulse || shape == CommandShape::kSine) {
    require_in_range("command.frequency_hz", frequency_hz, 1e-3, 0.5 / control_period_s);
  } else {
    require_non_negative("command.frequency_hz", frequency_hz);
  }
  require_in_range("command.duty_cycle", duty_cycle, 0.0, 1.0);
  require_in_range("initial_load_displacement_m", initial_load_displacement_m, -0.1, 0.1);
  require_in_range("cost_window_s", cost_window_s, control_period_s, duration_s);
  require_in_range("settling_band", settling_band, 1e-6, 0.5);
}

double Scenario::command_mps(double t) const {
  constexpr double kTwoPi = 6.28318530717958647692;
  switch (shape) {
    case CommandShape::kZero: return 0.0;
    case CommandShape::kStep: return amplitude_mps;
    case CommandShape::kPulse: {
      const double phase = t * frequency_hz - std::floor(t * frequency_hz);
      return phase < duty_cycle ? amplitude_mps : 0.0;
    }
    case CommandShape::kSine: return amplitude_mps * std::sin(kTwoPi * frequency_hz * t);
  }
  return 0.0;
}

}  // namespace pmlsm

// A test scenario of the closed loop: the raw velocity command, the initial
// condition and how long to run. configs/scenarios/*.yaml hold the paper's two
// (free vibration, pulse) and the references a rig needs: ramps, trapezoidal and
// jerk-limited (S-curve) moves, chirps, multi-sines, profiles from a CSV file, and
// setpoints from outside (external: the controller node follows VelocitySetpoint).
#pragma once

#include <string>
#include <vector>

#include "pmlsm/control/input_shaper.hpp"

namespace pmlsm {

/// The largest |command| any scenario may ask for (a typo guard, far above this motor).
inline constexpr double kMaxCommandSpeedMps = 10.0;

enum class CommandShape {
  kZero,
  kStep,
  kPulse,
  kSine,
  kRamp,
  kTrapezoid,
  kSCurve,
  kChirp,
  kMultiSine,
  kCsv,
  kExternal
};

/// One term of a multi-sine: amplitude * sin(2 pi frequency t + phase).
struct SineComponent {
  double amplitude_mps = 0;
  double frequency_hz = 0;
  double phase_rad = 0;
};

/// One row of a velocity profile (CSV: time_s, velocity_mps).
struct ProfilePoint {
  double time_s = 0;
  double velocity_mps = 0;
};

struct Scenario {
  std::string name;
  double duration_s = 0;
  CommandShape shape = CommandShape::kZero;
  double amplitude_mps = 0;  ///< step height, pulse height, sine/chirp amplitude, move velocity
  double frequency_hz = 0;   ///< pulse and sine frequency; the chirp's start frequency
  double duty_cycle = 0.5;   ///< pulse: fraction of each period at amplitude_mps
  /// ramp, trapezoid, s_curve: time at zero before the move starts.
  double start_s = 0;
  /// ramp: its slope; trapezoid, s_curve: the acceleration limit of the move.
  double accel_mps2 = 0;
  /// s_curve: the jerk limit.
  double jerk_mps3 = 0;
  /// trapezoid, s_curve: time at amplitude_mps between the rise and the fall.
  double hold_s = 0;
  /// chirp: the frequency reached at sweep_s (linear sweep from frequency_hz); after it
  /// the sine goes on at end_frequency_hz, phase-continuous.
  double end_frequency_hz = 0;
  double sweep_s = 0;
  /// multi_sine: the terms, summed.
  std::vector<SineComponent> components;
  /// csv: the profile (validated when loaded: see parse_velocity_profile), linearly
  /// interpolated; before the first row the first velocity, after the last row the last.
  std::vector<ProfilePoint> profile;
  std::string profile_file;  ///< where it came from (for messages)
  double max_gap_s = 0;      ///< csv: the largest time step allowed between rows
  /// external: the command comes from VelocitySetpoint samples (the controller node only;
  /// pmlsm/control/external_reference.hpp): a setpoint holds for timeout_s after it arrived,
  /// |setpoint| up to max_speed_mps, the command's rate limit is accel_mps2.
  double timeout_s = 0;
  double max_speed_mps = 0;
  /// false: V_ref is the command itself (a profiled reference is already smooth);
  /// true: the reference model (25) shapes it.
  bool use_reference_model = true;
  /// Input shaping of the command before the reference model (none: the paper's reference),
  /// timed to the velocity loop's mode (SystemParams::input_shaper_params).
  ShaperKind input_shaper = ShaperKind::kNone;
  double initial_load_displacement_m = 0;  ///< x_L - x_M at t = 0 (spring stretched, Fig. 10)
  double cost_window_s = 0;                ///< window of the cost (23): the first second in the paper
  double settling_band = 0;                ///< settling tolerance as a fraction (0.02: 2 %)

  /// @throws std::invalid_argument naming the first invalid field.
  void validate(double control_period_s) const;
  /// Raw command c(t) before the reference model. Allocation-free (the control loop calls it).
  /// 0 for external (the controller node takes it from the setpoints).
  double command_mps(double time_s) const;
  /// True for commands made of constant segments (step, pulse; the hold and rest phases of
  /// ramp, trapezoid, s_curve; flat stretches of a CSV profile): the settling metric then
  /// works per constant segment. Sines, chirps and multi-sines have none.
  bool has_constant_segments() const;
  /// The command's scale for the settling band: |amplitude|, the sum of the multi-sine's
  /// amplitudes, or the CSV profile's largest |velocity|.
  double command_scale_mps() const;
};

const char* to_string(CommandShape shape);
/// @throws std::invalid_argument on an unknown name, listing the known ones.
CommandShape command_shape_from_string(const std::string& name);

/// A jerk-limited change of velocity from 0 to delta_mps (either sign) with acceleration limit
/// accel_mps2 and jerk limit jerk_mps3 (infinity: a trapezoidal, acceleration-limited change):
/// the velocity tau seconds after it began (delta_mps from duration on).
struct VelocityTransition {
  double delta_mps = 0;
  double accel_mps2 = 0;
  double jerk_mps3 = 0;
  /// How long the change takes: |delta|/a + a/j when |delta| >= a^2/j, else 2 sqrt(|delta|/j).
  double duration_s() const;
  double velocity_mps(double tau_s) const;
};

/// Reads a velocity profile: a header line "time_s,velocity_mps", then one row per line of two
/// numbers. Rejects empty cells or lines (gaps), a missing or extra column, text, NaN and
/// infinities, a time that does not increase, a step in time above max_gap_s, negative times,
/// speeds beyond max_speed_mps, and fewer than two rows.
/// @throws std::invalid_argument "origin:LINE: what, got 'VALUE'".
std::vector<ProfilePoint> parse_velocity_profile(const std::string& text, const std::string& origin, double max_gap_s,
                                                 double max_speed_mps);

}  // namespace pmlsm

// Input shaping of the velocity command (Singer and Seering 1990; Singhose, Seering and Singer
// 1994; Singhose and Vaughan): the command is convolved with a few impulses timed to the load's
// mode, so that the vibrations their steps start cancel. Open loop: it cannot destabilise the
// velocity loop, and it costs a delay of half a period (ZV) or one period (ZVD, EI).
//
// For a mode of natural frequency w_n and damping zeta, w_d = w_n sqrt(1 - zeta^2),
// T_d = 2 pi / w_d and K = exp(-zeta pi / sqrt(1 - zeta^2)):
//   ZV   amplitudes [1, K] / (1 + K),            times [0, T_d/2]
//   ZVD  amplitudes [1, 2K, K^2] / (1 + K)^2,    times [0, T_d/2, T_d]
//   EI   amplitudes [(1+V)/4, (1-V)/2 K, (1+V)/4 K^2], normalised to sum 1, times [0, T_d/2, T_d]:
//        the residual vibration at w_n is V (the tolerance) instead of 0, which widens the band
//        of frequencies kept below V (the undamped EI with the damped mode's decay per half
//        period, as ZVD scales: exact for zeta = 0; with damping the vibration left on the mode
//        falls below V, 0.047 at zeta = 0.02 and 0.036 at 0.1, and the band stays 1.25-1.5x
//        ZVD's: InputShaper tests).
// The residual vibration of an impulse sequence for a mode (w, zeta), relative to one unit
// impulse: V = exp(-zeta w t_N) sqrt((sum A_i e^{zeta w t_i} cos(w_d t_i))^2 + (... sin ...)^2).
//
// Discrete time: an impulse at t = (n + f) T is split into (1 - f) at tick n and f at tick n + 1,
// which keeps its amplitude and its mean time, so the shaper is exact for a command that is
// linear over a period and still a finite impulse response with unit gain.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace pmlsm {

enum class ShaperKind { kNone, kZv, kZvd, kEi };

/// "none" | "zv" | "zvd" | "ei". @throws std::invalid_argument listing them.
ShaperKind shaper_kind_from_string(const std::string& text);
const char* to_string(ShaperKind kind);

struct InputShaperParams {
  ShaperKind kind = ShaperKind::kNone;
  double frequency_hz = 0;         ///< the mode's natural frequency f_n = w_n / (2 pi), > 0
  double damping_ratio = 0;        ///< zeta of the mode, [0, 0.5]
  double vibration_tolerance = 0;  ///< EI's V, (0, 0.25]
  double period_s = 0;             ///< the control period the shaper runs at
  /// @throws std::invalid_argument naming the first invalid value; also when the shaper's span
  /// (T_d or T_d / 2) exceeds 10 s, which no move of a linear motor waits for.
  void validate() const;
};

struct ShaperImpulse {
  double time_s = 0;
  double amplitude = 0;
};

/// The kind's impulses, times from 0, amplitudes summing to 1 (one impulse of 1 for kNone).
/// @throws std::invalid_argument as InputShaperParams::validate.
std::vector<ShaperImpulse> shaper_impulses(const InputShaperParams& params);

/// Residual vibration of `impulses` for a mode (frequency_hz, damping_ratio), relative to a
/// single unit impulse (formula above): 0 means none is left, 1 as much as unshaped.
double residual_vibration(const std::vector<ShaperImpulse>& impulses, double frequency_hz, double damping_ratio);

class InputShaper {
 public:
  /// @throws std::invalid_argument as InputShaperParams::validate.
  explicit InputShaper(const InputShaperParams& params);
  /// The shaped command of this tick: sum over taps j of w_j c_{k - j}. A non-finite command is
  /// rejected (the last accepted one is used) and counted. Allocation-free.
  double step(double command);
  /// Fills the history with `command`, as if it had been held forever (a start at speed).
  void reset(double command = 0.0);
  /// New impulses (the loop's mode moved with a live gain change), the commands of the last span
  /// kept: the next output is what the new shaper gives for the same past. Exact when the command
  /// was constant over the longer span (at rest, at speed); a command older than the old span is
  /// taken as the oldest one kept. Allocates: at a tick boundary, not in the tick.
  /// @throws std::invalid_argument as InputShaperParams::validate (the shaper unchanged).
  void retune(const InputShaperParams& params);
  const std::vector<double>& tap_weights() const { return taps_; }  ///< w_0, w_1, ... (sum 1)
  /// The delay the shaper adds to a move: its last impulse's time [s].
  double span_s() const { return span_s_; }
  std::uint64_t rejected_inputs() const { return rejected_inputs_; }

 private:
  std::vector<double> taps_;
  std::vector<double> history_;  ///< ring buffer of the last taps_.size() commands
  std::size_t newest_ = 0;
  double last_command_ = 0;
  double span_s_ = 0;
  std::uint64_t rejected_inputs_ = 0;
};

}  // namespace pmlsm

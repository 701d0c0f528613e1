// A guard in the compensation path: it watches the oscillation the compensator acts on, in the
// measured motor velocity (a signal the Kalman estimate cannot fool), and fades the compensation
// out before it hurts.
//
// It judges the motor's velocity error e = v_M - V_ref, high-passed (second order, corner f_c:
// the load's modes lie above it, tracking motion below), so what remains is the oscillatory part
// e~. The error, not v_M itself: a reference that moves at or above f_c (a 5 Hz sine) would
// otherwise look like a sustained oscillation. Over windows of window_s it takes the
// oscillation's size A = rms(e~) [m/s], and the reference's own high-passed size A_ref. A compensator that damps makes
// A fall window after window once an edge or a disturbance has excited the load; one that sustains a limit cycle keeps
// A up, one that destabilises makes it grow. The guard trips when, with A above the floor min_oscillation_mps,
// windows_to_trip windows in a row
//   - grew by more than growth_ratio each (kGrowing), or
//   - did not fall by at least min_decay each, A_k > (1 - min_decay) A_{k-1} (kSustained).
// A window counts only when some compensation acted in it (its high-passed force not all zero):
// PI alone is not the guard's to judge; and only when the reference does not explain it,
// A > max_reference_share A_ref: a loop tracking a fast reference has a steady error at the
// reference's frequency that is its bandwidth's, not a limit cycle (a limit cycle needs no
// reference; one riding on a moving reference still makes A outgrow the tracking error).
// The share compares not A but what the reference leaves of it,
//   U = rms(e~ - b0 r~(t) - b1 r~(t - kQuadratureLag_s)),  (b0, b1) the window's least squares:
// the error less what a gain and a phase of the high-passed reference r~ explain (two lagged copies
// of a narrow-band signal span its sine and cosine). Above the load mode a loop that makes the load
// follow moves the motor more than the reference (x_M = x_L (1 - w^2 / w_L^2)), and a frequency
// sweep through there makes that forced error outgrow the reference window after window: it is no
// limit cycle, and U stays small; a reference at rest leaves U = A. Growth and decay are A's.
// A window in which the compensator sat at its own limit for more than max_saturated_share of
// its ticks is not judged for a sustained oscillation: a saturated compensator forces the motor
// at a constant amplitude while it damps the load (the free vibration's first 0.4 s on a light
// load), so the motor cannot show the decay; growth still is. At its limit means an output share
// |F_c| / F_c,max of at least saturated_output_share, as the compensator reports it: a clamped law
// reaches 1, the RNN's tanh output u_n only comes near it (at |u_n| = 0.9 its slope is a fifth of
// the linear one, and the output barely answers its input).
// Tripped, the compensation's scale ramps from 1 to 0 over fade_s and stays 0 (latched) until
// reset(). step() never throws and does not allocate; a non-finite input is counted and the
// last finite one used instead.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

/// Its values come from the system file (compensator.guard; the period from timing), the one
/// place they live: none has a default of its own here.
struct VibrationGuardParams {
  double control_period_s = 0;
  double highpass_hz = 0;             ///< f_c of the high-pass, > 0, below the Nyquist frequency
  double window_s = 0;                ///< the evaluation window, at least 2 periods
  double min_oscillation_mps = 0;     ///< A below this is no oscillation to guard against
  double growth_ratio = 0;            ///< A(window) / A(previous) above this is growth, > 1
  double min_decay = 0;               ///< a damped oscillation loses at least this share a window, (0, 1)
  std::uint32_t windows_to_trip = 0;  ///< >= 1
  double max_reference_share = 0;     ///< a window with A <= this x A_ref is the reference's, > 0
  double saturated_output_share = 0;  ///< |F_c| / F_c,max at or above this: at the limit, (0, 1]
  double max_saturated_share = 0;     ///< above this share of a window at the limit: not judged sustained, (0, 1]
  double fade_s = 0;                  ///< >= 0 (0: off at once)
  void validate() const;
  /// Its own entries under `at` ("compensator.guard"); the period comes from the system.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v) {
    v.real(at + ".highpass_hz", p.highpass_hz,
           {0.01, 1e4, "the corner between tracking motion and vibration: 10 mHz to 10 kHz"});
    v.real(at + ".window_s", p.window_s, {1e-3, 100.0, "1 ms to 100 s of evaluation window"});
    v.real(at + ".min_oscillation_mps", p.min_oscillation_mps,
           {1e-6, 10.0, "1 um/s to 10 m/s: below it there is no oscillation worth guarding against"});
    v.real(at + ".growth_ratio", p.growth_ratio, {1.0001, 100.0, "more than 1: a growth"});
    v.real(at + ".min_decay", p.min_decay,
           {1e-3, 0.999, "a share of the amplitude lost per window: between none and all"});
    v.integer(at + ".windows_to_trip", p.windows_to_trip,
              {1.0, 1000.0, "a count of windows in a row: a whole number, 1 to 1000"});
    v.real(at + ".fade_s", p.fade_s, {0.0, 10.0, "0 (at once) to 10 s"});
    v.real(at + ".max_reference_share", p.max_reference_share,
           {1e-3, 1e3, "the error oscillation over the reference's own: a thousandth to a thousand times"});
    v.real(at + ".max_saturated_share", p.max_saturated_share,
           {1e-3, 1.0,
            "a share of a window's ticks: above it a window at the compensation's limit is not judged sustained"});
    v.real(
        at + ".saturated_output_share", p.saturated_output_share,
        {1e-3, 1.0, "a share of the compensator's own output range: at or above it the compensator is at its limit"});
  }
};

enum class VibrationGuardTrip : std::uint8_t { kNone, kSustained, kGrowing };
const char* to_string(VibrationGuardTrip trip) noexcept;

struct VibrationGuardInput {
  double motor_velocity_mps = 0;         ///< measured v_M(k)
  double reference_velocity_mps = 0;     ///< V_ref(k), what the velocity loop follows
  double compensation_force_n = 0;       ///< the compensation applied (after the previous scale)
  double compensation_output_share = 0;  ///< the compensator's |F_c| / F_c,max, [0, 1] (|u_n| for the RNN)
};

struct VibrationGuardOutput {
  double scale = 1.0;    ///< multiply the compensation force by this (1 -> 0 after a trip)
  bool tripped = false;  ///< latched
  VibrationGuardTrip reason = VibrationGuardTrip::kNone;
};

struct VibrationGuardCounters {
  std::uint64_t steps = 0;
  std::uint64_t rejected_inputs = 0;
  std::uint64_t windows = 0;
  std::uint64_t trip_tick = 0;    ///< the step at which it tripped (when tripped)
  double last_amplitude_mps = 0;  ///< A of the last window
  double last_unforced_mps = 0;   ///< U of the last window (A less the reference's own part)
  double last_reference_mps = 0;  ///< A_ref of the last window
  double last_force_rms_n = 0;    ///< rms of the high-passed compensation force of the last window
};

/// The lag of the reference's second copy in U's fit (see above): a quarter period at 50 Hz, so
/// the copies stay apart for any reference from a fraction of a hertz to well above the load modes.
inline constexpr double kQuadratureLag_s = 5e-3;

class VibrationGuard {
 public:
  /// @throws std::invalid_argument naming the invalid parameter.
  explicit VibrationGuard(const VibrationGuardParams& params);

  /// One control period.
  VibrationGuardOutput step(const VibrationGuardInput& in) noexcept;
  /// Back to scale 1, nothing latched (an operator's decision, after the plant was looked at).
  void reset() noexcept;

  const VibrationGuardOutput& output() const noexcept { return out_; }
  const VibrationGuardCounters& counters() const noexcept { return counters_; }
  const VibrationGuardParams& params() const noexcept { return params_; }

 private:
  double unforced_amplitude_mps(double n) const noexcept;  ///< U of the window of n steps
  VibrationGuardParams params_;
  double alpha_;  // high-pass coefficient
  std::uint32_t window_steps_;
  std::uint32_t fade_steps_;
  /// Two first-order high-pass sections in series (one signal).
  struct HighPass {
    double x_prev = 0, y1 = 0, y2 = 0;
    double step(double x, double alpha) noexcept;
  };
  HighPass error_hp_, reference_hp_, force_hp_;
  double e_prev_ = 0, r_prev_ = 0, f_prev_ = 0;
  bool primed_ = false;
  std::uint32_t in_window_ = 0;
  double sum_e2_ = 0, sum_r2_ = 0, sum_f2_ = 0;
  /// r~ of the last kQuadratureLag_s (a ring of lag_steps_ entries; a control period under
  /// 0.08 ms shortens the lag to kMaxLagSteps) and the fit's sums over the window: r~ r~,
  /// r~ r~_lag, r~_lag r~_lag, e~ r~, e~ r~_lag.
  static constexpr std::size_t kMaxLagSteps = 64;
  std::array<double, kMaxLagSteps> reference_lagged_{};
  std::size_t lag_steps_;
  std::size_t lag_at_ = 0;
  double sum_rr_ = 0, sum_rl_ = 0, sum_ll_ = 0, sum_er_ = 0, sum_el_ = 0;
  std::uint32_t saturated_in_window_ = 0;
  double previous_amplitude_ = 0;
  std::uint32_t sustained_run_ = 0, growing_run_ = 0;
  std::uint32_t faded_ = 0;
  VibrationGuardOutput out_;
  VibrationGuardCounters counters_;
};

}  // namespace pmlsm

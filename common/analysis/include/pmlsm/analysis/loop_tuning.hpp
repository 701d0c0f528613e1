// Stability margins of the velocity loop read from its measured open loop, and the PI gains
// tuned to requested margins (as a drive's auto-tuner does from its Bode plot).
//
// The measurement gives L = C G at each line (L = 1/S - 1, S = F/R: the loop as it runs, with
// the sampling, the current loop and every delay in it). Scaling both PI gains by s keeps the
// PI's zero: C' = s C, so L' = s L at every line and the margins of any s follow from one
// measurement:
//   phase margin  180 deg + arg L'(f_c) at every gain crossover |L'(f_c)| = 1 (the smallest)
//   gain margin   -20 log10 |L'(f_p)| at every phase crossover arg L'(f_p) = -180 deg (the
//                 smallest): a crossing with |L'| > 1 counts (a negative margin: unstable) when
//                 the lines resolve it, not where a mode turns the phase between two lines
// with the phase unwrapped along the lines and both read between lines by interpolation in
// log frequency. A crossover outside the measured band cannot be read: a gain whose crossovers
// leave the band is not chosen.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pmlsm/control/biquad.hpp"
#include "pmlsm/control/position_loop.hpp"
#include "pmlsm/analysis/frequency_response.hpp"
#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

struct LoopMargins {
  bool gain_crossover_found = false;
  double phase_margin_deg = 0;  ///< the smallest over the gain crossovers
  double gain_crossover_hz = 0;
  bool phase_crossover_found = false;
  double gain_margin_db = 0;  ///< the smallest over the phase crossovers
  double phase_crossover_hz = 0;
};

/// The margins of s H L from the lines whose coherence is at least min_coherence, with H the
/// force command's filters (nullptr: none). The measurement runs without them, so a filter is
/// judged before it is ever in the loop.
LoopMargins loop_margins(const std::vector<FrequencyPoint>& points, double gain_scale, double min_coherence,
                         const FilterChain* filters = nullptr);

/// `pmlsm commission --tune`: both velocity PI gains scaled to the largest that keeps these
/// margins. The parameter section "commissioning.tuning" (analysis_params.hpp).
struct TuningTargets {
  /// (0, 90): the 45 deg of the drive vendors' tuners (Kollmorgen WorkBench, Beckhoff TE5960).
  double min_phase_margin_deg = 45.0;
  /// > 0: the 8 dB of Kollmorgen WorkBench's Performance Servo Tuner.
  double min_gain_margin_db = 8.0;
  /// The most the gains may move either way, > 1: fourfold, so the loop the tuner extrapolates
  /// stays near the one measured.
  double max_gain_scale = 4.0;
  /// Designed to the margins plus these, so that the loop measured again at the tuned gains (with
  /// its own noise) still meets them. On the family, the tuned loop measured again had phase
  /// margins within 1 deg of the tuner's prediction and gain margins 0.5 dB below to 0.3 dB above.
  double phase_allowance_deg = 2.0;  ///< [0, 30]
  double gain_allowance_db = 1.0;    ///< [0, 10]
  /// @throws std::invalid_argument naming the first invalid value.
  void validate() const;
  /// Its entries under `at` ("commissioning.tuning"). Self: this, const or not.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& t, Visitor& v) {
    v.real(at + ".min_phase_margin_deg", t.min_phase_margin_deg, {1.0, 89.0, "1 to 89 deg"});
    v.real(at + ".min_gain_margin_db", t.min_gain_margin_db, {0.1, 40.0, "0.1 to 40 dB"});
    v.real(at + ".max_gain_scale", t.max_gain_scale,
           {1.01, 100.0, "the gains may move by 1 % to a hundredfold either way"});
    v.real(at + ".phase_allowance_deg", t.phase_allowance_deg, {0.0, 30.0, "0 to 30 deg"});
    v.real(at + ".gain_allowance_db", t.gain_allowance_db, {0.0, 10.0, "0 to 10 dB"});
  }
};

struct TunedGains {
  double gain_scale = 0;  ///< s: both PI gains times s
  double kp_n_s_per_m = 0;
  double ki_n_per_m = 0;
  LoopMargins before;  ///< at the measured gains (s = 1)
  LoopMargins after;   ///< at the tuned ones
};

/// The largest s in [1 / max_gain_scale, max_gain_scale] (on a grid of 1 % steps) whose margins
/// both meet the targets plus their allowances with both crossovers inside the measured band.
/// @returns nothing when no such s exists; `why` then says what limited it.
std::optional<TunedGains> tune_velocity_pi(const std::vector<FrequencyPoint>& points, double kp_n_s_per_m,
                                           double ki_n_per_m, const TuningTargets& targets, double min_coherence,
                                           std::string& why, const FilterChain* filters = nullptr);

/// The position loop's open loop (pmlsm/control/position_loop.hpp) per line at K_x = 1 s^-1, from
/// the same measurement: the velocity loop's closed loop at its gains scaled by `velocity_gain_scale`
/// with the force command's filters H, T' = s H L / (1 + s H L), times (closing on the load) the
/// load's velocity over the motor's Q, times the tick's sum from velocity to position,
/// T_s / (1 - e^(-j w T_s)):
///   L_x = T' Q T_s / (1 - e^(-j w T_s)).
/// Q (1 - S) is the load's velocity over the velocity loop's reference as line sums, well defined
/// where the motor stands still and Q alone is not. As points whose open_loop() is L_x (their
/// sensitivity 1 / (1 + L_x)) for loop_margins, each line's coherence the smaller of the motor's and
/// the load's; the load's lines matched to the motor's by frequency. closes_on none: none.
std::vector<FrequencyPoint> position_loop_points(const std::vector<FrequencyPoint>& points,
                                                 const std::vector<LoadRatioPoint>& load_points,
                                                 PositionFeedback closes_on, double period_s,
                                                 double velocity_gain_scale = 1.0,
                                                 const FilterChain* filters = nullptr);

/// The position loop's margins at `gain_per_s` from position_loop_points(). Below the measured
/// band T' and Q are 1 and the loop is the integrator K_x / (j w), its phase there above the lowest
/// line's: a gain crossover below the band is taken at K_x / 2 pi with the lowest line's phase
/// margin, a bound the true one exceeds.
LoopMargins position_loop_margins(const std::vector<FrequencyPoint>& position_points, double gain_per_s,
                                  double min_coherence);

/// The largest K_x on a grid of 1 % steps from 1000 s^-1 down to 0.01 s^-1 whose margins meet the
/// targets plus their allowances; nullopt and why when none does.
std::optional<std::pair<double, LoopMargins>> tune_position_gain(const std::vector<FrequencyPoint>& position_points,
                                                                 const TuningTargets& targets, double min_coherence,
                                                                 std::string& why);

/// A compensator's gain tried at one factor of its configured value: whether it passed the
/// verdict (clean and cheaper than PI alone) on every scenario, and its mean cost over PI alone's.
struct GainTrial {
  double factor = 0;
  bool passes = false;
  double mean_cost_ratio = 0;
};

/// The factor a compensator's gain is commissioned at, and whether it has a step to spare.
struct GainChoice {
  double factor = 0;
  bool step_to_spare = false;
};

/// Of the trials (factors ascending) that pass with the next one up passing too (a gain margin of
/// one step: a gain just short of where the compensation fights the loop is not preferred; the
/// largest factor is only that step), the lowest mean cost ratio; when none has a step to spare,
/// the lowest of those that pass (a verified gain on a narrow margin, said so); nullopt when none
/// passes.
/// @throws std::invalid_argument when the factors are not positive and ascending.
std::optional<GainChoice> choose_gain_factor(const std::vector<GainTrial>& trials);

}  // namespace pmlsm

// A robustness sweep: a family of plants (a grid over parameter ranges, its centre and a seeded
// random sample) x compensators x scenarios, each run in process, judged from its trace. The
// compensators' models stay as configured (nominal): only the plant moves, as on a rig whose
// load, coupling or bearings differ from what the estimator and the compensators assume. Or,
// with identify_models, each plant is first commissioned as a rig would be: PI alone runs the
// identification scenario, the load is fitted to what the drive measured (identification.hpp),
// and every run on that plant uses the identified models.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/analysis/compensated_run.hpp"
#include "pmlsm/analysis/identification.hpp"
#include "pmlsm/sim/scenario.hpp"
#include "pmlsm/sim/system_params.hpp"

namespace pmlsm {

/// One plant parameter of the family: a real entry of visit_parameters, between min and max.
struct SweepRange {
  std::string key_path;  ///< e.g. plant.mechanics.load_mass_kg (must start with "plant.")
  double min = 0;
  double max = 0;
  /// @throws std::invalid_argument: not a real plant parameter, min not below max, or a bound
  /// outside the parameter's plausible range.
  void validate(const SystemParams& nominal) const;
};

/// How the family is sampled.
struct PlantSampling {
  std::uint64_t grid_points = 2;  ///< per parameter, evenly spaced from min to max (2: the corners); 0: no grid
  bool centre = true;             ///< the centre of the box as well
  std::uint64_t random = 0;       ///< plants drawn uniformly in the box
  std::uint64_t seed = 1;         ///< of the random draw
};

/// What makes a run fail its verdict (besides a non-finite state and the guard tripping).
struct VerdictParams {
  /// The tail judged for a limit cycle and saturation: the last tail_s of the run.
  double tail_s = 0;
  /// The tail in this many windows: the decay rate is the least-squares slope of the log of
  /// their RMS values (one window of a mode's period or more each, or the RMS ripples).
  std::uint64_t tail_windows = 0;
  /// A spring-stretch oscillation (x_L - x_M, mean removed) of at least this amplitude in the
  /// tail whose amplitude decays slower than min_decay_rate_per_s is a limit cycle.
  double limit_cycle_amplitude_m = 0;
  double min_decay_rate_per_s = 0;
  /// More than this share of the tail's ticks with the force command at its limit: saturated.
  double max_saturated_tail_share = 0;
  /// A free vibration (a scenario that starts from a load displacement) whose spring stretch is
  /// not inside the scenario's settling band for good after this long is slow. Other scenarios'
  /// settling is the velocity PI's (its tiny K_i leaves friction's error near the band) and is
  /// shown, not judged.
  double max_free_vibration_settling_s = 0;
  /// A tail is at rest when the command (into the reference model) stays within this band of
  /// zero over it: judged for a limit cycle on its own. A moving tail (a sine, a chirp, a ramp's
  /// cruise) holds the reference's own forced response: judged against PI alone's.
  double rest_command_band_mps = 0;
  /// A run ends in a standstill when its command has rested (as above) this long up to its end:
  /// judged for hunting and chatter (a free vibration, a move and a second after it; the pulse's
  /// 0.5 s after its last edge is the edge's settling, not a standstill).
  double min_rest_s = 0;
  /// A standstill whose spring stretch, in the tail's last window, reaches this far from its
  /// mean (peak) hunts: "residual".
  double max_rest_stretch_peak_m = 0;
  /// A standstill whose compensation force has a larger RMS in the tail's last window chatters:
  /// "chatter".
  double max_rest_compensation_rms_n = 0;
  /// A moving tail is a limit cycle only when its spring-stretch amplitude exceeds
  /// limit_cycle_amplitude_m, this multiple of PI alone's on the same plant and reference, and
  /// does not decay (judge_against_pi_alone): the reference's forced response is not one.
  double max_forced_ratio_to_pi = 0;
  void validate() const;
};

struct SweepSpec {
  std::vector<SweepRange> ranges;
  PlantSampling sampling;
  std::vector<CompensatorKind> compensators;  ///< kNone (PI alone) is always run as the baseline
  std::vector<Scenario> scenarios;
  VerdictParams verdict;
  /// Commission every plant first (identify_load on identification_scenario, PI alone) and run it
  /// with the identified models; false: the configured models on every plant.
  bool identify_models = false;
  Scenario identification_scenario;
  IdentificationParams identification;
  /// @throws std::invalid_argument naming the first invalid field (the key path of a range
  /// that is no real plant parameter, inverted bounds, a bound outside its plausible range).
  void validate(const SystemParams& nominal) const;
};

/// One plant of the family: its label ("corner 3", "centre", "random 17") and a value per range.
struct PlantSample {
  std::string label;
  std::vector<double> values;
};

/// The family, in a fixed order: grid (row-major, first parameter slowest), centre, random.
std::vector<PlantSample> sample_plants(const SweepSpec& spec);

/// nominal with the sample's values set (the estimator's and compensators' models untouched).
/// @throws std::invalid_argument when a value is out of its plausible range.
SystemParams plant_variant(const SystemParams& nominal, const SweepSpec& spec, const PlantSample& plant);

/// What one run did.
struct RunVerdict {
  double cost = std::numeric_limits<double>::quiet_NaN();  ///< eq. (23), true v_L, first cost window
  double settling_s = std::numeric_limits<double>::infinity();
  double last_to_first_window_cost = std::numeric_limits<double>::quiet_NaN();  ///< cost per window: trend
  double tail_stretch_amplitude_m = 0;  ///< sqrt(2) x RMS of x_L - x_M (mean removed) over the tail
  double tail_decay_rate_per_s = 0;     ///< -d ln(RMS of a window) / dt over the tail's windows; < 0: growing
  /// A moving tail's stretch less its forced response (the part a linear filter of V_ref explains,
  /// unforced_stretch): sqrt(2) x its RMS, and its decay rate as above. At rest: the stretch's own.
  double tail_unforced_amplitude_m = 0;
  double tail_unforced_decay_rate_per_s = 0;
  double saturated_share = 0;  ///< of all ticks, force command at its limit
  double saturated_tail_share = 0;
  /// Chatter over the tail, measured, not yet judged: RMS of the force command about its mean
  /// (the drive's own hunting as well as a compensator's) and RMS of the compensation force.
  double tail_force_rms_n = 0;
  double tail_compensation_rms_n = 0;
  double guard_trip_s = -1;  ///< time the vibration guard tripped, -1: never
  /// The command within rest_command_band_mps of zero over the whole tail.
  bool rest_tail = false;
  /// ... and for min_rest_s up to the end: judged for residual and chatter.
  bool standstill = false;
  /// Peak |x_L - x_M - mean| over the tail's last window (tail_s / tail_windows).
  double rest_stretch_peak_m = 0;
  /// RMS of the compensation force over the tail's last window.
  double rest_compensation_rms_n = 0;
  /// Where the load ended against where it was sent: x_ref at the last tick (T sum of V_ref before
  /// it, the controller's) less the load's travel from the first tick (measured, not judged; the
  /// position loop's, position_loop.hpp, to close).
  double end_position_error_m = 0;
  bool non_finite = false;  ///< the plant diverged or a non-finite number in the trace
  /// The load's sensor failed during the run (the filter went on with the motor's side alone).
  bool sensor_failed = false;
  /// Tail at rest: the stretch at least limit_cycle_amplitude_m and not decaying. Moving tail:
  /// set by judge_against_pi_alone only.
  bool limit_cycle = false;
  bool saturated = false;
  bool slow = false;      ///< a free vibration settled later than the verdict allows
  bool residual = false;  ///< standstill: rest_stretch_peak_m over max_rest_stretch_peak_m
  bool chatter = false;   ///< standstill: rest_compensation_rms_n over max_rest_compensation_rms_n
  /// "" when the run is clean; else its faults: "non-finite", "sensor", "limit cycle", "saturated",
  /// "guard", "slow", "residual", "chatter".
  std::string faults() const;
};

/// Judges a trace on its own (pure: tests feed it synthetic ones). A moving tail's limit cycle
/// needs PI alone's run on the same plant and reference: judge_against_pi_alone.
RunVerdict judge_run(const std::vector<TickRecord>& trace, const Scenario& scenario, double control_period_s,
                     double force_limit_n, const VerdictParams& verdict);

/// A run of `scenario` on `params` with `compensator`, judged on its own (judge_run with the
/// system's control period and force limit).
RunVerdict judged_run(const SystemParams& params, const Scenario& scenario, const CompensatorSetup& compensator,
                      const VerdictParams& verdict);

/// The tail's spring stretch with its forced response taken out: the least-squares fit of
/// x_L - x_M over [begin, end) by a constant and a linear filter of V_ref (kForcedResponseTaps taps
/// kForcedResponseTapSpacing_s apart, the taps reaching back before `begin`), subtracted. Such a
/// filter reproduces any linear loop's steady response to a reference of up to four frequencies
/// (a sine, a multi-sine, the narrow band a chirp crosses in a tail); what is left is motion at
/// frequencies the reference does not hold: a limit cycle, or a start transient still ringing.
std::vector<double> unforced_stretch(const std::vector<TickRecord>& trace, std::size_t begin, std::size_t end,
                                     double control_period_s);
inline constexpr int kForcedResponseTaps = 8;
inline constexpr double kForcedResponseTapSpacing_s = 0.01;

/// A moving tail (a continuous reference) against PI alone's on the same plant and reference: a
/// limit cycle when its unforced stretch (unforced_stretch: the reference's own frequencies taken
/// out) has an amplitude of at least limit_cycle_amplitude_m and more than max_forced_ratio_to_pi
/// times PI alone's, and does not decay. Tails at rest keep judge_run's.
void judge_against_pi_alone(RunVerdict& run, const RunVerdict& pi_alone, const VerdictParams& verdict);

struct SweepRun {
  std::size_t plant = 0;        ///< index into the samples
  std::size_t compensator = 0;  ///< index into SweepResult::compensators
  std::size_t scenario = 0;     ///< index into spec.scenarios
  RunVerdict verdict;
  /// cost / PI alone's cost on the same plant and scenario (1 for PI itself).
  double cost_ratio_to_pi = std::numeric_limits<double>::quiet_NaN();
  /// Clean (faults() empty) and, for a compensator, cheaper than PI alone on this plant. PI
  /// alone's runs are the baseline: their verdicts are shown, and they pass by definition.
  bool passed = false;
};

struct SweepResult {
  std::vector<PlantSample> plants;
  std::vector<IdentifiedLoad> identified;     ///< per plant, with identify_models (else empty)
  std::vector<CompensatorKind> compensators;  ///< kNone first, then the spec's others
  std::vector<SweepRun> runs;                 ///< plant-major, then compensator, then scenario
  const SweepRun& run(std::size_t plant, std::size_t compensator, std::size_t scenario) const;
};

/// Progress: runs done, runs in all (called from the worker threads, one at a time).
using SweepProgress = std::function<void(std::size_t done, std::size_t total)>;

/// Runs the whole sweep on `threads` threads (0: one per core). rnn_weights for kRnn.
/// @throws std::invalid_argument from the spec or a plant variant.
SweepResult run_sweep(const SystemParams& nominal, const SweepSpec& spec, const std::vector<double>& rnn_weights,
                      unsigned threads, const SweepProgress& progress = {});

}  // namespace pmlsm

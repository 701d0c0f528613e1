// The commissioning's decisions, from a measured frequency response on: the force command's notches
// designed, the velocity loop judged and tuned to its margins, the values to write, the compensators'
// gains and state feedback's output filter tried, and the commissioned system verified as the sweep
// judges a plant; a family of plants commissioned one row each. Pure and DDS-free: the measurement
// on a live drive, the report's files and the system file written are `pmlsm commission`'s
// (tools/pmlsm/commission.cpp). What it decides is said into a Transcript as it goes, for the
// report.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "pmlsm/analysis/frequency_response.hpp"
#include "pmlsm/analysis/frequency_response_measurement.hpp"
#include "pmlsm/analysis/identification.hpp"
#include "pmlsm/analysis/loop_tuning.hpp"
#include "pmlsm/analysis/sweep.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/config/sweep_file.hpp"
#include "pmlsm/control/biquad.hpp"
#include "pmlsm/sim/scenario.hpp"
#include "pmlsm/sim/system_params.hpp"
#include "pmlsm/util/exit_codes.hpp"

namespace pmlsm {

/// What a commissioning says as it goes: kept for the report, and on stdout as it goes when
/// echoing (a family's plants are not: they print a row each).
struct Transcript {
  std::string text;
  bool echo = true;
};

/// printf into the transcript (and to stdout when echoing).
[[gnu::format(printf, 2, 3)]] void say(Transcript& transcript, const char* format, ...);

/// What a commissioning is asked to do, as `pmlsm commission` takes it.
struct CommissioningChoices {
  /// Measured on the simulated plant; else on a drive, and the verification then simulates the
  /// plant identified.
  bool simulate = false;
  bool tune = false;            ///< write the tuned velocity PI gains (and try the compensators' gains)
  bool design_filters = false;  ///< notches on the resonances that limit the loop, in free slots
  /// The sweep file whose scenarios, compensators, weights and verdict verify the commissioned
  /// system ("": no verification).
  std::string verify;
};

/// What the loop's margins allow: the tuned gains (nullopt when none meet the targets), and
/// whether the force command's filters are refused (they would leave less than the targets).
struct LoopVerdict {
  std::optional<TunedGains> tuned;
  bool filters_refused = false;
  std::string margins;  ///< as the loop will run: with the filters, at the gains it will run with
};

/// A verification's outcome: whether every compensator ran clean and cheaper than PI alone on
/// every scenario, how many runs did not, and the largest cost over PI alone's.
struct Verification {
  bool passed = true;
  std::size_t runs = 0;
  std::size_t failed_runs = 0;
  double worst_cost_ratio = 0;
};

inline constexpr const char* kVerificationColumns =
    "scenario,compensator,cost,cost_ratio_to_pi,faults,tail_force_rms_n,tail_compensation_rms_n";

/// The verification file, its RNN weights and PI alone's judged run of each of its scenarios on
/// the commissioned system: loaded and run once for the trials and the verification alike (PI
/// alone runs no compensator, so neither the output filter nor a compensator's gain changes it).
struct VerificationBasis {
  std::string path;
  SweepFile file;
  std::vector<double> weights;
  std::vector<RunVerdict> pi_alone;  ///< per scenario of the file
};

/// What the commissioning decided from a measured response.
struct CommissionDecision {
  int exit_code = kExitOk;
  FilterChainParams filters;  ///< the force command's, designed or configured
  LoopVerdict loop;
  std::vector<std::pair<std::string, double>> values;  ///< the numbers it writes
  std::vector<ConfigOverride> text_values;             ///< the filter slots, switches and gains it writes
  std::optional<SystemParams> commissioned;            ///< the system verified (unless refused before)
  std::optional<Verification> verification;
};

/// One plant of a family: the fit's errors against the plant (anti-resonance, resonance, load
/// mass, spring, motor mass, in per cent), the margins measured again at the tuned gains with the
/// force command's filters, and what the commissioning decided.
struct FamilyRow {
  double errors[5] = {0, 0, 0, 0, 0};
  /// With a load encoder: the load side's corner against the plant's sqrt(k / m_L) [%], and the
  /// sensor's gain against the motor's encoder; NaN without one.
  double load_side_error_percent = std::numeric_limits<double>::quiet_NaN();
  double load_sensor_gain = std::numeric_limits<double>::quiet_NaN();

  double tuned_kp_n_s_per_m = 0;
  LoopMargins tuned;  ///< measured at the tuned gains (not predicted)
  CommissionDecision decision;
};

/// Told of a measurement's progress before its first tick and once a simulated second after: the
/// measurement (its plan, its phase) and its tick.
using MeasurementProgress = std::function<void(const FrequencyResponseMeasurement& measurement, std::uint64_t tick)>;

/// The measurement on the simulated plant of `configured` (run_measurement).
FrequencyResponseMeasurement measure_on_simulated_plant(const SystemParams& configured,
                                                        const MeasurementProgress& progress = nullptr);

std::string describe(const LoopMargins& m);

/// The velocity loop's margins as measured, the gains tuned to the targets with the force
/// command's filters in the loop, and the filters judged at the gains the loop will run with
/// (the tuned ones with `tune`, else the configured ones), printed.
LoopVerdict judge_loop(const SystemParams& configured, const FrequencyResponseResult& result,
                       const FilterChain& filters, bool tune, Transcript& transcript);

/// Notches for the resonances over the two-mass model that limit the loop's gain, in the free
/// slots of the force command's chain (filter_design.hpp), printed; the slots placed go into
/// `values` as the system file's keys. Returns the chain the loop will run with.
FilterChainParams design_force_command_filters(const SystemParams& configured, const FrequencyResponseResult& result,
                                               std::vector<ConfigOverride>& values, Transcript& transcript);

/// The keys the commissioning writes: the two-mass model from the frequency response, the
/// bearing friction from the time-domain fit when there is one (a response at one velocity does
/// not separate it; a live drive's comes from `pmlsm identify` on a recording).
std::vector<std::pair<std::string, double>> commissioned_parameters(const TwoMassFit& fit,
                                                                    const std::optional<IdentifiedLoad>& time_domain);

/// The relative error of a measured value against the plant's, in per cent.
double error_percent(double measured, double truth);

/// A measurement on the simulated plant of `p`, evaluated; nullopt and why when it ended early or
/// its response was refused.
std::optional<FrequencyResponseResult> measured_response(const SystemParams& p, std::string& why);

VerificationBasis verification_basis(const std::string& sweep_path, const SystemParams& commissioned);

/// A compensator's run passes when it is clean and cheaper than PI alone's.
bool passes_against(const RunVerdict& v, const RunVerdict& pi_alone);

/// The commissioned system verified as the sweep judges a plant: every scenario of the sweep file
/// with PI alone and each compensator on the plant, the models and gains commissioned; a table,
/// a row per run into `csv` (kVerificationColumns, each led by `row_prefix`).
Verification verify_commissioned(const VerificationBasis& basis, const SystemParams& commissioned, std::ostream& csv,
                                 const std::string& row_prefix, Transcript& transcript);

/// The system the commissioning verifies: the configured one with the commissioned values and the
/// force command's filters; on a live drive, the simulated plant is the identified one (the
/// simulation of what was measured).
SystemParams commissioned_system(const SystemParams& configured,
                                 const std::vector<std::pair<std::string, double>>& values, const FilterChain& filters,
                                 const TwoMassFit& fit, bool simulate);

/// With --tune: state feedback's output filter (declared in the system file, off) tried on the
/// commissioned system, on the verification file's scenarios: on when with it state feedback
/// passes the verdict on every one and the mean of its costs over PI alone's is lower (its lag
/// helps only a model that fits the plant, which the commissioning has just measured). Printed;
/// the key goes into text_values and `commissioned` has it.
void tune_state_feedback_filter(const VerificationBasis& basis, SystemParams& commissioned,
                                std::vector<ConfigOverride>& text_values, Transcript& transcript);

/// With --tune: acceleration feedback's K_a and the RNN's output scale, each tried at
/// kGainTrialFactors times its configured value on the commissioned system, on the verification
/// file's scenarios, each run judged as the verification judges it (a drive vendor's tuner sets a
/// gain by measuring the loop at a few), and commissioned at choose_gain_factor's choice
/// (loop_tuning.hpp: the cheapest with a step to spare, else the cheapest that passes); none
/// passing leaves the configured gain. Printed; the keys go into text_values and `commissioned` has them.
void tune_compensator_gains(const VerificationBasis& basis, SystemParams& commissioned,
                            std::vector<ConfigOverride>& text_values, Transcript& transcript);

/// From a measured response on: the force command's filters (designed with --design-filters), the
/// loop judged and tuned, the commissioned system, state feedback's output filter and the
/// compensators' gains tried (--tune with a verification file) and the verification, its rows
/// into `verification_csv` led by `row_prefix`. Exit 6 in the decision when the filters are refused, --tune finds no
/// gains or the verification fails.
CommissionDecision decide(const CommissioningChoices& o, const SystemParams& configured,
                          const FrequencyResponseResult& result, const std::optional<IdentifiedLoad>& time_domain,
                          std::ostream& verification_csv, const std::string& row_prefix, Transcript& transcript);

/// The row of plant `p`, commissioned as `pmlsm commission --simulate` would with the same options;
/// nullopt and why when the measurement, the time-domain fit or the tuning failed.
std::optional<FamilyRow> family_row(const CommissioningChoices& o, const SystemParams& p,
                                    const Scenario& identification, std::ostream& verification_csv,
                                    const std::string& label, std::string& why);

/// Whether the loop measured again at the tuned gains meets the targets.
bool margins_met(const LoopMargins& m, const TuningTargets& targets);

}  // namespace pmlsm

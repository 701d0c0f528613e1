// The offline search of section 3.3: what differential evolution (or jDE,
// CMA-ES) minimises. One evaluation is a closed-loop run of the full nonlinear
// plant with the Jordan RNN as compensator (online learning off, so a weight
// set has one cost), scored by eq. (23)-(24):
//   F_Co = sum_{k=1}^{K} |V_ref(k) - V_load(k)|,  K = cost window / T (1000),
// summed over the training scenarios with their weights. Optionally each run goes on to the
// scenario's end and is judged as the robustness sweep judges it (pmlsm/analysis/sweep.hpp): a run
// with a limit cycle, a saturated tail, the vibration guard tripped, a slow free vibration or a
// non-finite state pays a penalty, so a weight set cannot buy a low cost in the window with a fault after it.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/analysis/identification.hpp"
#include "pmlsm/compensation/jordan_rnn.hpp"
#include "pmlsm/optim/de_params.hpp"
#include "pmlsm/sim/scenario.hpp"
#include "pmlsm/analysis/sweep.hpp"
#include "pmlsm/sim/system_params.hpp"

namespace pmlsm {

/// Which load velocity enters (23): the Kalman estimate (the paper: all a rig
/// measures) or the simulated truth (what the simulation can afford to use).
enum class CostVelocity { estimated, truth };
CostVelocity cost_velocity_from_string(const std::string& text);
const char* to_string(CostVelocity which);

struct TrainingScenario {
  Scenario scenario;
  std::string file;     ///< where it was read from (for remote workers and messages)
  double weight = 1.0;  ///< > 0
};

/// A plant the weights are scored on: the configured system with some plant parameters moved
/// (real entries of visit_parameters under plant.*; the estimator's and compensators' models stay).
struct PlantVariant {
  std::string name;
  std::vector<std::pair<std::string, double>> values;  ///< key path, value; empty: the configured plant
  double weight = 1.0;                                 ///< > 0
  /// The models a commissioning run identified on this plant (identified_parameters: the Kalman
  /// filter's and state feedback's), set after the moves; empty: the configured models.
  std::vector<std::pair<std::string, double>> models{};
  /// False: commissioned_plants leaves this plant on the configured models, as the main job runs
  /// the configured plant.
  bool commission = true;
};

/// How the costs over the plants make one number.
enum class PlantObjective {
  kWeightedSum,     ///< sum over plants of weight x (the scenarios' weighted cost sum)
  kWorstRatioToPi,  ///< max over plants of weight x sum over scenarios of weight x cost / PI alone's cost
};
PlantObjective plant_objective_from_string(const std::string& text);
const char* to_string(PlantObjective objective);

/// Each plant commissioned as a rig (and the sweep's `models: identified`) would be: PI alone
/// runs `identification` on it, identify_load fits its load, and the variant carries the
/// identified models. @throws std::invalid_argument naming the plant when a fit fails.
std::vector<PlantVariant> commissioned_plants(const SystemParams& params, std::vector<PlantVariant> plants,
                                              const Scenario& identification);

/// params with the variant's values set, then its models. @throws std::invalid_argument naming the variant and the
/// key (not a real plant parameter, or the value out of its plausible range).
SystemParams apply_plant_variant(const SystemParams& params, const PlantVariant& variant);

/// Where the search starts: every member drawn (the paper), or one member the network's
/// equivalent of the configured acceleration feedback (rnn_weights_from_acceleration_feedback),
/// the rest drawn. CMA-ES centres its first generation on the best initial member, DE keeps a
/// member until a better trial replaces it: either way the search ends no worse than that law.
enum class TrainingStart { kRandom, kAccelerationFeedback };
TrainingStart training_start_from_string(const std::string& text);
const char* to_string(TrainingStart start);

/// The weights with which the RNN applies, for small signals, the configured acceleration
/// feedback: G_n u_n = -K_a a with a the network's signal, u_n = -(K_a / (G_n s)) x_0
/// (JordanRnn::linear_chain_weights). Both compensators scale by the same gain schedule. The RNN's
/// output neuron saturates softly towards G_n where acceleration feedback clips at its limit.
/// @throws std::invalid_argument when the two read different signals (compensator.rnn.on_reference_error
/// differs from compensator.acceleration_feedback.on_reference_error) or the chain's weights
/// would exceed JordanRnn::kMaxAbsWeight.
std::vector<double> rnn_weights_from_acceleration_feedback(const SystemParams& params);

/// configs/training.yaml: the optimiser and what it is scored on.
struct TrainingParams {
  std::string optimiser;  ///< "de" (the paper), "jde", "cmaes"
  /// The search's own parameters (population_size, mutation_factor, crossover_rate, init_lower,
  /// init_upper, seed: top-level keys of the file), checked by DeParams::validate. Its dimension
  /// and first member are the network's, set when the search starts (make_de_params).
  DeParams search;
  TrainingStart start = TrainingStart::kRandom;
  std::uint64_t max_evaluations = 0;  ///< budget; the run stops at the first generation that reaches it
  double target_cost = 0;             ///< stop early at or below this cost (0: never)
  CostVelocity cost_velocity = CostVelocity::truth;
  std::vector<TrainingScenario> scenarios;
  std::vector<PlantVariant> plants;  ///< at least one (the configured plant: no values)
  PlantObjective plant_objective = PlantObjective::kWeightedSum;
  /// Judge every run whole (with worst_ratio_to_pi only): a faulted run's ratio counts
  /// RnnCost::kFaultPenalty more.
  bool judge_runs = false;
  VerdictParams verdict;  ///< when judge_runs
  /// Commission every plant first (commissioned_plants) and score the weights with the models
  /// identified there, as a rig runs them; false: the configured models on every plant.
  bool identify_models = false;
  std::string identification_scenario_file;
  Scenario identification_scenario;  ///< when identify_models
  void validate(double control_period_s) const;
};

/// The cost of a weight set: thread-safe (each call builds its own loop).
class RnnCost {
 public:
  /// On the configured plant alone (the paper's search).
  /// @throws std::invalid_argument when a parameter or scenario is invalid.
  RnnCost(const SystemParams& params, std::vector<TrainingScenario> scenarios, CostVelocity which);
  /// On each plant variant, the costs combined by objective (PI alone's costs, needed by
  /// kWorstRatioToPi, are computed here once).
  RnnCost(const SystemParams& params, std::vector<TrainingScenario> scenarios, CostVelocity which,
          const std::vector<PlantVariant>& plants, PlantObjective objective);
  /// The same, each run judged whole by `verdict` (the objective must be kWorstRatioToPi).
  RnnCost(const SystemParams& params, std::vector<TrainingScenario> scenarios, CostVelocity which,
          const std::vector<PlantVariant>& plants, PlantObjective objective, const VerdictParams& verdict);
  /// What a judged run that failed its verdict adds to its cost ratio: PI alone's whole cost
  /// again, so a faulted run never looks better than PI alone (ratio 1) on that plant.
  static constexpr double kFaultPenalty = 1.0;
  std::size_t dimension() const { return dimension_; }
  /// The objective over plants of the weighted sum of (23) over the scenarios; +inf for a
  /// wrong-size or non-finite set, or one under which a plant diverged.
  double operator()(const std::vector<double>& weights) const;
  /// Cost (23) of one trace with this object's choice of V_load.
  double scenario_cost(const std::vector<TickRecord>& trace, const Scenario& scenario) const;
  /// The ticks a cost needs: the window plus tick 0.
  std::uint64_t cost_ticks(const Scenario& scenario) const;

 private:
  struct Plant {
    std::string name;
    SystemParams params;
    double weight = 1.0;
    std::vector<double> pi_costs;  ///< per scenario, PI alone (kWorstRatioToPi)
    /// per scenario, PI alone's whole run judged (judged runs): a moving tail is judged against it
    std::vector<RunVerdict> pi_verdicts;
  };
  void judge_with(const VerdictParams& verdict);
  std::vector<Plant> plants_;
  bool judge_runs_ = false;
  VerdictParams verdict_;
  std::vector<TrainingScenario> scenarios_;
  CostVelocity which_;
  PlantObjective objective_ = PlantObjective::kWeightedSum;
  double control_period_s_ = 0;
  std::size_t dimension_ = 0;
};

/// A whole scenario with the RNN in the loop (one-tick delay, see run_compensated).
std::vector<TickRecord> run_with_rnn(const SystemParams& params, const Scenario& scenario,
                                     const std::vector<double>& weights, bool online_learning,
                                     std::uint64_t max_ticks = UINT64_MAX);

}  // namespace pmlsm

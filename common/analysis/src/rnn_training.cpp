#include "pmlsm/analysis/rnn_training.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

CostVelocity cost_velocity_from_string(const std::string& text) {
  if (text == "estimated") return CostVelocity::estimated;
  if (text == "truth") return CostVelocity::truth;
  throw std::invalid_argument("expected 'estimated' or 'truth', got '" + text + "'");
}

const char* to_string(CostVelocity which) { return which == CostVelocity::estimated ? "estimated" : "truth"; }

PlantObjective plant_objective_from_string(const std::string& text) {
  if (text == "weighted_sum") return PlantObjective::kWeightedSum;
  if (text == "worst_ratio_to_pi") return PlantObjective::kWorstRatioToPi;
  throw std::invalid_argument("expected 'weighted_sum' or 'worst_ratio_to_pi', got '" + text + "'");
}

const char* to_string(PlantObjective objective) {
  return objective == PlantObjective::kWeightedSum ? "weighted_sum" : "worst_ratio_to_pi";
}

TrainingStart training_start_from_string(const std::string& text) {
  if (text == "random") return TrainingStart::kRandom;
  if (text == "acceleration_feedback") return TrainingStart::kAccelerationFeedback;
  throw std::invalid_argument("expected 'random' or 'acceleration_feedback', got '" + text + "'");
}

const char* to_string(TrainingStart start) {
  return start == TrainingStart::kRandom ? "random" : "acceleration_feedback";
}

std::vector<double> rnn_weights_from_acceleration_feedback(const SystemParams& params) {
  const CompensatorTuning& c = params.compensator;
  if (c.rnn.on_reference_error != c.acceleration_feedback.on_reference_error) {
    throw std::invalid_argument(std::string("start acceleration_feedback: the network reads ") +
                                (c.rnn.on_reference_error ? "a_L - dV_ref/dt" : "a_L") +
                                " (compensator.rnn.on_reference_error) but "
                                "acceleration feedback acts on " +
                                (c.acceleration_feedback.on_reference_error ? "a_L - dV_ref/dt" : "a_L") +
                                " (compensator.acceleration_feedback.on_reference_error): set them alike");
  }
  // F = G_n u_n = -K_a a and x_0 = s a: u_n = -(K_a / (G_n s)) x_0.
  const double gain = -c.acceleration_feedback.gain_kg / (c.rnn.gain_n * c.rnn.input_scale_s2_per_m);
  try {
    return JordanRnn::linear_chain_weights(c.rnn.layer_sizes, gain);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("start acceleration_feedback: ") + e.what());
  }
}

std::vector<PlantVariant> commissioned_plants(const SystemParams& params, std::vector<PlantVariant> plants,
                                              const Scenario& identification) {
  for (PlantVariant& plant : plants) {
    if (!plant.commission) continue;
    PlantVariant moved = plant;
    moved.models.clear();
    const SystemParams on_plant = apply_plant_variant(params, moved);
    try {
      plant.models = identified_parameters(commission_load(on_plant, identification));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("plants '" + plant.name + "': identification: " + e.what());
    }
  }
  return plants;
}

SystemParams apply_plant_variant(const SystemParams& params, const PlantVariant& variant) {
  SystemParams out = params;
  for (const auto& [key, value] : variant.values) {
    if (key.rfind("plant.", 0) != 0) {
      throw std::invalid_argument("plants '" + variant.name + "': " + key +
                                  ": only the plant moves (plant.*): the models stay as configured");
    }
    try {
      real_parameter(out, key) = value;
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("plants '" + variant.name + "': " + e.what());
    }
  }
  // Only what commissioning identifies (one list: identified_parameters) may follow the plant.
  const auto identified_keys = identified_parameters(IdentifiedLoad{});
  for (const auto& [key, value] : variant.models) {
    const bool identified = std::any_of(identified_keys.begin(), identified_keys.end(),
                                        [&key = key](const auto& entry) { return entry.first == key; });
    if (!identified) {
      throw std::invalid_argument("plants '" + variant.name + "': models " + key +
                                  ": not a model commissioning identifies");
    }
    try {
      real_parameter(out, key) = value;
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("plants '" + variant.name + "': models " + e.what());
    }
  }
  try {
    out.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("plants '" + variant.name + "': " + e.what());
  }
  return out;
}

void TrainingParams::validate(double control_period_s) const {
  if (optimiser != "de" && optimiser != "jde" && optimiser != "cmaes") {
    throw std::invalid_argument("optimiser: expected de, jde or cmaes, got '" + optimiser + "'");
  }
  search.validate();
  // Initial weights inside what a weight set may hold (JordanRnn::kMaxAbsWeight).
  require_in_range("init_lower", search.init_lower, -JordanRnn::kMaxAbsWeight, JordanRnn::kMaxAbsWeight);
  require_in_range("init_upper", search.init_upper, -JordanRnn::kMaxAbsWeight, JordanRnn::kMaxAbsWeight);
  if (max_evaluations < search.population_size) {
    throw std::invalid_argument("max_evaluations: must be >= population_size, got " + std::to_string(max_evaluations));
  }
  // 1e9 closed-loop runs: over a month at the ~290 runs/s of the README's 52,000 in 3 minutes.
  if (max_evaluations > 1000000000) {
    throw std::invalid_argument("max_evaluations: must be <= 1000000000 (over a month of runs), got " +
                                std::to_string(max_evaluations));
  }
  require_in_range("target_cost", target_cost, 0.0, 1e9);
  if (scenarios.empty()) throw std::invalid_argument("scenarios: at least one is needed");
  for (std::size_t i = 0; i < scenarios.size(); ++i) {
    const std::string name = "scenarios[" + std::to_string(i) + "].weight";
    require_in_range(name.c_str(), scenarios[i].weight, 1e-6, 1e6);
    scenarios[i].scenario.validate(control_period_s);
  }
  if (plants.empty()) throw std::invalid_argument("plants: at least one (the configured plant: set [])");
  for (std::size_t i = 0; i < plants.size(); ++i) {
    const std::string name = "plants[" + std::to_string(i) + "].weight";
    require_in_range(name.c_str(), plants[i].weight, 1e-6, 1e6);
  }
  if (judge_runs) {
    if (plant_objective != PlantObjective::kWorstRatioToPi) {
      throw std::invalid_argument(
          "verdict: judged runs need plant_objective worst_ratio_to_pi (a penalty is a ratio "
          "to PI alone's cost), got " +
          std::string(to_string(plant_objective)));
    }
    verdict.validate();
  }
}

RnnCost::RnnCost(const SystemParams& params, std::vector<TrainingScenario> scenarios, CostVelocity which)
    : RnnCost(params, std::move(scenarios), which, {PlantVariant{"configured", {}, 1.0}},
              PlantObjective::kWeightedSum) {}

RnnCost::RnnCost(const SystemParams& params, std::vector<TrainingScenario> scenarios, CostVelocity which,
                 const std::vector<PlantVariant>& plants, PlantObjective objective)
    : scenarios_(std::move(scenarios)), which_(which), objective_(objective) {
  params.validate();
  control_period_s_ = params.timing.control_period_s;
  dimension_ = JordanRnn::parameter_count(params.compensator.rnn.layer_sizes);
  for (const TrainingScenario& s : scenarios_) {
    require_positive("weight", s.weight);
    s.scenario.validate(params.timing.control_period_s);
  }
  if (plants.empty()) throw std::invalid_argument("plants: at least one");
  for (const PlantVariant& variant : plants) {
    require_positive(("plants '" + variant.name + "' weight").c_str(), variant.weight);
    Plant plant{variant.name, apply_plant_variant(params, variant), variant.weight, {}, {}};
    if (objective_ == PlantObjective::kWorstRatioToPi) {
      for (const TrainingScenario& s : scenarios_) {
        const auto trace = run_compensated(
            plant.params, s.scenario, [](const CompensatorView&) { return Compensation{}; }, cost_ticks(s.scenario));
        const double pi_cost = scenario_cost(trace, s.scenario);
        if (!(pi_cost > 0) || !std::isfinite(pi_cost)) {
          throw std::invalid_argument("plants '" + variant.name + "': PI alone's cost on " + s.scenario.name + " is " +
                                      format_value(pi_cost) + ": no ratio to it");
        }
        plant.pi_costs.push_back(pi_cost);
      }
    }
    plants_.push_back(std::move(plant));
  }
}

RnnCost::RnnCost(const SystemParams& params, std::vector<TrainingScenario> scenarios, CostVelocity which,
                 const std::vector<PlantVariant>& plants, PlantObjective objective, const VerdictParams& verdict)
    : RnnCost(params, std::move(scenarios), which, plants, objective) {
  judge_with(verdict);
}

void RnnCost::judge_with(const VerdictParams& verdict) {
  if (objective_ != PlantObjective::kWorstRatioToPi) {
    throw std::invalid_argument("verdict: judged runs need the objective worst_ratio_to_pi");
  }
  verdict.validate();
  verdict_ = verdict;
  judge_runs_ = true;
  for (Plant& plant : plants_) {
    plant.pi_verdicts.clear();
    for (const TrainingScenario& s : scenarios_) {
      const auto trace = run_compensated(
          plant.params, s.scenario, [](const CompensatorView&) { return Compensation{}; }, UINT64_MAX);
      plant.pi_verdicts.push_back(
          judge_run(trace, s.scenario, control_period_s_, plant.params.velocity_loop.force_limit_n, verdict_));
    }
  }
}

std::uint64_t RnnCost::cost_ticks(const Scenario& scenario) const {
  return static_cast<std::uint64_t>(std::llround(scenario.cost_window_s / control_period_s_)) + 1;
}

double RnnCost::scenario_cost(const std::vector<TickRecord>& trace, const Scenario& scenario) const {
  const std::uint64_t window = cost_ticks(scenario) - 1;
  double cost = 0;
  for (std::uint64_t k = 1; k <= window && k < trace.size(); ++k) {
    const double v_load = which_ == CostVelocity::truth ? trace[k].load_velocity_mps : trace[k].est_load_velocity_mps;
    cost += std::abs(trace[k].v_ref_mps - v_load);
  }
  return cost;
}

double RnnCost::operator()(const std::vector<double>& weights) const {
  const double worst = std::numeric_limits<double>::infinity();
  if (weights.size() != dimension_) return worst;
  for (double w : weights) {
    if (!(std::fabs(w) <= JordanRnn::kMaxAbsWeight)) return worst;  // also NaN
  }
  double total = 0;
  for (const Plant& plant : plants_) {
    double plant_cost = 0;
    for (std::size_t i = 0; i < scenarios_.size(); ++i) {
      const TrainingScenario& s = scenarios_[i];
      const auto trace =
          run_with_rnn(plant.params, s.scenario, weights, false, judge_runs_ ? UINT64_MAX : cost_ticks(s.scenario));
      if (!trace.empty() && trace.back().plant_fault_state != nullptr) return worst;  // a diverged plant
      const double cost = scenario_cost(trace, s.scenario);
      if (objective_ != PlantObjective::kWorstRatioToPi) {
        plant_cost += s.weight * cost;
        continue;
      }
      double ratio = cost / plant.pi_costs[i];
      if (judge_runs_) {
        RunVerdict verdict =
            judge_run(trace, s.scenario, control_period_s_, plant.params.velocity_loop.force_limit_n, verdict_);
        judge_against_pi_alone(verdict, plant.pi_verdicts[i], verdict_);
        if (!verdict.faults().empty()) ratio += kFaultPenalty;
      }
      plant_cost += s.weight * ratio;
    }
    if (objective_ == PlantObjective::kWorstRatioToPi) {
      total = std::max(total, plant.weight * plant_cost);
    } else {
      total += plant.weight * plant_cost;
    }
  }
  return std::isfinite(total) ? total : worst;
}

std::vector<TickRecord> run_with_rnn(const SystemParams& params, const Scenario& scenario,
                                     const std::vector<double>& weights, bool online_learning,
                                     std::uint64_t max_ticks) {
  RnnCompensator rnn(params.rnn_compensator_params(online_learning));
  rnn.set_weights(weights);
  return run_compensated(
      params, scenario,
      [&rnn](const CompensatorView& view) {
        const CompensatorStep step = rnn.step(rnn_input(view));
        return compensation_from_output(step.force_n, step.u_n);
      },
      max_ticks);
}

}  // namespace pmlsm

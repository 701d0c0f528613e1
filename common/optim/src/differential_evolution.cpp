// DE/rand/1/bin (paper eqs. 21-22); see differential_evolution.hpp.
//
// DE checkpoint file (text, one item a line, doubles with 17 significant
// digits so that they read back exactly; "inf" for an infinite cost):
//
//   pmlsm-optimiser-checkpoint 1
//   optimiser DE/rand/1/bin
//   population_size <NP>
//   dimension <D>
//   mutation_factor <F_s>
//   crossover_rate <CR>
//   init_lower <x_lo>
//   init_upper <x_hi>
//   seed <seed>
//   generation <generations completed>
//   evaluations <cost evaluations so far>
//   initialised <0|1>                      (0: step() has not run, no members follow)
//   rng <std::mt19937_64 state, as its operator<< writes it>
//   member <i> <cost_i> <x_i,0> ... <x_i,D-1>   (NP lines, i = 0..NP-1, if initialised)
//   end
#include "pmlsm/optim/differential_evolution.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "pmlsm/optim/batch_evaluation.hpp"
#include "pmlsm/optim/checkpoint.hpp"

namespace pmlsm {
namespace {

using detail::evaluate_batch;
using detail::kCheckpointTag;
using detail::kCheckpointVersion;
using detail::kInfinity;

}  // namespace

// ---------------------------------------------------------------------------
// DifferentialEvolution

DifferentialEvolution::DifferentialEvolution(const DeParams& params, BatchEvaluator& evaluator)
    : params_(params), evaluator_(&evaluator), rng_(params.seed) {
  params_.validate();
}

void DifferentialEvolution::initialise_population() {
  // x_i,j ~ U[init_lower, init_upper] (Table 1), drawn member by member.
  const double width = params_.init_upper - params_.init_lower;
  std::vector<std::vector<double>> population(params_.population_size, std::vector<double>(params_.dimension));
  for (auto& member : population) {
    for (double& x : member) x = params_.init_lower + width * uniform_unit(rng_);
  }
  if (!params_.first_member.empty()) population.front() = params_.first_member;
  std::vector<double> costs;
  evaluate_batch(*evaluator_, population, costs);
  population_ = std::move(population);
  costs_ = std::move(costs);
  evaluations_ += params_.population_size;
  initialised_ = true;
}

OptimiserReport DifferentialEvolution::step() {
  // If the evaluator throws, the optimiser is left as before the call (the
  // RNG is rewound), so a retry continues the same run.
  const std::mt19937_64 rng_before = rng_;
  try {
    if (!initialised_) initialise_population();

    const std::size_t np = params_.population_size;
    const std::size_t dim = params_.dimension;
    const double f_s = params_.mutation_factor;
    const double cr = params_.crossover_rate;

    // 1. All random numbers of the generation, in one thread, in a fixed order:
    //    per member r1, r2, r3, j_rand, then D crossover draws.
    std::vector<std::vector<double>> trials(np, std::vector<double>(dim));
    for (std::size_t i = 0; i < np; ++i) {
      std::size_t r1, r2, r3;  // distinct and != i, by rejection
      do r1 = uniform_index(rng_, np);
      while (r1 == i);
      do r2 = uniform_index(rng_, np);
      while (r2 == i || r2 == r1);
      do r3 = uniform_index(rng_, np);
      while (r3 == i || r3 == r1 || r3 == r2);
      const std::size_t j_rand = uniform_index(rng_, dim);  // this component always comes from the mutant
      const auto& x_i = population_[i];
      const auto& x_r1 = population_[r1];
      const auto& x_r2 = population_[r2];
      const auto& x_r3 = population_[r3];
      for (std::size_t j = 0; j < dim; ++j) {
        const bool from_mutant = uniform_unit(rng_) < cr || j == j_rand;  // (22)
        // (21): v_i = x_r3 + F_s (x_r1 - x_r2). No clipping to the init box: the paper has none.
        trials[i][j] = from_mutant ? x_r3[j] + f_s * (x_r1[j] - x_r2[j]) : x_i[j];
      }
    }

    // 2. The whole generation as one batch.
    std::vector<double> trial_costs;
    evaluate_batch(*evaluator_, trials, trial_costs);
    evaluations_ += np;

    // 3. Greedy selection: the trial replaces its parent if it is no worse.
    //    Costs are finite or +inf, so an infinite trial never replaces a finite parent.
    for (std::size_t i = 0; i < np; ++i) {
      if (trial_costs[i] <= costs_[i]) {
        population_[i] = std::move(trials[i]);
        costs_[i] = trial_costs[i];
      }
    }
    ++generation_;
  } catch (...) {
    rng_ = rng_before;
    throw;
  }
  return report();
}

std::size_t DifferentialEvolution::best_index() const {
  // Lowest cost, first index on ties. Greedy selection is elitist, so this is the best so far.
  return static_cast<std::size_t>(std::min_element(costs_.begin(), costs_.end()) - costs_.begin());
}

OptimiserReport DifferentialEvolution::report() const {
  OptimiserReport out;
  out.generation = generation_;
  out.evaluations = evaluations_;
  out.best_cost = kInfinity;
  out.mean_cost = kInfinity;
  if (!initialised_) return out;
  const std::size_t best = best_index();
  out.best_cost = costs_[best];
  out.best = population_[best];
  double sum = 0;
  std::size_t finite = 0;
  for (double cost : costs_) {
    if (std::isfinite(cost)) {
      sum += cost;
      ++finite;
    }
  }
  if (finite > 0) out.mean_cost = sum / static_cast<double>(finite);
  return out;
}

void DifferentialEvolution::save_checkpoint(const std::string& path) const {
  std::ostringstream out;
  out << kCheckpointTag << ' ' << kCheckpointVersion << '\n'
      << "optimiser " << name() << '\n'
      << "population_size " << params_.population_size << '\n'
      << "dimension " << params_.dimension << '\n'
      << "mutation_factor " << detail::format_exact(params_.mutation_factor) << '\n'
      << "crossover_rate " << detail::format_exact(params_.crossover_rate) << '\n'
      << "init_lower " << detail::format_exact(params_.init_lower) << '\n'
      << "init_upper " << detail::format_exact(params_.init_upper) << '\n'
      << "seed " << params_.seed << '\n'
      << "generation " << generation_ << '\n'
      << "evaluations " << evaluations_ << '\n'
      << "initialised " << (initialised_ ? 1 : 0) << '\n'
      << "rng " << rng_ << '\n';
  if (initialised_) {
    for (std::size_t i = 0; i < population_.size(); ++i) {
      out << "member " << i << ' ' << detail::format_exact(costs_[i]);
      for (double x : population_[i]) out << ' ' << detail::format_exact(x);
      out << '\n';
    }
  }
  out << "end\n";
  detail::write_checkpoint_atomically(path, out.str());
}

void DifferentialEvolution::load_checkpoint(const std::string& path) {
  detail::CheckpointReader in(path);
  in.expect_header(name());
  DeParams loaded;
  loaded.population_size = in.matching_count("population_size", params_.population_size);
  loaded.dimension = in.matching_count("dimension", params_.dimension);
  loaded.mutation_factor = in.number("mutation_factor");
  loaded.crossover_rate = in.number("crossover_rate");
  loaded.init_lower = in.number("init_lower");
  loaded.init_upper = in.number("init_upper");
  loaded.seed = in.count("seed");
  loaded.first_member = params_.first_member;  // the caller's: a checkpoint does not carry it
  try {
    loaded.validate();
  } catch (const std::invalid_argument& e) {
    in.fail(std::string("invalid parameter ") + e.what());
  }
  const std::uint64_t generation = in.count("generation");
  const std::uint64_t evaluations = in.count("evaluations");
  const std::uint64_t initialised = in.count("initialised");
  if (initialised > 1) in.fail("initialised must be 0 or 1");
  const std::uint64_t expected_evaluations = initialised == 1 ? loaded.population_size * (generation + 1) : 0;
  if (evaluations != expected_evaluations || (initialised == 0 && generation != 0)) {
    in.fail("generation " + std::to_string(generation) + " and evaluations " + std::to_string(evaluations) +
            " are inconsistent");
  }
  std::mt19937_64 rng;
  {
    std::istringstream state(in.text("rng"));
    state >> rng;
    if (state.fail() || !(state >> std::ws).eof()) in.fail("unreadable RNG state");
  }
  std::vector<std::vector<double>> population;
  std::vector<double> costs;
  if (initialised == 1) {
    for (std::size_t i = 0; i < loaded.population_size; ++i) {
      std::vector<double> member;
      const double cost = in.member(i, loaded.dimension, member);
      if (std::isnan(cost) || cost == -kInfinity) in.fail("member cost must be finite or inf");
      costs.push_back(cost);
      population.push_back(std::move(member));
    }
  }
  in.expect_end();

  // Everything read and checked: commit.
  params_ = loaded;
  rng_ = rng;
  initialised_ = initialised == 1;
  generation_ = generation;
  evaluations_ = evaluations;
  population_ = std::move(population);
  costs_ = std::move(costs);
}

}  // namespace pmlsm

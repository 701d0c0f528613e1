// jDE and CMA-ES from pagmo2 behind pmlsm::Optimiser; see pagmo_optimisers.hpp
// for the choices (variants, box, sigma0, memory, evaluation, seeds).
//
// Checkpoint file (text; doubles with 17 significant digits):
//
//   pmlsm-optimiser-checkpoint 1
//   optimiser <jDE | CMA-ES>
//   population_size <NP>
//   dimension <D>
//   init_lower <x_lo>
//   init_upper <x_hi>
//   seed <seed>
//   generation <generations completed>
//   evaluations <cost evaluations so far>
//   initialised <0|1>
//   init_rng <std::mt19937_64 state of the initial-population draw>
//   best_cost <best cost so far, inf before the first step>
//   best <D components of the best so far>         (only if initialised)
//   member <i> <cost_i> <x_i,0> ... <x_i,D-1>      (NP lines, only if initialised)
//   algorithm_state <n>
//   <n characters: boost text archive of the pagmo::algorithm (RNG and adapted state)>
//   end

// pagmo::cmaes holds Eigen matrices that libpagmo allocates but whose inline
// destructor is compiled here, so this file must use libpagmo's Eigen
// allocation scheme: plain malloc (glibc's is 16-byte aligned) and at most
// 16-byte alignment. Eigen picks another scheme under AddressSanitizer, and
// -mavx raises the alignment: pin the first, refuse the second.
#ifndef EIGEN_MALLOC_ALREADY_ALIGNED
#define EIGEN_MALLOC_ALREADY_ALIGNED 1
#endif
#include <Eigen/Core>
#if EIGEN_MAX_ALIGN_BYTES > 16
#error "pagmo_optimisers.cpp: Eigen alignment above 16 bytes does not match libpagmo (built for 16)"
#endif

#include "pmlsm/optim/pagmo_optimisers.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <pagmo/algorithm.hpp>
#include <pagmo/algorithms/cmaes.hpp>
#include <pagmo/algorithms/sade.hpp>
#include <pagmo/bfe.hpp>
#include <pagmo/population.hpp>
#include <pagmo/problem.hpp>
#include <pagmo/s11n.hpp>
#include <pagmo/types.hpp>

#include "pmlsm/optim/batch_evaluation.hpp"
#include "pmlsm/optim/checkpoint.hpp"

namespace pmlsm {
namespace {

using detail::kInfinity;

// pagmo's numbering (sade.hpp): 7 = DE/rand/1/bin (2 would be rand/1/exp); adaptation 1 = jDE.
constexpr unsigned kSadeRand1Bin = 7;
constexpr unsigned kSadeJde = 1;
// The pagmo box is the init range widened this many times around its centre.
constexpr double kBoxWidthOverInitWidth = 10.0;
// CMA-ES initial step, as a fraction of the box width (pagmo scales by it):
// 0.03 x 10 = 0.3 of the init range, within Hansen's advice of 1/4..1/3 of the range.
constexpr double kCmaesSigma0 = 0.03;

using detail::evaluate_batch;
using detail::finite_or_worst;

/// splitmix64: well-mixed 32-bit pagmo seeds from the one 64-bit DeParams::seed.
std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

struct PagmoSeeds {
  unsigned algorithm;
  unsigned population;
};

PagmoSeeds derive_seeds(std::uint64_t seed) {
  std::uint64_t state = seed;
  const auto algorithm = static_cast<unsigned>(splitmix64(state) >> 32);
  const auto population = static_cast<unsigned>(splitmix64(state) >> 32);
  return {algorithm, population};
}

/// pagmo user-defined problem: our cost, reached through the BatchEvaluator
/// as batches of one (sade and cmaes call problem::fitness one candidate at a time).
class EvaluatorProblem {
 public:
  EvaluatorProblem() = default;  // pagmo requires it; never evaluated
  EvaluatorProblem(BatchEvaluator& evaluator, std::vector<double> lower, std::vector<double> upper)
      : evaluator_(&evaluator), lower_(std::move(lower)), upper_(std::move(upper)) {}

  pagmo::vector_double fitness(const pagmo::vector_double& candidate) const {
    if (evaluator_ == nullptr) throw std::logic_error("EvaluatorProblem: no evaluator");
    const std::vector<std::vector<double>> batch{candidate};
    std::vector<double> costs;
    evaluator_->evaluate(batch, costs);
    if (costs.size() != 1) {
      throw std::runtime_error("BatchEvaluator returned " + std::to_string(costs.size()) + " costs for 1 candidate");
    }
    return {finite_or_worst(costs[0])};
  }
  std::pair<pagmo::vector_double, pagmo::vector_double> get_bounds() const { return {lower_, upper_}; }
  std::string get_name() const { return "pmlsm cost through a BatchEvaluator"; }
  // The evaluator is shared by all copies and need not be reentrant.
  pagmo::thread_safety get_thread_safety() const { return pagmo::thread_safety::none; }

 private:
  BatchEvaluator* evaluator_ = nullptr;  // not owned
  std::vector<double> lower_, upper_;
};

std::string algorithm_name(PagmoAlgorithm algorithm) { return algorithm == PagmoAlgorithm::jde ? "jDE" : "CMA-ES"; }

void validate_for(PagmoAlgorithm algorithm, const DeParams& params) {
  params.validate();
  const std::size_t minimum = algorithm == PagmoAlgorithm::jde ? 7 : 5;  // pagmo's own limits
  if (params.population_size < minimum) {
    throw std::invalid_argument("population_size: must be >= " + std::to_string(minimum) + " for " +
                                algorithm_name(algorithm) + ", got " + std::to_string(params.population_size));
  }
  const double half_width = 0.5 * kBoxWidthOverInitWidth * (params.init_upper - params.init_lower);
  const double centre = 0.5 * (params.init_lower + params.init_upper);
  if (!std::isfinite(centre - half_width) || !std::isfinite(centre + half_width)) {
    throw std::invalid_argument("init_upper: the pagmo box (10 x the init range) must be finite, got [" +
                                std::to_string(params.init_lower) + ", " + std::to_string(params.init_upper) + "]");
  }
}

pagmo::problem make_problem(const DeParams& params, BatchEvaluator& evaluator) {
  const double half_width = 0.5 * kBoxWidthOverInitWidth * (params.init_upper - params.init_lower);
  const double centre = 0.5 * (params.init_lower + params.init_upper);
  return pagmo::problem{EvaluatorProblem{evaluator, std::vector<double>(params.dimension, centre - half_width),
                                         std::vector<double>(params.dimension, centre + half_width)}};
}

pagmo::algorithm make_algorithm(PagmoAlgorithm algorithm, unsigned seed) {
  // gen = 1: one generation per step(); tolerances 0: never stop early; memory: carry the adaptation over.
  constexpr unsigned kGenerationsPerEvolve = 1;
  constexpr double kNoTolerance = 0.0;
  constexpr bool kMemory = true;
  if (algorithm == PagmoAlgorithm::jde) {
    return pagmo::algorithm{
        pagmo::sade{kGenerationsPerEvolve, kSadeRand1Bin, kSadeJde, kNoTolerance, kNoTolerance, kMemory, seed}};
  }
  constexpr double kAuto = -1;  // cc, cs, c1, cmu from Hansen's defaults for N and mu
  constexpr bool kForceBounds = false;
  return pagmo::algorithm{pagmo::cmaes{kGenerationsPerEvolve, kAuto, kAuto, kAuto, kAuto, kCmaesSigma0, kNoTolerance,
                                       kNoTolerance, kMemory, kForceBounds, seed}};
}

bool holds(const pagmo::algorithm& algo, PagmoAlgorithm algorithm) {
  return algorithm == PagmoAlgorithm::jde ? algo.is<pagmo::sade>() : algo.is<pagmo::cmaes>();
}

}  // namespace

// ---------------------------------------------------------------------------
// BatchEvaluatorBfe

std::vector<double> BatchEvaluatorBfe::operator()(const pagmo::problem& problem, const std::vector<double>& dvs) const {
  if (evaluator_ == nullptr) throw std::logic_error("BatchEvaluatorBfe: default-constructed, no evaluator");
  if (problem.get_nf() != 1) throw std::invalid_argument("BatchEvaluatorBfe: the problem must have one objective");
  const std::size_t dim = problem.get_nx();
  if (dim == 0 || dvs.size() % dim != 0) {
    throw std::invalid_argument("BatchEvaluatorBfe: " + std::to_string(dvs.size()) +
                                " values are not whole decision vectors of size " + std::to_string(dim));
  }
  std::vector<std::vector<double>> candidates(dvs.size() / dim);
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const auto first = dvs.begin() + static_cast<std::ptrdiff_t>(i * dim);
    candidates[i].assign(first, first + static_cast<std::ptrdiff_t>(dim));
  }
  std::vector<double> costs;
  evaluate_batch(*evaluator_, candidates, costs);
  // No problem.increment_fevals() here: pagmo 2.18's bfe::operator() counts the evaluations itself.
  return costs;
}

// ---------------------------------------------------------------------------
// PagmoOptimiser

struct PagmoOptimiser::State {
  pagmo::algorithm algorithm;
  pagmo::population population;  // empty until the first step()
  std::mt19937_64 init_rng;      // draws the initial population
  bool initialised = false;
  std::uint64_t generation = 0;
  double best_cost = kInfinity;  // best ever evaluated (CMA-ES may drop it from the population)
  std::vector<double> best;
};

PagmoOptimiser::PagmoOptimiser(PagmoAlgorithm algorithm, const DeParams& params, BatchEvaluator& evaluator)
    : algorithm_(algorithm), params_(params), evaluator_(&evaluator) {
  validate_for(algorithm_, params_);
  const PagmoSeeds seeds = derive_seeds(params_.seed);
  state_ = std::make_unique<State>();
  state_->algorithm = make_algorithm(algorithm_, seeds.algorithm);
  state_->population = pagmo::population{make_problem(params_, *evaluator_), 0u, seeds.population};
  state_->init_rng.seed(params_.seed);
}

PagmoOptimiser::~PagmoOptimiser() = default;

std::string PagmoOptimiser::name() const { return algorithm_name(algorithm_); }

OptimiserReport PagmoOptimiser::step() {
  // Work on a copy and commit at the end: if the evaluator throws, nothing changed.
  auto next = std::make_unique<State>(*state_);
  if (!next->initialised) {
    // Uniform in [init_lower, init_upper], the same draw as DE's, evaluated as one batch.
    const double width = params_.init_upper - params_.init_lower;
    std::vector<double> dvs(params_.population_size * params_.dimension);
    for (double& x : dvs) x = params_.init_lower + width * uniform_unit(next->init_rng);
    std::copy(params_.first_member.begin(), params_.first_member.end(), dvs.begin());
    const pagmo::bfe batch_evaluator{BatchEvaluatorBfe{*evaluator_}};
    const std::vector<double> costs = batch_evaluator(next->population.get_problem(), dvs);
    for (std::size_t i = 0; i < params_.population_size; ++i) {
      const auto first = dvs.begin() + static_cast<std::ptrdiff_t>(i * params_.dimension);
      next->population.push_back(pagmo::vector_double(first, first + static_cast<std::ptrdiff_t>(params_.dimension)),
                                 {costs[i]});
    }
    next->initialised = true;
  }
  // Best so far: the initial population (CMA-ES replaces all of it in its first generation), then
  // every population after evolve(): every candidate CMA-ES evaluated is in it, and a jDE trial
  // that is not there lost to its parent, so scanning the population suffices.
  const auto take_best = [&next] {
    const auto& costs = next->population.get_f();
    for (std::size_t i = 0; i < costs.size(); ++i) {
      if (costs[i][0] < next->best_cost || next->best.empty()) {
        next->best_cost = costs[i][0];
        next->best = next->population.get_x()[i];
      }
    }
  };
  if (next->generation == 0) take_best();
  next->population = next->algorithm.evolve(next->population);
  ++next->generation;
  take_best();
  state_ = std::move(next);
  return report();
}

OptimiserReport PagmoOptimiser::report() const {
  OptimiserReport out;
  out.generation = state_->generation;
  out.evaluations = state_->population.get_problem().get_fevals();
  out.best_cost = state_->best_cost;
  out.best = state_->best;
  out.mean_cost = kInfinity;
  double sum = 0;
  std::size_t finite = 0;
  for (const auto& f : state_->population.get_f()) {
    if (std::isfinite(f[0])) {
      sum += f[0];
      ++finite;
    }
  }
  if (finite > 0) out.mean_cost = sum / static_cast<double>(finite);
  return out;
}

std::vector<std::vector<double>> PagmoOptimiser::population() const { return state_->population.get_x(); }

std::vector<double> PagmoOptimiser::costs() const {
  std::vector<double> out;
  for (const auto& f : state_->population.get_f()) out.push_back(f[0]);
  return out;
}

void PagmoOptimiser::save_checkpoint(const std::string& path) const {
  const State& s = *state_;
  std::string algorithm_state;
  {
    std::ostringstream archive_text;
    {
      boost::archive::text_oarchive archive(archive_text);
      const pagmo::algorithm& algo = s.algorithm;
      archive << algo;
    }
    algorithm_state = archive_text.str();
  }
  std::ostringstream out;
  out << "pmlsm-optimiser-checkpoint 1\n"
      << "optimiser " << name() << '\n'
      << "population_size " << params_.population_size << '\n'
      << "dimension " << params_.dimension << '\n'
      << "init_lower " << detail::format_exact(params_.init_lower) << '\n'
      << "init_upper " << detail::format_exact(params_.init_upper) << '\n'
      << "seed " << params_.seed << '\n'
      << "generation " << s.generation << '\n'
      << "evaluations " << s.population.get_problem().get_fevals() << '\n'
      << "initialised " << (s.initialised ? 1 : 0) << '\n'
      << "init_rng " << s.init_rng << '\n'
      << "best_cost " << detail::format_exact(s.best_cost) << '\n';
  if (s.initialised) {
    out << "best";
    for (double x : s.best) out << ' ' << detail::format_exact(x);
    out << '\n';
    const auto& xs = s.population.get_x();
    const auto& fs = s.population.get_f();
    for (std::size_t i = 0; i < xs.size(); ++i) {
      out << "member " << i << ' ' << detail::format_exact(fs[i][0]);
      for (double x : xs[i]) out << ' ' << detail::format_exact(x);
      out << '\n';
    }
  }
  out << "algorithm_state " << algorithm_state.size() << '\n' << algorithm_state << '\n' << "end\n";
  detail::write_checkpoint_atomically(path, out.str());
}

void PagmoOptimiser::load_checkpoint(const std::string& path) {
  detail::CheckpointReader in(path);
  in.expect_header(name());
  DeParams loaded = params_;  // mutation_factor and crossover_rate are not used here
  loaded.population_size = in.matching_count("population_size", params_.population_size);
  loaded.dimension = in.matching_count("dimension", params_.dimension);
  loaded.init_lower = in.number("init_lower");
  loaded.init_upper = in.number("init_upper");
  loaded.seed = in.count("seed");
  try {
    validate_for(algorithm_, loaded);
  } catch (const std::invalid_argument& e) {
    in.fail(std::string("invalid parameter ") + e.what());
  }

  auto next = std::make_unique<State>();
  next->generation = in.count("generation");
  const std::uint64_t evaluations = in.count("evaluations");
  const std::uint64_t initialised = in.count("initialised");
  if (initialised > 1) in.fail("initialised must be 0 or 1");
  next->initialised = initialised == 1;
  if (!next->initialised && (next->generation != 0 || evaluations != 0)) {
    in.fail("not initialised but generation or evaluations is not 0");
  }
  {
    std::istringstream state(in.text("init_rng"));
    state >> next->init_rng;
    if (state.fail() || !(state >> std::ws).eof()) in.fail("unreadable RNG state");
  }
  next->best_cost = in.number("best_cost");
  if (std::isnan(next->best_cost)) in.fail("best_cost is NaN");

  const PagmoSeeds seeds = derive_seeds(loaded.seed);
  next->population = pagmo::population{make_problem(loaded, *evaluator_), 0u, seeds.population};
  if (next->initialised) {
    next->best = in.numbers("best", loaded.dimension);
    for (std::size_t i = 0; i < loaded.population_size; ++i) {
      pagmo::vector_double member;
      const double cost = in.member(i, loaded.dimension, member);
      if (std::isnan(cost)) in.fail("member cost is NaN");
      next->population.push_back(std::move(member), {cost});
    }
  }
  // The problem's counter is the evaluation count; push_back with a known cost does not count.
  next->population.get_problem().increment_fevals(evaluations);

  const std::string algorithm_state = in.raw(in.count("algorithm_state"));
  try {
    std::istringstream archive_text(algorithm_state);
    boost::archive::text_iarchive archive(archive_text);
    archive >> next->algorithm;
  } catch (const std::exception& e) {
    in.fail(std::string("corrupt algorithm state: ") + e.what());
  }
  if (!holds(next->algorithm, algorithm_)) {
    in.fail("algorithm state is " + next->algorithm.get_name() + ", not " + name());
  }
  in.expect_end();

  params_ = loaded;
  state_ = std::move(next);
}

}  // namespace pmlsm

// pagmo2's self-adaptive DE (jDE) and CMA-ES behind pmlsm::Optimiser.
//
// jDE  = pagmo::sade, variant 7 (DE/rand/1/bin in pagmo's numbering; pagmo's
//        variant 2 is rand/1/exp), variant_adptv 1 (jDE self-adaptation of F
//        and CR per member, Brest et al. 2006). Needs population_size >= 7.
// CMA-ES = pagmo::cmaes, lambda = population_size (>= 5), mu = lambda / 2,
//        force_bounds false. Not elitist: the report's best is the best ever
//        evaluated, which need not be in the current population.
//
// Both run with memory = true (F/CR, or mean, step size and covariance, carry
// over between evolve() calls) and one generation per step(), so stepping is
// the same run as one long evolve(); the stopping tolerances are 0 (the caller
// decides when to stop).
//
// Box: pagmo needs finite bounds. The box is the init range widened 10 times
// around its centre (for [-1, 1]: [-10, 10]). jDE re-draws a trial component
// that leaves the box uniformly inside the box (pagmo's rule); CMA-ES ignores
// the box (force_bounds false) except that it scales its initial step:
// sigma0 = 0.03 of the box width = 0.3 of the init range.
//
// Initial population: drawn by us, uniform in [init_lower, init_upper] from a
// std::mt19937_64 seeded with DeParams::seed (the same population as DE's for
// the same seed), evaluated as one batch through the BatchEvaluator.
//
// Evaluation: in pagmo 2.18 neither sade nor cmaes accepts a batch fitness
// evaluator (no set_bfe(); only gaco, maco, nsga2, nspso and pso_gen do), so
// after the initial population their candidates are evaluated one at a time
// through pagmo::problem::fitness, which our problem forwards to the
// BatchEvaluator as a batch of one: remote workers still work, but without
// parallelism. BatchEvaluatorBfe below is the bfe for algorithms that accept one.
//
// Seeds: algorithm seed and pagmo population seed are derived from
// DeParams::seed (splitmix64), so runs are reproducible, and identical for any
// evaluator and thread count.
//
// Checkpoint: a text file "pmlsm-pagmo-checkpoint 1" with the parameters, the
// counters, the best-so-far, the population (costs and decision vectors, 17
// significant digits) and the algorithm's whole state (pagmo's boost text
// serialisation of pagmo::algorithm: RNG, jDE's per-member F and CR, or
// CMA-ES's mean, sigma, C, B, D, evolution paths and counters). A resumed run
// continues bit-identically to an uninterrupted one (tested).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <pagmo/threading.hpp>

#include "pmlsm/optim/optimiser.hpp"

namespace pagmo {
class problem;
}

namespace pmlsm {

enum class PagmoAlgorithm { jde, cmaes };

class PagmoOptimiser final : public Optimiser {
 public:
  /// The evaluator must outlive the optimiser. mutation_factor and crossover_rate are not used.
  /// @throws std::invalid_argument naming the first invalid parameter.
  PagmoOptimiser(PagmoAlgorithm algorithm, const DeParams& params, BatchEvaluator& evaluator);
  ~PagmoOptimiser() override;
  PagmoOptimiser(const PagmoOptimiser&) = delete;
  PagmoOptimiser& operator=(const PagmoOptimiser&) = delete;

  std::string name() const override;
  OptimiserReport step() override;
  OptimiserReport report() const override;
  void save_checkpoint(const std::string& path) const override;
  void load_checkpoint(const std::string& path) override;

  /// Current population and its costs (empty before the first step()).
  std::vector<std::vector<double>> population() const;
  std::vector<double> costs() const;

 private:
  struct State;  // pagmo objects, kept out of this header
  PagmoAlgorithm algorithm_;
  DeParams params_;
  BatchEvaluator* evaluator_;  // not owned
  std::unique_ptr<State> state_;
};

/// A pagmo user-defined batch fitness evaluator (UDBFE) that forwards to a
/// BatchEvaluator: use as pagmo::bfe{BatchEvaluatorBfe{evaluator}} with
/// algorithms that have set_bfe(). The problem must be single-objective and
/// unconstrained. pagmo::bfe::operator() counts the evaluations in the
/// problem (pagmo 2.18), so calling this class directly does not. The
/// evaluator must outlive every copy; copies
/// share it, hence thread_safety::none (pagmo will not call copies concurrently).
class BatchEvaluatorBfe {
 public:
  BatchEvaluatorBfe() = default;  // pagmo requires it; calling a default-constructed one throws
  explicit BatchEvaluatorBfe(BatchEvaluator& evaluator) : evaluator_(&evaluator) {}
  /// dvs: the decision vectors one after the other; returns one cost per vector.
  std::vector<double> operator()(const pagmo::problem& problem, const std::vector<double>& dvs) const;
  std::string get_name() const { return "pmlsm::BatchEvaluatorBfe"; }
  pagmo::thread_safety get_thread_safety() const { return pagmo::thread_safety::none; }

 private:
  BatchEvaluator* evaluator_ = nullptr;  // not owned
};

}  // namespace pmlsm

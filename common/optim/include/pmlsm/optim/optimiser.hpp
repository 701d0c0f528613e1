// Population-based optimisers for training the vibration compensator (paper
// section 3.3), behind one interface so that the trainer can switch between
// the paper's DE/rand/1/bin (pmlsm/optim/differential_evolution.hpp) and
// pagmo2's jDE and CMA-ES (pmlsm/optim/pagmo_optimisers.hpp) without changing
// anything else.
//
// Evaluation seam: an optimiser never calls the cost itself; it hands whole
// batches of candidates to a BatchEvaluator, which may run them on local
// threads (ThreadPoolEvaluator, pmlsm/optim/thread_pool_evaluator.hpp) or on
// remote workers.
//
// Determinism: for a given seed the sequence of candidates and the result are
// identical for any evaluator and any thread count, because all random numbers
// are drawn in one thread before the batch is evaluated and costs are returned
// by index.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "pmlsm/optim/de_params.hpp"

namespace pmlsm {

/// Cost of one candidate; must be deterministic and thread-safe (called concurrently).
using CostFunction = std::function<double(const std::vector<double>& candidate)>;

/// Evaluates a batch of candidates, costs[i] for candidates[i]. The seam where remote workers plug in.
/// Implementations resize `costs` to candidates.size().
class BatchEvaluator {
 public:
  virtual ~BatchEvaluator() = default;
  virtual void evaluate(const std::vector<std::vector<double>>& candidates, std::vector<double>& costs) = 0;
};

struct OptimiserReport {
  std::uint64_t generation = 0;   // generations completed
  std::uint64_t evaluations = 0;  // cost evaluations so far (including the initial population)
  double best_cost = 0;           // +infinity before the first step()
  double mean_cost = 0;           // over the current population (finite members; +infinity if none)
  std::vector<double> best;       // best candidate so far (empty before the first step())
};

class Optimiser {
 public:
  virtual ~Optimiser() = default;
  virtual std::string name() const = 0;  // "DE/rand/1/bin", "jDE", "CMA-ES"
  /// One generation (the first call also evaluates the initial population).
  virtual OptimiserReport step() = 0;
  virtual OptimiserReport report() const = 0;
  /// Atomic: writes path + ".tmp", fsyncs it, renames it to path, fsyncs the directory.
  /// @throws std::runtime_error naming the file if it cannot be written.
  virtual void save_checkpoint(const std::string& path) const = 0;
  /// Replaces the whole state by the checkpoint's; the optimiser is unchanged if this throws.
  /// @throws std::runtime_error naming the file and what is wrong (missing, wrong optimiser,
  ///         wrong dimension, corrupt or truncated).
  virtual void load_checkpoint(const std::string& path) = 0;
};

enum class OptimiserKind { de, jde, cmaes };

/// "de" | "jde" | "cmaes". @throws std::invalid_argument listing the choices.
OptimiserKind parse_optimiser_kind(const std::string& text);

/// jDE/CMA-ES use population_size, dimension, init bounds and seed from `common`
/// (mutation_factor and crossover_rate are DE-only). The evaluator must outlive the optimiser.
/// @throws std::invalid_argument naming the first invalid parameter.
std::unique_ptr<Optimiser> make_optimiser(OptimiserKind kind, const DeParams& common, BatchEvaluator& evaluator);

// Random-number mappings used by the optimisers, defined here (not
// std::uniform_*_distribution, whose output is implementation-defined) so a
// seed gives the same run with any standard library.

/// Uniform in [0, 1) from the top 53 bits of one draw.
inline double uniform_unit(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

/// Uniform integer in [0, n), n >= 1, unbiased by rejection of the draws below 2^64 mod n.
inline std::uint64_t uniform_index(std::mt19937_64& rng, std::uint64_t n) {
  const std::uint64_t reject_below = (0 - n) % n;  // (2^64 - n) mod n == 2^64 mod n
  std::uint64_t draw = rng();
  while (draw < reject_below) draw = rng();
  return draw % n;
}

}  // namespace pmlsm

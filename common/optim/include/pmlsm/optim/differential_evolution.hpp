// The paper's optimiser, DE/rand/1/bin (section 3.3, eqs. 21-22), behind pmlsm::Optimiser.
#pragma once

#include <cstddef>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "pmlsm/optim/optimiser.hpp"

namespace pmlsm {

/// DE/rand/1/bin exactly as the paper, eqs. (21)-(22):
///   init      x_i,j ~ U[init_lower, init_upper]
///   mutation  v_i = x_r3 + F_s (x_r1 - x_r2),  r1, r2, r3 distinct and != i      (21)
///   crossover u_i,j = v_i,j if rand_j < CR or j == j_rand, else x_i,j          (22)
///   selection x_i <- u_i if cost(u_i) <= cost(x_i)
/// A generation's random numbers are drawn first, then all NP trials are
/// evaluated as one batch, then selection (so the result does not depend on
/// the evaluator). There is no bound handling after the initialisation: the
/// paper has none, and the network weights may leave the initial box.
///
/// Checkpoint: a text file, see save_checkpoint() in differential_evolution.cpp
/// for the format. A resumed run continues bit-identically to an uninterrupted one.
/// population_size and dimension must match the optimiser's; the other
/// parameters (F_s, CR, init box, seed) and the RNG state are taken from the
/// file so that the saved run continues as it was.
class DifferentialEvolution final : public Optimiser {
 public:
  /// The evaluator must outlive the optimiser.
  /// @throws std::invalid_argument naming the first invalid parameter.
  DifferentialEvolution(const DeParams& params, BatchEvaluator& evaluator);

  std::string name() const override { return "DE/rand/1/bin"; }
  OptimiserReport step() override;
  OptimiserReport report() const override;
  void save_checkpoint(const std::string& path) const override;
  void load_checkpoint(const std::string& path) override;

  const DeParams& params() const { return params_; }
  /// Current population and its costs (empty before the first step()).
  const std::vector<std::vector<double>>& population() const { return population_; }
  const std::vector<double>& costs() const { return costs_; }

 private:
  void initialise_population();
  std::size_t best_index() const;

  DeParams params_;
  BatchEvaluator* evaluator_;  // not owned
  std::mt19937_64 rng_;
  bool initialised_ = false;
  std::uint64_t generation_ = 0;
  std::uint64_t evaluations_ = 0;
  std::vector<std::vector<double>> population_;
  std::vector<double> costs_;
};

}  // namespace pmlsm

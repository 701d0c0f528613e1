// Evaluation helpers shared by thread_pool_evaluator.cpp,
// differential_evolution.cpp and pagmo_optimisers.cpp; not an API.
#pragma once

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "pmlsm/optim/optimiser.hpp"

namespace pmlsm {
namespace detail {

inline constexpr double kInfinity = std::numeric_limits<double>::infinity();

/// A cost that is NaN or infinite (a run that blew up) is simply the worst.
inline double finite_or_worst(double cost) { return std::isfinite(cost) ? cost : kInfinity; }

/// Runs one batch through the evaluator and checks what came back.
inline void evaluate_batch(BatchEvaluator& evaluator, const std::vector<std::vector<double>>& candidates,
                           std::vector<double>& costs) {
  evaluator.evaluate(candidates, costs);
  if (costs.size() != candidates.size()) {
    throw std::runtime_error("BatchEvaluator returned " + std::to_string(costs.size()) + " costs for " +
                             std::to_string(candidates.size()) + " candidates");
  }
  for (double& cost : costs) cost = finite_or_worst(cost);
}

}  // namespace detail
}  // namespace pmlsm

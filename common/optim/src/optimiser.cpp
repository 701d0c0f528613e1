// The factory (the optimisers' common parameters are in de_params.cpp). The optimisers are in
// differential_evolution.cpp and pagmo_optimisers.cpp, the local evaluator in
// thread_pool_evaluator.cpp, the checkpoint plumbing in checkpoint.cpp.
#include "pmlsm/optim/optimiser.hpp"

#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>

#include "pmlsm/optim/differential_evolution.hpp"
#include "pmlsm/optim/pagmo_optimisers.hpp"
#include "pmlsm/util/validate.hpp"

namespace pmlsm {

// ---------------------------------------------------------------------------
// Factory

OptimiserKind parse_optimiser_kind(const std::string& text) {
  if (text == "de") return OptimiserKind::de;
  if (text == "jde") return OptimiserKind::jde;
  if (text == "cmaes") return OptimiserKind::cmaes;
  throw std::invalid_argument("optimiser: must be one of de, jde, cmaes, got '" + text + "'");
}

std::unique_ptr<Optimiser> make_optimiser(OptimiserKind kind, const DeParams& common, BatchEvaluator& evaluator) {
  switch (kind) {
    case OptimiserKind::de: return std::make_unique<DifferentialEvolution>(common, evaluator);
    case OptimiserKind::jde: return std::make_unique<PagmoOptimiser>(PagmoAlgorithm::jde, common, evaluator);
    case OptimiserKind::cmaes: return std::make_unique<PagmoOptimiser>(PagmoAlgorithm::cmaes, common, evaluator);
  }
  throw std::invalid_argument("optimiser: unknown kind " + std::to_string(static_cast<int>(kind)));
}

}  // namespace pmlsm

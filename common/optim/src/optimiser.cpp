// The optimisers' common parameters and the factory. The optimisers are in
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
// Parameters

void DeParams::validate() const {
  if (population_size < 4) {
    // r1, r2, r3 and i must be four distinct members, eq. (21).
    throw std::invalid_argument("population_size: must be >= 4, got " + std::to_string(population_size));
  }
  if (dimension < 1) throw std::invalid_argument("dimension: must be >= 1, got " + std::to_string(dimension));
  require_finite("mutation_factor", mutation_factor);
  if (!(mutation_factor > 0.0 && mutation_factor <= 2.0)) {
    throw std::invalid_argument("mutation_factor: must be in (0, 2], got " + format_value(mutation_factor));
  }
  require_in_range("crossover_rate", crossover_rate, 0.0, 1.0);
  require_finite("init_lower", init_lower);
  require_finite("init_upper", init_upper);
  if (!(init_lower < init_upper)) {
    throw std::invalid_argument("init_upper: must be > init_lower (" + format_value(init_lower) + "), got " +
                                format_value(init_upper));
  }
  if (!std::isfinite(init_upper - init_lower)) {
    throw std::invalid_argument("init_upper: init_upper - init_lower must be finite, got " + format_value(init_upper) +
                                " - " + format_value(init_lower));
  }
  if (!first_member.empty()) {
    if (first_member.size() != dimension) {
      throw std::invalid_argument("first_member: expected " + std::to_string(dimension) + " values, got " +
                                  std::to_string(first_member.size()));
    }
    for (std::size_t i = 0; i < first_member.size(); ++i) {
      require_finite(("first_member[" + std::to_string(i) + "]").c_str(), first_member[i]);
    }
  }
}

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

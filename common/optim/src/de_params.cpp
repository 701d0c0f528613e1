// DeParams::validate: the ranges of a population search, checked once for every optimiser and
// for the training file (pmlsm/analysis/rnn_training.hpp).
#include "pmlsm/optim/de_params.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

void DeParams::validate() const {
  if (population_size < 4) {
    // r1, r2, r3 and i must be four distinct members, eq. (21).
    throw std::invalid_argument("population_size: must be >= 4, got " + std::to_string(population_size));
  }
  // Plausible sizes: the paper's NP is 120; 1e5 members of 91 weights already hold 73 MB.
  if (population_size > 100000) {
    throw std::invalid_argument("population_size: must be <= 100000 (the paper's NP is 120), got " +
                                std::to_string(population_size));
  }
  if (dimension < 1) throw std::invalid_argument("dimension: must be >= 1, got " + std::to_string(dimension));
  require_finite("mutation_factor", mutation_factor);
  // F_s scales the difference vector of (21): below 1e-9 a trial cannot leave its base member's
  // rounding, so such a value is a typing error rather than a search.
  if (!(mutation_factor >= 1e-9 && mutation_factor <= 2.0)) {
    throw std::invalid_argument("mutation_factor: must be in [1e-09, 2], got " + format_value(mutation_factor));
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

}  // namespace pmlsm

// The parameters of a population search (Table 1 of the paper: NP, F_s, CR, the initial box),
// shared by the optimisers (pmlsm/optim/optimiser.hpp) and the training file's reader, which
// checks them here once. Pure: no pagmo, no threads.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace pmlsm {

struct DeParams {
  std::size_t population_size = 120;           // NP, Table 1; >= 4 (jDE needs >= 7, CMA-ES >= 5)
  std::size_t dimension = 91;                  // D, Table 1; >= 1
  double mutation_factor = 0.8;                // F_s, (21); in [1e-9, 2]
  double crossover_rate = 0.7;                 // CR, (22); in [0, 1]
  double init_lower = -1.0, init_upper = 1.0;  // Table 1; lower < upper, finite
  std::uint64_t seed = 1;
  /// Empty, or `dimension` finite values that replace the initial population's member 0 after
  /// the draw (the other members and the random stream stay as without it): a search started
  /// from a known candidate. DE keeps it until a trial beats it; CMA-ES centres its first
  /// generation on the best initial member. Used before the first generation only (a checkpoint
  /// does not carry it).
  std::vector<double> first_member;
  /// @throws std::invalid_argument "population_size: must be >= 4, got 3" style.
  void validate() const;
};

}  // namespace pmlsm

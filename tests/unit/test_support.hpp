// Shared set-up for the unit tests: the shipped parameters, loaded once.
#pragma once

#include <string>

#include "pmlsm/config/config.hpp"
#include "pmlsm/config/weights_file.hpp"

namespace pmlsm::test {

inline const SystemParams& shipped_params() {
  static const SystemParams params = load_system_params(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml");
  return params;
}

inline Scenario shipped_scenario(const std::string& name) {
  return load_scenario(std::string(PMLSM_SOURCE_DIR) + "/configs/scenarios/" + name + ".yaml",
                       shipped_params().timing.control_period_s);
}

/// The shipped RNN weights (configs/rnn_weights.yaml), loaded once.
inline const std::vector<double>& shipped_rnn_weights() {
  static const std::vector<double> weights =
      load_rnn_weights(std::string(PMLSM_SOURCE_DIR) + "/configs/rnn_weights.yaml").weights;
  return weights;
}

/// The shipped plant without friction, ripple or mechanical damping: the linear
/// two-mass system the paper's handy numbers describe.
inline SystemParams ideal_params() {
  SystemParams p = shipped_params();
  p.plant.friction.coulomb_n = 0;
  p.plant.friction.viscous_n_s_per_m = 0;
  p.plant.ripple.scale_n = 0;
  p.plant.mechanics.damping_n_s_per_m = 0;
  return p;
}

}  // namespace pmlsm::test

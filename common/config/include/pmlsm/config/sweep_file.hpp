// A robustness sweep file (configs/sweeps/*.yaml): the plant family, the compensators, the
// scenarios and the verdict's thresholds, and optionally (models:) whether every plant is
// commissioned first (identified: true, on identification_scenario). Read by `pmlsm sweep FILE`.
#pragma once

#include <string>
#include <vector>

#include "pmlsm/config/config.hpp"
#include "pmlsm/analysis/sweep.hpp"

namespace pmlsm {

struct SweepFile {
  SweepSpec spec;
  std::string weights_path;                  ///< the RNN's weights (relative paths resolved against the file)
  std::vector<std::string> scenario_files;   ///< as resolved
  std::string identification_scenario_file;  ///< models.identification_scenario, resolved ("" without)
};

/// nominal: the system the plants vary (its timing validates the scenarios, its table the keys).
/// @throws ConfigError naming the file, the key path, the value and its line.
SweepFile load_sweep_file(const std::string& path, const SystemParams& nominal,
                          const std::vector<ConfigOverride>& overrides = {});
/// The `verdict:` section of a sweep file alone (a training file judges its runs by it, so the
/// sweep and the training judge alike). @throws ConfigError naming the file, the key and its line.
VerdictParams load_sweep_verdict(const std::string& path);
SweepFile parse_sweep_file(const std::string& yaml_text, const std::string& origin, const SystemParams& nominal,
                           const std::vector<ConfigOverride>& overrides = {});

}  // namespace pmlsm

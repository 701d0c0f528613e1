// `--set key.path=value` (ConfigOverride::parse) applied to a shipped file. Input: one override
// per line; the first byte picks the file (system, a scenario, training, CANopen).
#include <vector>

#include "fuzz_support.hpp"
#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/config/config.hpp"

namespace pmlsm::fuzz::config_override {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  static const std::string system_yaml = source_file("configs/system.yaml");
  static const std::string scenario_yaml = source_file("configs/scenarios/pulse.yaml");
  static const std::string training_yaml = source_file("configs/training.yaml");
  static const std::string canopen_yaml = source_file("configs/canopen/drive.yaml");
  static const std::string training_origin = source_path("configs/training.yaml");
  if (size == 0) return 0;

  const std::string text = as_text(data + 1, size - 1);
  std::vector<ConfigOverride> overrides;
  std::size_t begin = 0;
  while (begin <= text.size()) {
    std::size_t end = text.find('\n', begin);
    if (end == std::string::npos) end = text.size();
    try {
      overrides.push_back(ConfigOverride::parse(text.substr(begin, end - begin)));
    } catch (const ConfigError&) {
    }
    begin = end + 1;
  }
  try {
    switch (data[0] % 4) {
      case 0: parse_system_params(system_yaml, "configs/system.yaml", overrides); break;
      case 1: parse_scenario(scenario_yaml, "configs/scenarios/pulse.yaml", 1e-3, overrides); break;
      case 2: parse_training_params(training_yaml, training_origin, 1e-3, overrides); break;
      default: parse_canopen_config(canopen_yaml, "configs/canopen/drive.yaml", overrides); break;
    }
  } catch (const ConfigError&) {
  }
  return 0;
}

}  // namespace pmlsm::fuzz::config_override

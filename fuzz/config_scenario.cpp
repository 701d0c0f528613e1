// configs/scenarios/*.yaml (parse_scenario) at the shipped 1 ms control period.
#include "fuzz_support.hpp"
#include "pmlsm/config/config.hpp"

namespace pmlsm::fuzz::config_scenario {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  try {
    parse_scenario(as_text(data, size), "fuzz/scenario.yaml", 1e-3);
  } catch (const ConfigError&) {
  }
  return 0;
}

}  // namespace pmlsm::fuzz::config_scenario

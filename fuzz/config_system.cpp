// configs/system.yaml: the system parameters (parse_system_params). Any text gives the parameters
// or a ConfigError naming the key and value.
#include "fuzz_support.hpp"
#include "pmlsm/config/config.hpp"

namespace pmlsm::fuzz::config_system {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  try {
    parse_system_params(as_text(data, size), "fuzz/system.yaml");
  } catch (const ConfigError&) {
  }
  return 0;
}

}  // namespace pmlsm::fuzz::config_system

// configs/canopen/drive.yaml (parse_canopen_config).
#include "fuzz_support.hpp"
#include "pmlsm/config/canopen_config.hpp"

namespace pmlsm::fuzz::config_canopen {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  try {
    parse_canopen_config(as_text(data, size), "fuzz/drive.yaml");
  } catch (const ConfigError&) {
  }
  return 0;
}

}  // namespace pmlsm::fuzz::config_canopen

// configs/training.yaml (parse_training_params). The text is named as if it were the shipped
// file, so that its relative scenario names reach the shipped scenarios.
#include "fuzz_support.hpp"
#include "pmlsm/config/config.hpp"

namespace pmlsm::fuzz::config_training {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  static const std::string origin = source_path("configs/training.yaml");
  try {
    parse_training_params(as_text(data, size), origin, 1e-3);
  } catch (const ConfigError&) {
  }
  return 0;
}

}  // namespace pmlsm::fuzz::config_training

// The RNN weights file (parse_rnn_weights, what load_rnn_weights reads): a valid set passes
// validate_rnn_weights and builds the network it describes.
#include <vector>

#include "fuzz_support.hpp"
#include "pmlsm/compensation/jordan_rnn.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/config/weights_file.hpp"

namespace pmlsm::fuzz::weights_file {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  RnnWeightsFile file;
  try {
    file = parse_rnn_weights(as_text(data, size), "fuzz/weights.yaml");
  } catch (const ConfigError&) {
    return 0;
  }
  // What the loader accepted must be what the validator and the network accept (no throw).
  validate_rnn_weights(file);
  JordanRnn network(file.layer_sizes);
  network.set_weights(file.weights);
  std::vector<double> inputs(network.external_input_count(), 0.5);
  network.forward(inputs.data());
  return 0;
}

}  // namespace pmlsm::fuzz::weights_file

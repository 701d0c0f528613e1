// The RNN weights file: one set of Jordan-network weights (jordan_rnn.hpp) with
// what is needed to use it, as written by the DE trainer and read by the
// compensator.
//
// Format "pmlsm-rnn-weights/1": a YAML mapping with exactly these keys, all required but input:
//
//   format: pmlsm-rnn-weights/1
//   layer_sizes: [3, 6, 6, 3, 1]      # inputs (external inputs + the state unit) first,
//                                     # output (1 neuron) last; see JordanRnn
//   input_scale_s2_per_m: 0.02        # s: the network input is s * a_L, > 0
//   input: accel_error                # the signal the set was trained on: load_accel (a_L, the
//                                     # paper's; the value when the key is absent) or accel_error
//                                     # (a_L - dV_ref/dt)
//   gain_n: 300.0                     # G_n: force = G_n u_n, > 0
//   cost: 5.3                         # cost (23) of this set, >= 0, or -1 when unknown
//   source: "de_trainer seed 1 gen 433"   # free text: where the set comes from
//   weights: [ ... ]                  # JordanRnn::parameter_count(layer_sizes) numbers
//
// weights are in JordanRnn's flat order: layer by layer from the first hidden
// layer; within a layer neuron by neuron; per neuron its incoming weights in
// the order of the previous layer's neurons (external inputs, then the state
// unit, for the first hidden layer), then its bias. Every number must be finite.
// save_rnn_weights() writes the weights with 17 significant digits (the header
// numbers with 15 when those suffice), so that a load reads back the identical
// doubles; it writes one neuron per line.
// Unknown keys, missing or duplicate keys, another format tag, a wrong count,
// non-numeric or non-finite values, and weights beyond +-JordanRnn::kMaxAbsWeight (100:
// beyond it tanh only switches) are errors. The gain and input scale must equal the
// config's compensator.rnn values, which the config bounds (gain 1 mN to 100 kN), and the input
// its compensator.rnn.on_reference_error.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "pmlsm/sim/system_params.hpp"

namespace pmlsm {

struct RnnWeightsFile {
  std::vector<int> layer_sizes;
  double input_scale_s2_per_m = 0;
  bool on_reference_error = false;  ///< input: accel_error (true) or load_accel (false)
  double gain_n = 0;
  double cost = -1;  ///< cost (23) of the set, or -1 when unknown
  std::string source;
  std::vector<double> weights;
};

inline constexpr const char* kRnnWeightsFormat = "pmlsm-rnn-weights/1";

/// Sizes valid (JordanRnn rules), weights.size() == parameter_count(layer_sizes),
/// all values finite, scale and gain > 0, cost >= 0 or == -1.
/// @throws std::invalid_argument naming the field and value ("weights[3]: must be finite, got nan").
void validate_rnn_weights(const RnnWeightsFile& file);

/// @throws pmlsm::ConfigError (a std::runtime_error) naming the file, the key and the
/// value of the first problem: "w.yaml: weights[3]: must be finite, got .nan".
RnnWeightsFile load_rnn_weights(const std::string& path);
/// The same for a text already read; `origin` names it in messages.
RnnWeightsFile parse_rnn_weights(const std::string& text, const std::string& origin);

/// Validates, then writes path + ".tmp", flushes and fsyncs it and renames it
/// over path (atomic: readers see the old or the new file, never a partial one).
/// @throws pmlsm::ConfigError naming the path (invalid content or an I/O error);
/// the .tmp file is removed on failure.
void save_rnn_weights(const std::string& path, const RnnWeightsFile& file);

/// Why a weight set does not fit the network that `params` configure (invalid
/// set, other layer sizes, input scale or gain); empty when it fits. The one
/// check every loader of weights runs (files, the NetworkWeights topic).
std::string rnn_weights_misfit(const RnnWeightsFile& file, const SystemParams& params);

/// Which weight sets a running compensator takes: those that fit (rnn_weights_misfit) and
/// whose version is above the one in use (the first set is taken at any version; a set
/// from a file is version 0).
/// A set with a version not above the one in use is a rollback and refused: a trainer
/// that means to replace a newer set starts its versions above it (de_trainer
/// --first-version). Every offer leaves a log line (version, origin, source, cost, verdict).
class WeightSetGate {
 public:
  explicit WeightSetGate(const SystemParams& params);
  /// "" when taken (version() becomes `version`), otherwise why not.
  /// origin: where the set came from ("the NetworkWeights topic", a file name).
  std::string offer(const RnnWeightsFile& set, std::uint64_t version, const char* origin);
  std::uint64_t version() const { return version_; }
  std::uint64_t taken() const { return taken_; }
  std::uint64_t refused() const { return refused_; }
  /// The line describing the last offer, for the node's log.
  const std::string& last_log() const { return last_log_; }

 private:
  SystemParams params_;
  std::uint64_t version_ = 0;
  std::uint64_t taken_ = 0;
  std::uint64_t refused_ = 0;
  std::string last_log_;
};

}  // namespace pmlsm

// Live parameters: the entries of the system file a running node lets an operator change (its
// gains, its filters), as the paper's rig had them in ControlDesk and ROS 2 has them in
// `ros2 param`. A change is parsed by its entry's kind and checked with the same ranges and the
// same component checks as the file (SystemParams::validate, on the whole system with the change
// in it); a refused change leaves the old value and says why. Each accepted change gets the next
// version and is kept; the node applies the new parameters at its next tick boundary
// (take_pending), so a tick never sees half a change. Pure: no DDS, no threads (the node owns the
// locking and the topics).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "pmlsm/sim/system_params.hpp"

namespace pmlsm {

/// The entry's value as the system file writes it ("10000", "notch", "true").
/// @throws std::invalid_argument "no such parameter" or "a list: ...".
std::string parameter_text(const SystemParams& params, const std::string& key_path);

/// Sets one entry from text, parsed by the entry's kind (a real, a whole number, true/false, one
/// of a choice's names). Only the entry's own kind is checked here, not its range.
/// @throws std::invalid_argument naming the key and what is wrong with the text.
void set_parameter(SystemParams& params, const std::string& key_path, const std::string& text);

struct LiveChange {
  std::uint64_t version = 0;
  std::string key;
  std::string old_value;
  std::string new_value;
};

struct LiveAnswer {
  bool accepted = false;
  std::uint64_t version = 0;  ///< the parameters' version after the request
  std::string value;          ///< the entry's value after the request (the old one when refused)
  std::string reason;         ///< why it was refused ("" when accepted)
};

class LiveParameters {
 public:
  /// @throws std::invalid_argument when a key is not an entry of the table (named).
  LiveParameters(const SystemParams& params, std::vector<std::string> live_keys);

  /// A change request: accepted (the next version) or refused with the reason, the old value kept.
  LiveAnswer set(const std::string& key, const std::string& text);
  /// Several changes taken together (a tuner's result): each parsed by its kind, then the whole
  /// system checked once with all of them in it, so a filter slot's values and its kind can move
  /// in any order. All accepted (one version each, in order) or none, the reason naming the
  /// first key refused; the answer's version is the last one's.
  LiveAnswer set_many(const std::vector<std::pair<std::string, std::string>>& changes);
  /// The entry's value; refused when the key is not one of this node's.
  LiveAnswer get(const std::string& key) const;
  const std::vector<std::string>& keys() const { return keys_; }

  /// At a tick boundary: true once after one or more accepted changes (then apply params()).
  bool take_pending();
  const SystemParams& params() const { return params_; }
  std::uint64_t version() const { return version_; }
  const std::vector<LiveChange>& history() const { return history_; }

 private:
  bool is_live(const std::string& key) const;

  SystemParams params_;
  std::vector<std::string> keys_;
  std::uint64_t version_ = 0;
  bool pending_ = false;
  std::vector<LiveChange> history_;
};

/// The keys the velocity controller (the controller node, the in-process loop) takes live: the
/// PI's gains and every filter slot.
std::vector<std::string> velocity_controller_live_keys();
/// accel_feedback's: its gain K_a.
std::vector<std::string> accel_feedback_live_keys();
/// state_feedback's: the design's ratios and the friction fed forward (SystemParams' model, period,
/// loop and output filter stay for the run).
std::vector<std::string> state_feedback_live_keys();
/// rnn_compensator's: the online rule's settings (the network's shape, scales and weights are not:
/// its weights come live on /pmlsm/network_weights).
std::vector<std::string> rnn_compensator_live_keys();

}  // namespace pmlsm

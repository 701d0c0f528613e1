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

/// Another node's live parameters that this node's own values derive from: state feedback's model
/// of the velocity loop runs on the controller's Kp, so a change of it at the controller must reach
/// the model at the same tick. The owner's accepted changes come as events (ParameterEvent: its
/// version after them and the entries, in order: a SET_MANY of n entries ends at `version`, so
/// its entries hold the n versions before it); the owner's data for a tick says which version it
/// computed that tick with (VelocityReference.parameters_version). At the boundary before a tick,
/// every change up to that version is applied, and the node re-derives its values from
/// overlay(): the dependent computes the tick with the values its owner used. A version the
/// owner ran with but whose event has not arrived is `missing` (a lockstep node waits for it; a
/// realtime one goes on and applies it when it comes, late). An owner whose version went back has
/// restarted from its file: its changes are dropped. Pure: the node owns the topics.
class FollowedParameters {
 public:
  /// `params`: the system as loaded (the owner's version 0), to check offered entries against.
  FollowedParameters(std::string owner, const SystemParams& params);

  /// An accepted change of the owner: its version after the change and the (key, new value)
  /// entries in the order they were taken. Versions already offered are ignored (a repeated
  /// answer). @return "" or why it was not taken (an entry not of the table or not parsed by its
  /// kind, a version that leaves a gap below it).
  std::string offer(std::uint64_t version, const std::vector<std::pair<std::string, std::string>>& entries);

  struct Step {
    bool changed = false;          ///< followed values changed from this tick: re-derive from overlay()
    bool missing = false;          ///< the owner computed this tick with a version not offered yet
    bool owner_restarted = false;  ///< the owner's version went back: its earlier changes dropped
  };
  /// At the boundary before a tick the owner computed with `owner_version`. The changes applied
  /// are in applied_now() until the next call.
  Step at_tick(std::uint64_t owner_version);
  /// Writes the owner's values applied so far over `params` (this node's own, with its own changes).
  void overlay(SystemParams& params) const;

  const std::string& owner() const { return owner_; }
  std::uint64_t applied_version() const { return applied_version_; }
  /// The highest version offered without a gap below it.
  std::uint64_t offered_version() const { return offered_version_; }
  const std::vector<LiveChange>& applied_now() const { return applied_now_; }

 private:
  std::string owner_;
  SystemParams start_;
  std::vector<LiveChange> pending_;                          ///< offered, not applied yet; versions increasing
  std::vector<std::pair<std::string, std::string>> values_;  ///< key -> the owner's value applied
  std::vector<LiveChange> applied_now_;
  std::uint64_t applied_version_ = 0;
  std::uint64_t offered_version_ = 0;
};

/// The keys `node` takes live, in the table's order: the entries that name it as theirs
/// (Plausible::live_at and choice's live_at in visit_parameters, pmlsm/sim/system_params.hpp).
/// The controller: the PI's gains and every filter slot; accel_feedback: its K_a; state_feedback:
/// the design's ratios and the friction fed forward; rnn_compensator: its online rule's settings
/// and output scale (its weights come live on /pmlsm/network_weights); a component added in its
/// own folder: the entries its section declares live. None for another name.
std::vector<std::string> live_keys(const SystemParams& params, const std::string& node);

}  // namespace pmlsm

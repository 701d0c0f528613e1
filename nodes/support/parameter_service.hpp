// A node's live parameters on DDS: ParameterRequest in (addressed by node name, "" or "*": every
// node), ParameterEvent out (the answer, and the record of every change: recordings keep it). The
// node calls serve() at each tick boundary; a change the checks accept is applied from that tick
// on (LiveParameters, pmlsm/sim/live_parameters.hpp). A request repeated with the same request_id
// (a requester resending until it hears back) is answered again, not applied twice. `pmlsm param`
// is the operator's end.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "ParameterEventPubSubTypes.h"
#include "ParameterRequestPubSubTypes.h"
#include "node_support.hpp"
#include "pmlsm/sim/live_parameters.hpp"

namespace pmlsm::node {

class ParameterService {
 public:
  /// `live` must outlive the service. @throws std::runtime_error from DDS.
  ParameterService(NodeRuntime& rt, std::string node_name, LiveParameters& live);

  /// Answers every request that arrived, at the boundary before tick `tick`. @return true when a
  /// change was accepted: the node applies live.params() before computing the tick.
  bool serve(std::uint64_t tick);
  std::uint64_t requests() const { return requests_; }
  std::uint64_t refused() const { return refused_; }

 private:
  void answer(std::uint64_t tick);
  /// SET_MANY: the request's "key = value" entries taken together; the event lists the changes.
  LiveAnswer set_many(std::uint64_t tick, const std::string& requester);
  void list_into(pmlsm_msgs::msg::ParameterEvent& event) const;

  NodeRuntime& rt_;
  std::string node_name_;
  LiveParameters& live_;
  dds::Reader<pmlsm_msgs::msg::ParameterRequestPubSubType> reader_;
  dds::Writer<pmlsm_msgs::msg::ParameterEventPubSubType> writer_;
  pmlsm_msgs::msg::ParameterRequest request_;
  pmlsm_msgs::msg::ParameterEvent event_;
  /// The last answers, by request_id, for requests repeated by their requester.
  std::array<pmlsm_msgs::msg::ParameterEvent, 8> answered_;
  std::size_t next_answered_ = 0;
  std::uint64_t requests_ = 0;
  std::uint64_t refused_ = 0;
  bool applied_ = false;
};

/// Another node's live changes this node derives values from, on DDS (FollowedParameters,
/// pmlsm/sim/live_parameters.hpp): the owner's accepted changes read from ParameterEvent, applied
/// at the tick the owner computed with them (VelocityReference.parameters_version). In lockstep a
/// change the owner made but whose event has not arrived is not there yet: the tick waits for it
/// (the owner wrote the event before that tick's data, so it is on its way); in realtime the tick
/// goes on with the old values and the change applies when it arrives, said late.
class ParameterFollower {
 public:
  /// @throws std::runtime_error from DDS.
  ParameterFollower(NodeRuntime& rt, std::string node_name, std::string owner, const SystemParams& params);

  enum class Result { kSame, kChanged, kNotYet };
  /// At the boundary before `tick`, which the owner computed with `owner_version`; never waits.
  /// kChanged: the followed values changed from this tick (overlay them on the node's own and
  /// re-derive); kNotYet: lockstep only, the owner's change has not arrived (ask again when the
  /// inputs move).
  Result at_tick(std::uint64_t tick, std::uint64_t owner_version);
  /// After kNotYet for the peer timeout: the line saying which change of the owner's never came.
  void report_not_heard(std::uint64_t tick, std::uint64_t owner_version, double timeout_s) const;
  /// The owner's values applied so far written over `params`.
  void overlay(SystemParams& params) const { followed_.overlay(params); }

 private:
  void take();

  NodeRuntime& rt_;
  std::string node_name_;
  FollowedParameters followed_;
  dds::Reader<pmlsm_msgs::msg::ParameterEventPubSubType> reader_;
  pmlsm_msgs::msg::ParameterEvent event_;
  std::vector<std::pair<std::string, std::string>> entries_;
  std::uint64_t behind_since_tick_ = 0;
  bool behind_ = false;
};

}  // namespace pmlsm::node

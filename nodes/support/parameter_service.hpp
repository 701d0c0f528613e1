// A node's live parameters on DDS: ParameterRequest in (addressed by node name, "" or "*": every
// node), ParameterEvent out (the answer, and the record of every change: recordings keep it). The
// node calls serve() at each tick boundary; a change the checks accept is applied from that tick
// on (LiveParameters, pmlsm/sim/live_parameters.hpp). A request repeated with the same request_id
// (a requester resending until it hears back) is answered again, not applied twice. `pmlsm param`
// is the operator's end.
#pragma once

#include <array>
#include <cstdint>
#include <string>

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

}  // namespace pmlsm::node

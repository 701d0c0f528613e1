// PlantTruth of the virtual drive's lockstep periods for the evaluator (never read by a
// controller), stamped with the bridge's run (its latched DriveState).
#pragma once

#include <cstdint>
#include <vector>

#include "DriveStatePubSubTypes.h"
#include "PlantTruthPubSubTypes.h"
#include "node_support.hpp"
#include "pmlsm/sim/simulated_drive.hpp"

namespace pmlsm::node {

/// PlantTruth of the lockstep periods, stamped with the bridge's run (its latched DriveState).
/// Held until the evaluator matched and the run id is known; the buffer is reserved for the
/// whole scenario at construction, so the tick loop never allocates.
class TruthPublisher {
 public:
  TruthPublisher(NodeRuntime& rt, std::uint64_t ticks);

  /// The truth of tick `tick` (the drive's periods since the run began).
  void add(std::uint64_t tick, const SimulatedDrive& drive, double applied_force_n);
  /// Sends what is held once it can be stamped and heard.
  void flush();
  /// Ticks added and not yet sent (no run id or no reader yet).
  std::uint64_t held() const { return queued_; }
  /// At the end: says what was never sent, then waits for the acknowledgments of what was.
  void finish();

  std::uint64_t published() const { return published_; }
  std::uint64_t dropped() const { return dropped_; }

 private:
  NodeRuntime& rt_;
  dds::Writer<pmlsm_msgs::msg::PlantTruthPubSubType> writer_;
  dds::Reader<pmlsm_msgs::msg::DriveStatePubSubType> state_reader_;
  pmlsm_msgs::msg::DriveState state_;
  std::vector<pmlsm_msgs::msg::PlantTruth> pending_;
  std::uint64_t published_ = 0;
  std::uint64_t queued_ = 0;
  std::uint64_t dropped_ = 0;
  std::uint64_t run_id_ = 0;
};

}  // namespace pmlsm::node

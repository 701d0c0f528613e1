#include "truth_publisher.hpp"

#include <cstdio>

#include "msg_mapping.hpp"

namespace pmlsm::node {

namespace msg = pmlsm_msgs::msg;

TruthPublisher::TruthPublisher(NodeRuntime& rt, std::uint64_t ticks)
    : rt_(rt),
      writer_(rt.participant.make_writer(dds::topics::kPlantTruth)),
      state_reader_(rt.participant.make_reader(dds::topics::kDriveState, rt.wakeup)) {
  pending_.resize(ticks + 1);
}

void TruthPublisher::add(std::uint64_t tick, const SimulatedDrive& drive, double applied_force_n) {
  if (tick < published_ + queued_ || queued_ + published_ >= pending_.size()) {
    ++dropped_;  // a tick already held (a repeated answer) or beyond the scenario
    return;
  }
  msg::PlantTruth& t = pending_[queued_ + published_];
  to_msg(drive.plant().truth(), {applied_force_n, drive.last_u_d_v(), drive.last_u_q_v()}, t);
  t.stamp(make_stamp(tick, rt_.period_s, 0));
  ++queued_;
}

void TruthPublisher::flush() {
  while (state_reader_.take(state_)) {
    if (state_.stamp().run_id() != 0) run_id_ = state_.stamp().run_id();
  }
  if (queued_ == 0 || run_id_ == 0 || writer_.matched_readers() == 0) return;
  for (; queued_ > 0; --queued_, ++published_) {
    msg::PlantTruth& t = pending_[published_];
    t.stamp().run_id(run_id_);
    writer_.write(t);
  }
}

void TruthPublisher::finish() {
  flush();
  if (queued_ > 0) {
    std::fprintf(stderr, "virtual_drive: %llu PlantTruth samples never sent (%s)\n",
                 static_cast<unsigned long long>(queued_),
                 run_id_ == 0 ? "no DriveState of the bridge: run id unknown" : "no PlantTruth reader");
  }
  writer_.wait_for_acknowledgments(kFlushTimeout);
}

}  // namespace pmlsm::node

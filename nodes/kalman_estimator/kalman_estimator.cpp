// kalman_estimator: the Kalman filter of section 3.5 on DDS. For every
// MotorFeedback tick k it predicts with the force the drive applied over the
// last tick (MotorFeedback.applied_force_n, u_{k-1}; plus the modelled friction
// and ripple of that tick, from the encoder velocity and position, when
// kalman.friction_input / ripple_input are enabled) and updates with the
// measured motor velocity, then publishes EstimatedState (v_M, v_L, F_s, a_L,
// and the input u the prediction used). The in-process loop feeds the filter
// the same three values, so the traces are identical.
#include <chrono>
#include <cmath>
#include <cstdio>

#include "EstimatedStatePubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "msg_mapping.hpp"
#include "kalman_estimator_command_line.hpp"
#include "cycle_component.hpp"
#include "node_support.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/estimation/kalman_filter.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;

class KalmanEstimatorComponent final : public node::CycleComponent {
 public:
  /// estimate_readers: EstimatedState readers to wait for before the first estimate (0: at once).
  KalmanEstimatorComponent(const node::ComponentContext& context, node::CommonOptions common, int estimate_readers)
      : common_(std::move(common)),
        rt_("kalman_estimator", common_, context),
        period_s_(rt_.period_s),
        ticks_(scenario_ticks(rt_.cfg.scenario, period_s_)),
        // Deep history: the estimator is off the chain and may fall behind, yet must see every
        // tick (best effort only when asked, across a network in realtime).
        feedback_reader_(rt_.participant.make_reader(pdds::topics::kMotorFeedback, rt_.wakeup,
                                                     node::chain_input_profile(rt_.cfg, pdds::kObserverProfile))),
        estimate_writer_(rt_.participant.make_writer(pdds::topics::kEstimatedState)),
        filter_(rt_.cfg.params.kalman_params()),
        estimate_readers_(estimate_readers),
        feedback_follower_("kalman_estimator", common_, rt_.cfg.clock, ticks_, period_s_) {}

 private:
  void activate() override {
    if (estimate_readers_ > 0) {
      rt_.status.publish(node_state::STATE_WAITING, 0, period_s_, "waiting for readers");
    } else {
      start_running();
    }
  }

  Update update() override {
    // A drive that runs a short scenario fast can be done before an observer's EstimatedState
    // reader matched; the estimates written before the match would then reach nobody.
    if (!running_) {
      if (estimate_writer_.matched_readers() < static_cast<std::size_t>(estimate_readers_)) return Update::waiting();
      start_running();
      return Update::worked();
    }
    if (next_tick_ >= ticks_) return Update::finished(kExitOk);
    const auto next =
        feedback_follower_.try_next(feedback_reader_, feedback_, next_tick_, period_s_, rt_.status, rejected_);
    if (next == node::FeedbackFollower::Next::kNone) return Update::waiting();
    if (next == node::FeedbackFollower::Next::kEnded) return Update::finished(feedback_follower_.exit_code());
    if (next == node::FeedbackFollower::Next::kNewRun) filter_.reset();  // the estimate belonged to the old run
    const std::uint64_t k = feedback_.stamp().tick();
    estimate(k);
    next_tick_ = k + 1;
    return Update::worked();
  }

  std::chrono::duration<double> input_timeout() const override {
    return running_ ? feedback_follower_.timeout() : std::chrono::duration<double>(common_.peer_timeout_s);
  }

  int inputs_lost() override {
    if (!running_) {
      std::fprintf(stderr, "kalman_estimator: readers missing after %.1f s: %zu of %d EstimatedState readers\n",
                   common_.peer_timeout_s, estimate_writer_.matched_readers(), estimate_readers_);
      return kExitPeerMissing;
    }
    return feedback_follower_.lost(next_tick_, period_s_, rt_.status);
  }

  int finish(int exit_code) override {
    const auto& c = filter_.counters();
    rt_.status.status().rejected(rejected_ + c.rejected_measurements + c.rejected_inputs);
    rt_.status.publish(node_state::STATE_STOPPING, next_tick_, period_s_, "done");
    estimate_writer_.wait_for_acknowledgments(node::flush_timeout(exit_code));
    std::printf("kalman_estimator: %llu ticks, %llu rejected\n", static_cast<unsigned long long>(next_tick_),
                static_cast<unsigned long long>(rejected_ + c.rejected_measurements + c.rejected_inputs));
    const LoadSensorMonitor& load = filter_.load_monitor();
    if (load.failed()) {
      std::fprintf(stderr,
                   "kalman_estimator: the load's sensor failed at tick %llu: %s; the estimate is the motor's "
                   "encoder's alone from then on (%llu readings refused in all)\n",
                   static_cast<unsigned long long>(load.failed_at_tick()), to_string(load.fault()),
                   static_cast<unsigned long long>(load.rejected()));
    } else if (load.rejected() > 0) {
      std::printf("kalman_estimator: the load's sensor: %llu readings refused\n",
                  static_cast<unsigned long long>(load.rejected()));
    }
    return exit_code;
  }

  pdds::Wakeup& wakeup() override { return rt_.wakeup; }

  void start_running() {
    running_ = true;
    rt_.status.publish(node_state::STATE_RUNNING, 0, period_s_, "running");
  }

  void estimate(std::uint64_t k) {
    // The filter itself rejects (and counts) a non-finite measurement or input.
    node::from_msg(feedback_, input_);
    node::to_msg(filter_.step(input_), k, estimate_);
    estimate_.stamp(node::make_stamp(k, period_s_, feedback_follower_.run().current()));  // the run it follows
    estimate_writer_.write(estimate_);
  }

  node::CommonOptions common_;
  node::NodeRuntime rt_;
  double period_s_;
  std::uint64_t ticks_;
  pdds::Reader<msg::MotorFeedbackPubSubType> feedback_reader_;
  pdds::Writer<msg::EstimatedStatePubSubType> estimate_writer_;
  KalmanFilter filter_;
  int estimate_readers_;
  node::FeedbackFollower feedback_follower_;
  bool running_ = false;

  msg::MotorFeedback feedback_;
  msg::EstimatedState estimate_;
  KalmanInput input_;
  std::uint64_t next_tick_ = 0;  // ticks up to here are done
  std::uint64_t rejected_ = 0;
};

}  // namespace

namespace pmlsm::node {

PMLSM_COMPONENT(kalman_estimator, make_kalman_estimator, 1);

MadeComponent make_kalman_estimator(const ComponentContext& context, int argc, char** argv) {
  CommonOptions common;
  common.spin_us = 0.0;
  int estimate_readers = 0;
  if (const auto code = parse_kalman_estimator_command_line(argc, argv, common, estimate_readers)) {
    return {nullptr, *code};
  }
  return {std::make_unique<KalmanEstimatorComponent>(context, std::move(common), estimate_readers)};
}

}  // namespace pmlsm::node

// kalman_estimator: the Kalman filter of section 3.5 on DDS. For every
// MotorFeedback tick k it predicts with the force the drive applied over the
// last tick (MotorFeedback.applied_force_n, u_{k-1}; plus the modelled friction
// and ripple of that tick, from the encoder velocity and position, when
// kalman.friction_input / ripple_input are enabled) and updates with the
// measured motor velocity, then publishes EstimatedState (v_M, v_L, F_s, a_L,
// and the input u the prediction used). The in-process loop feeds the filter
// the same three values, so the traces are identical.
#include <cmath>
#include <cstdio>

#include "EstimatedStatePubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "msg_mapping.hpp"
#include "node_support.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/estimation/kalman_filter.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;

int run(int argc, char** argv) {
  CLI::App app{"Kalman estimator of the load velocity and spring force on DDS"};
  node::CommonOptions common;
  common.spin_us = 0.0;
  node::add_common_options(app, common);
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  node::NodeRuntime rt("kalman_estimator", common);
  const node::LoadedConfig& cfg = rt.cfg;
  const double period = rt.period_s;
  // Deep history: the estimator is off the lockstep chain and may fall behind;
  // it must still see every tick.
  auto feedback_reader = rt.participant.make_reader<pmlsm_msgs::msg::MotorFeedbackPubSubType>(
      pdds::topics::kMotorFeedback, rt.wakeup, pdds::kObserverProfile);
  auto estimate_writer = rt.participant.make_writer<pmlsm_msgs::msg::EstimatedStatePubSubType>(pdds::topics::kEstimatedState);

  KalmanFilter filter(cfg.params.kalman_params());
  const std::uint64_t ticks = scenario_ticks(cfg.scenario, period);
  rt.status.publish(node_state::STATE_RUNNING, 0, period, "running");

  pmlsm_msgs::msg::MotorFeedback feedback;
  pmlsm_msgs::msg::EstimatedState estimate;
  KalmanInput input;
  std::uint64_t next_tick = 0;  // ticks up to here are done
  node::TickFilter tick_filter;
  node::RunFollower run;
  bool new_run = false;
  std::uint64_t rejected = 0;
  int exit_code = kExitOk;

  bool any_feedback = false;
  while (next_tick < ticks && !pdds::stop_requested()) {
    const bool ok = node::take_next_tick(rt.wakeup, feedback_reader, feedback, tick_filter, run, new_run, rejected,
                                         node::feedback_timeout(common, cfg.clock, any_feedback));
    if (!ok) {
      exit_code =
          node::end_of_feedback_wait("kalman_estimator", common, cfg.clock, any_feedback, next_tick, period, rt.status);
      break;
    }
    any_feedback = true;
    if (new_run && run.restarts() > 0) {
      // The drive restarted: the estimate belongs to the old run; start afresh as at start-up.
      std::printf("kalman_estimator: the drive restarted (run %016llx -> %016llx) at its tick %llu: "
                  "following the new run\n",
                  static_cast<unsigned long long>(run.previous()), static_cast<unsigned long long>(run.current()),
                  static_cast<unsigned long long>(feedback.stamp().tick()));
      filter.reset();
      rt.status.publish(node_state::STATE_RUNNING, feedback.stamp().tick(), period, "drive restarted: new run followed");
    }
    const std::uint64_t k = feedback.stamp().tick();
    // The filter itself rejects (and counts) a non-finite measurement or input.
    node::from_msg(feedback, input);
    node::to_msg(filter.step(input), k, estimate);
    estimate.stamp(node::make_stamp(k, period, run.current()));  // the run this estimate follows
    estimate_writer.write(estimate);
    next_tick = k + 1;
  }
  const auto& c = filter.counters();
  rt.status.status().rejected(rejected + c.rejected_measurements + c.rejected_inputs);
  rt.status.publish(node_state::STATE_STOPPING, next_tick, period, "done");
  estimate_writer.wait_for_acknowledgments(node::flush_timeout(exit_code));
  std::printf("kalman_estimator: %llu ticks, %llu rejected\n", static_cast<unsigned long long>(next_tick),
              static_cast<unsigned long long>(rejected + c.rejected_measurements + c.rejected_inputs));
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  return pmlsm::node::run_node("kalman_estimator", [&] { return run(argc, argv); });
}

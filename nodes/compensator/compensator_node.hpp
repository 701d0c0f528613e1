// What the compensator nodes (rnn_compensator, accel_feedback, state_feedback) share: they
// read EstimatedState and VelocityReference, pair them by tick, and answer
// every tick k with CompensatorOutput k. The controller applies output k at
// tick k+1 (see run_compensated in pmlsm/sim/closed_loop.hpp), so both clocks work
// and the distributed lockstep trace equals the in-process one.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <stdexcept>

#include "CompensatorOutputPubSubTypes.h"
#include "EstimatedStatePubSubTypes.h"
#include "VelocityReferencePubSubTypes.h"
#include "msg_mapping.hpp"
#include "node_support.hpp"
#include "parameter_service.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/live_parameters.hpp"

namespace pmlsm::node {

/// Pairs EstimatedState and VelocityReference of the same tick, in tick order.
/// Older or duplicate ticks are rejected (counted); a tick missing on one topic
/// is skipped (counted) once the other topic has moved past it.
class CompensatorInputs {
 public:
  CompensatorInputs(dds::Participant& participant, dds::Wakeup& wakeup, const LoadedConfig& cfg)
      : wakeup_(wakeup),
        estimate_reader_(participant.make_reader(dds::topics::kEstimatedState, wakeup,
                                                 chain_input_profile(cfg, dds::kObserverProfile))),
        reference_reader_(participant.make_reader(dds::topics::kVelocityReference, wakeup,
                                                  chain_input_profile(cfg, dds::kObserverProfile))),
        end_watch_(scenario_ticks(cfg.scenario, cfg.params.timing.control_period_s), cfg.params.timing.control_period_s,
                   cfg.clock == Clock::kRealtime) {}

  /// Waits for the next complete tick. False on timeout, on stop, or when an input's writers left
  /// after running to the end and the run's last ticks were lost (end_of_wait says which).
  /// The drive run the last estimate followed (stamped on the output, so it follows the same run).
  std::uint64_t run_id() const { return estimate_.stamp().run_id(); }
  /// The controller's live-parameter version the last paired tick was computed with.
  std::uint64_t parameters_version() const { return parameters_version_; }

  bool next(std::chrono::duration<double> timeout, std::uint64_t& tick, CompensatorView& view) {
    return wait_until(wakeup_, timeout, [&] {
      for (;;) {
        if (!have_estimate_) have_estimate_ = take_from(estimate_reader_, estimate_);
        if (!have_reference_) have_reference_ = take_from(reference_reader_, reference_);
        if (!have_estimate_ || !have_reference_) {
          // The input still missing its tick had its writers leave: the run may be over.
          const std::size_t writers =
              have_estimate_ ? reference_reader_.matched_writers() : estimate_reader_.matched_writers();
          tail_lost_ = end_watch_.tail_lost(writers, next_tick_, monotonic_ns());
          return false;
        }
        const std::uint64_t e = estimate_.feedback_tick();
        const std::uint64_t r = reference_.stamp().tick();
        if (e == r) break;
        // One topic skipped a tick: drop the older sample.
        ++skipped_;
        if (e < r)
          have_estimate_ = false;
        else
          have_reference_ = false;
      }
      tick = reference_.stamp().tick();
      view.load_accel_mps2 = estimate_.a_load_mps2();
      view.v_load_mps = estimate_.v_load_mps();
      view.v_ref_mps = reference_.v_ref_mps();
      view.spring_force_n = estimate_.spring_force_n();
      view.command_mps = reference_.velocity_command_mps();
      view.a_ref_mps2 = reference_.a_ref_mps2();
      parameters_version_ = reference_.parameters_version();
      have_estimate_ = have_reference_ = false;
      next_tick_ = tick + 1;
      end_watch_.taken(monotonic_ns());
      return true;
    });
  }

  /// After next() returned false: exit 0 when the inputs ended with the run (the last ticks lost
  /// on a best-effort link, said on stdout), else end_of_failed_wait's code and line.
  int end_of_wait(const char* node_name, std::uint64_t answered, double timeout_s) const {
    if (tail_lost_ && !dds::stop_requested()) {
      std::printf(
          "%s: the EstimatedState or VelocityReference writer left after running to the end; the run's last "
          "%llu tick(s) never arrived (lost on a best-effort input)\n",
          node_name, static_cast<unsigned long long>(end_watch_.missing(next_tick_)));
      return kExitOk;
    }
    return end_of_failed_wait(node_name, "EstimatedState and VelocityReference", "estimator or controller", answered,
                              timeout_s);
  }

  std::uint64_t rejected() const { return rejected_; }
  std::uint64_t skipped() const { return skipped_; }

 private:
  template <typename ReaderT, typename Message>
  bool take_from(ReaderT& reader, Message& sample) {
    while (reader.take(sample)) {
      if (tick_of(sample) < next_tick_) {
        ++rejected_;
        continue;
      }
      return true;
    }
    return false;
  }
  static std::uint64_t tick_of(const pmlsm_msgs::msg::EstimatedState& m) { return m.feedback_tick(); }
  static std::uint64_t tick_of(const pmlsm_msgs::msg::VelocityReference& m) { return m.stamp().tick(); }

  dds::Wakeup& wakeup_;
  dds::Reader<pmlsm_msgs::msg::EstimatedStatePubSubType> estimate_reader_;
  dds::Reader<pmlsm_msgs::msg::VelocityReferencePubSubType> reference_reader_;
  pmlsm_msgs::msg::EstimatedState estimate_;
  pmlsm_msgs::msg::VelocityReference reference_;
  bool have_estimate_ = false;
  bool have_reference_ = false;
  std::uint64_t next_tick_ = 0;
  std::uint64_t parameters_version_ = 0;
  std::uint64_t rejected_ = 0;
  std::uint64_t skipped_ = 0;
  InputEndWatch end_watch_;
  bool tail_lost_ = false;
};

/// What run_fixed_law did: the node's exit code and the ticks it answered.
struct CompensatorLoopResult {
  int exit_code = kExitOk;
  std::uint64_t answered = 0;
};

using CompensatorWriter = dds::Writer<pmlsm_msgs::msg::CompensatorOutputPubSubType>;

/// The loop of a compensator whose law is fixed for the run (accel_feedback, state_feedback), its
/// gains live: publishes NodeStatus running, then answers every paired tick k with
/// CompensatorOutput k (force_of(view), u = force / force_limit_n, the training error
/// V_ref - v_L) until the scenario's ticks are answered, a stop is requested, or the inputs stop
/// coming for the peer timeout (end_of_failed_wait's exit code). Before each tick it serves the
/// parameter requests that arrived (`pmlsm param`) and, with a `follower`, takes the controller's
/// changes the controller computed this tick with; either reaches the law through
/// retune(its own live parameters with the controller's over them) before that tick's force. A
/// retune the law refuses keeps the old values and is said; the writer is flushed before it
/// returns.
template <typename ForceOf, typename Retune>
CompensatorLoopResult run_fixed_law(const char* node_name, NodeRuntime& rt, const CommonOptions& common,
                                    CompensatorInputs& inputs, CompensatorWriter& writer, double force_limit_n,
                                    ParameterService& parameters, const LiveParameters& live,
                                    ParameterFollower* follower, ForceOf&& force_of, Retune&& retune) {
  const std::uint64_t ticks = scenario_ticks(rt.cfg.scenario, rt.period_s);
  rt.status.publish(pmlsm_msgs::msg::NodeStatus_Constants::STATE_RUNNING, 0, rt.period_s, "running");
  pmlsm_msgs::msg::CompensatorOutput out;
  CompensatorStep step;
  CompensatorLoopResult result;
  std::uint64_t tick = 0;
  CompensatorView view;
  while (result.answered < ticks && !dds::stop_requested()) {
    if (!inputs.next(std::chrono::duration<double>(common.peer_timeout_s), tick, view)) {
      result.exit_code = inputs.end_of_wait(node_name, result.answered, common.peer_timeout_s);
      break;
    }
    bool changed = parameters.serve(tick);
    if (follower != nullptr) {
      const auto followed =
          follower->at_tick(tick, inputs.parameters_version(), std::chrono::duration<double>(common.peer_timeout_s));
      if (followed == ParameterFollower::Result::kMissing) {
        result.exit_code = dds::stop_requested() ? kExitOk : kExitPeerLost;
        break;
      }
      changed = changed || followed == ParameterFollower::Result::kChanged;
    }
    if (changed) {
      SystemParams now = live.params();
      if (follower != nullptr) follower->overlay(now);
      try {
        retune(now);
      } catch (const std::invalid_argument& e) {
        std::fprintf(stderr, "%s: tick %llu: parameters not taken, the old ones kept: %s\n", node_name,
                     static_cast<unsigned long long>(tick), e.what());
      }
    }
    step.force_n = force_of(view);
    step.u_n = step.force_n / force_limit_n;
    step.training_error_mps = view.v_ref_mps - view.v_load_mps;
    to_msg(step, pmlsm_msgs::msg::CompensatorOutput_Constants::FLAG_ENABLED, tick, 0, out);
    out.stamp(make_stamp(tick, rt.period_s, inputs.run_id()));
    writer.write(out);
    result.answered = tick + 1;
  }
  writer.wait_for_acknowledgments(flush_timeout(result.exit_code));
  return result;
}

}  // namespace pmlsm::node

// What the compensator nodes (rnn_compensator, accel_feedback, state_feedback and the laws in
// compensators/) share: they read EstimatedState and VelocityReference, pair them by tick, and
// answer every tick k with CompensatorOutput k. The controller applies output k at
// tick k+1 (see run_compensated in pmlsm/sim/closed_loop.hpp), so both clocks work
// and the distributed lockstep trace equals the in-process one.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <stdexcept>

#include "CompensatorOutputPubSubTypes.h"
#include "EstimatedStatePubSubTypes.h"
#include "VelocityReferencePubSubTypes.h"
#include "msg_mapping.hpp"
#include "node_support.hpp"
#include "cycle_component.hpp"
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
      : estimate_reader_(participant.make_reader(dds::topics::kEstimatedState, wakeup,
                                                 chain_input_profile(cfg, dds::kObserverProfile))),
        reference_reader_(participant.make_reader(dds::topics::kVelocityReference, wakeup,
                                                  chain_input_profile(cfg, dds::kObserverProfile))),
        end_watch_(scenario_ticks(cfg.scenario, cfg.params.timing.control_period_s), cfg.params.timing.control_period_s,
                   cfg.clock == Clock::kRealtime) {}

  /// The drive run the last estimate followed (stamped on the output, so it follows the same run).
  std::uint64_t run_id() const { return estimate_.stamp().run_id(); }
  /// The controller's live-parameter version the last paired tick was computed with.
  std::uint64_t parameters_version() const { return parameters_version_; }

  enum class Take {
    kTick,   ///< the next complete tick is in `tick` and `view`
    kNone,   ///< not complete yet
    kEnded,  ///< an input's writers left after running to the end, and the run's last ticks were lost
  };

  /// Takes the next complete tick if it has arrived; never waits.
  Take try_next(std::uint64_t& tick, CompensatorView& view) {
    for (;;) {
      if (!have_estimate_) have_estimate_ = take_from(estimate_reader_, estimate_);
      if (!have_reference_) have_reference_ = take_from(reference_reader_, reference_);
      if (!have_estimate_ || !have_reference_) {
        // The input still missing its tick had its writers leave: the run may be over.
        const std::size_t writers =
            have_estimate_ ? reference_reader_.matched_writers() : estimate_reader_.matched_writers();
        tail_lost_ = end_watch_.tail_lost(writers, next_tick_, monotonic_ns());
        return tail_lost_ ? Take::kEnded : Take::kNone;
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
    return Take::kTick;
  }

  /// After try_next() said kEnded: exit 0, the lost ticks said on stdout. After the inputs did not
  /// come for the peer timeout: end_of_failed_wait's code and line.
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

using CompensatorWriter = dds::Writer<pmlsm_msgs::msg::CompensatorOutputPubSubType>;

/// A compensator whose law is fixed for the run (accel_feedback, state_feedback, the laws in
/// compensators/), its gains live, as a cycle (cycle_component.hpp): activated, it publishes
/// NodeStatus running; each update answers the next paired tick k with CompensatorOutput k
/// (force(view), u = force / the velocity loop's force limit, the training error V_ref - v_L)
/// until the scenario's ticks are answered. Before each tick it serves the parameter requests
/// that arrived (`pmlsm param`) and, following an owner, takes the owner's changes the owner
/// computed this tick with (in lockstep the tick waits for them: the update says kWaiting);
/// either reaches the law through retune(its own live parameters with the owner's over them)
/// before that tick's force. A retune the law refuses keeps the old values and is said. At the
/// end the writer is flushed and report() says what it did.
class FixedLawComponent : public CycleComponent {
 protected:
  /// `followed_owner`: the node whose live parameters the law derives values from, or nullptr.
  FixedLawComponent(const char* node_name, const ComponentContext& context, CommonOptions common,
                    const char* followed_owner = nullptr)
      : node_name_(node_name),
        common_(std::move(common)),
        rt_(node_name, common_, context),
        inputs_(rt_.participant, rt_.wakeup, rt_.cfg),
        writer_(rt_.participant.make_writer(dds::topics::kCompensatorOutput)),
        live_(rt_.cfg.params, live_keys(rt_.cfg.params, node_name)),
        parameters_(rt_, node_name, live_),
        force_limit_n_(rt_.cfg.params.velocity_loop.force_limit_n),
        ticks_(scenario_ticks(rt_.cfg.scenario, rt_.period_s)) {
    if (followed_owner != nullptr) follower_.emplace(rt_, node_name, followed_owner, rt_.cfg.params);
  }

  /// The law's force for the view of a tick [N]; never throws.
  virtual double force(const CompensatorView& view) = 0;
  /// Live parameters at a tick boundary. @throws std::invalid_argument (the old ones kept).
  virtual void retune(const SystemParams& params) = 0;
  /// Its summary line on stdout and its NodeStatus rejected count, after `answered` ticks.
  virtual void report(std::uint64_t answered) = 0;

  const char* node_name_;
  CommonOptions common_;
  NodeRuntime rt_;
  CompensatorInputs inputs_;
  CompensatorWriter writer_;
  LiveParameters live_;
  ParameterService parameters_;
  std::optional<ParameterFollower> follower_;
  const double force_limit_n_;  ///< the velocity loop's: u = force / it

 private:
  void activate() final {
    rt_.status.publish(pmlsm_msgs::msg::NodeStatus_Constants::STATE_RUNNING, 0, rt_.period_s, "running");
  }

  Update update() final {
    if (!holding_) {
      if (answered_ >= ticks_) return Update::finished(kExitOk);
      switch (inputs_.try_next(tick_, view_)) {
        case CompensatorInputs::Take::kNone: return Update::waiting();
        case CompensatorInputs::Take::kEnded:
          return Update::finished(inputs_.end_of_wait(node_name_, answered_, common_.peer_timeout_s));
        case CompensatorInputs::Take::kTick: break;
      }
      changed_ = parameters_.serve(tick_);
      holding_ = true;
    }
    if (follower_) {
      const auto followed = follower_->at_tick(tick_, inputs_.parameters_version());
      if (followed == ParameterFollower::Result::kNotYet) return Update::waiting();
      changed_ = changed_ || followed == ParameterFollower::Result::kChanged;
    }
    holding_ = false;
    if (changed_) {
      SystemParams now = live_.params();
      if (follower_) follower_->overlay(now);
      try {
        retune(now);
      } catch (const std::invalid_argument& e) {
        std::fprintf(stderr, "%s: tick %llu: parameters not taken, the old ones kept: %s\n", node_name_,
                     static_cast<unsigned long long>(tick_), e.what());
      }
    }
    step_.force_n = force(view_);
    step_.u_n = step_.force_n / force_limit_n_;
    step_.training_error_mps = view_.v_ref_mps - view_.v_load_mps;
    to_msg(step_, pmlsm_msgs::msg::CompensatorOutput_Constants::FLAG_ENABLED, tick_, 0, out_);
    out_.stamp(make_stamp(tick_, rt_.period_s, inputs_.run_id()));
    writer_.write(out_);
    answered_ = tick_ + 1;
    return Update::worked();
  }

  std::chrono::duration<double> input_timeout() const final {
    return std::chrono::duration<double>(common_.peer_timeout_s);
  }

  int inputs_lost() final {
    // Holding a tick: what did not come is the owner's change it was computed with.
    if (holding_ && follower_) {
      follower_->report_not_heard(tick_, inputs_.parameters_version(), common_.peer_timeout_s);
      return kExitPeerLost;
    }
    return inputs_.end_of_wait(node_name_, answered_, common_.peer_timeout_s);
  }

  int finish(int exit_code) final {
    writer_.wait_for_acknowledgments(flush_timeout(exit_code));
    report(answered_);
    rt_.status.publish(pmlsm_msgs::msg::NodeStatus_Constants::STATE_STOPPING, answered_, rt_.period_s, "done");
    return exit_code;
  }

  dds::Wakeup& wakeup() final { return rt_.wakeup; }

  const std::uint64_t ticks_;
  std::uint64_t answered_ = 0;
  std::uint64_t tick_ = 0;
  CompensatorView view_;
  bool holding_ = false;  ///< a tick taken, its answer waiting for the owner's change
  bool changed_ = false;
  CompensatorStep step_;
  pmlsm_msgs::msg::CompensatorOutput out_;
};

}  // namespace pmlsm::node

// controller: the motor-side velocity loop on DDS. For every MotorFeedback
// tick it runs the reference model (25) on the scenario's command and the
// velocity PI, and answers with ForceCommand (feedback_tick = that tick); it
// also publishes VelocityReference. It is event-driven: the same code serves
// the lockstep and the realtime clock.
//
// With --compensation topic (or accel / rnn / state, the same) the PI output gets the compensator's force
// (CompensatorOutput, Fig. 4's hybrid controller): output k-1 is applied at
// tick k (run_compensated in pmlsm/sim/closed_loop.hpp). Lockstep waits for it;
// realtime uses the newest one no older than 3 ticks and counts the ticks
// without (they get no compensation).
//
// With an external scenario (command.shape: external) the raw command comes from
// VelocitySetpoint samples (another node, `pmlsm setpoint`) through ExternalReference
// (pmlsm/control/external_reference.hpp): rejected setpoints are counted, a source gone quiet
// brings the command back to zero at the rate limit, and both are reported on NodeStatus. Setpoint
// age is judged on this node's steady clock, in lockstep as in realtime (the source runs on
// wall time). A run with a rejected invalid setpoint, or whose source went quiet mid-move,
// ends with exit code 5: it did not do what was asked.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>

#include "CompensatorOutputPubSubTypes.h"
#include "CurrentFeedbackPubSubTypes.h"
#include "ForceCommandPubSubTypes.h"
#include "VoltageCommandPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "VelocityReferencePubSubTypes.h"
#include "VelocitySetpointPubSubTypes.h"
#include "controller_command_line.hpp"
#include "msg_mapping.hpp"
#include "cycle_component.hpp"
#include "node_support.hpp"
#include "parameter_service.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/live_parameters.hpp"
#include "pmlsm/control/current_controller.hpp"
#include "pmlsm/compensation/standstill_gate.hpp"
#include "pmlsm/control/input_freshness.hpp"
#include "pmlsm/sim/velocity_controller.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;

using node::ControllerOptions;

class ControllerComponent final : public node::CycleComponent {
 public:
  ControllerComponent(const node::ComponentContext& context, node::CommonOptions common,
                      const ControllerOptions& options)
      : common_(checked(std::move(common))),
        opt_(options),
        rt_("controller", common_, context),
        period_s_(rt_.period_s),
        ticks_(scenario_ticks(rt_.cfg.scenario, period_s_)),
        voltage_level_(rt_.cfg.command_level == node::CommandLevel::kVoltage),
        lockstep_(rt_.cfg.clock == node::Clock::kLockstep),
        compensated_(options.compensation != "none"),
        peer_timeout_(common_.peer_timeout_s),
        feedback_reader_(rt_.participant.make_reader(pdds::topics::kMotorFeedback, rt_.wakeup)),
        command_writer_(rt_.participant.make_writer(pdds::topics::kForceCommand)),
        reference_writer_(rt_.participant.make_writer(pdds::topics::kVelocityReference)),
        current_reader_(rt_.participant.make_reader(pdds::topics::kCurrentFeedback, rt_.wakeup)),
        voltage_writer_(rt_.participant.make_writer(pdds::topics::kVoltageCommand)),
        current_loop_(rt_.cfg.params.current_controller_params()),
        current_steps_(rt_.cfg.params.timing.current_steps_per_tick()),
        compensation_reader_(rt_.participant.make_reader(pdds::topics::kCompensatorOutput, rt_.wakeup,
                                                         node::chain_input_profile(rt_.cfg, pdds::kObserverProfile))),
        controller_(std::in_place, rt_.cfg.params, rt_.cfg.scenario),
        live_(rt_.cfg.params, live_keys(rt_.cfg.params, "controller")),
        parameters_(rt_, "controller", live_) {
    if (rt_.cfg.scenario.shape == CommandShape::kExternal) {
      external_.emplace(external_reference_params(rt_.cfg.scenario, period_s_));
      setpoint_reader_.emplace(rt_.participant.make_reader(pdds::topics::kVelocitySetpoint, rt_.wakeup));
    }
  }

 private:
  /// Where the tick in hand is: its feedback, then (lockstep, compensated) its compensation, then
  /// (voltage level) the current loop's exchanges.
  enum class Phase { kReaders, kFeedback, kCompensation, kCurrentLoop };

  static node::CommonOptions checked(node::CommonOptions common) {
    if (common.wake_batch_us > 0.0) {
      throw ConfigError("--wake-batch-us " + std::to_string(common.wake_batch_us) +
                        ": the controller is on the control chain; batching would pace the loop");
    }
    return common;
  }

  void activate() override;
  Update update() override;
  std::chrono::duration<double> input_timeout() const override {
    return phase_ == Phase::kFeedback ? feedback_follower_.timeout() : peer_timeout_;
  }
  int inputs_lost() override;
  int finish(int exit_code) override;
  pdds::Wakeup& wakeup() override { return rt_.wakeup; }

  /// The next tick's feedback: the tick in hand, then its compensation or its answer.
  Update take_feedback();
  /// Lockstep: waits (kWaiting) for output k-1; realtime: the newest on time, or none.
  Update compensate();
  /// The velocity loop's step for the tick in hand with `compensation`, published.
  Update answer(const Compensation& compensation);
  /// The voltage command level: the drive's current loop, 32 exchanges per tick.
  Update current_loop();
  /// The tick in hand is done.
  Update tick_done();
  /// Moving to the next phase of a tick is work: the wait for that phase's input starts there.
  static Update as_work(const Update& update) {
    return update.progress == Progress::kWaiting ? Update::worked() : update;
  }

  /// The drive restarted: what this loop integrated belongs to the old run.
  void follow_new_run();
  bool take_compensation(std::uint64_t k);
  void publish(std::uint64_t k, const VelocityControllerOutput& out, double applied_compensation_n);
  /// A late compensation episode's start or end: said on stderr and NodeStatus.
  void report_freshness(std::uint64_t k, const InputFreshness::Step& fresh);
  /// External scenario: takes the setpoints that arrived, steps the policy; reports news.
  double external_command(std::uint64_t k);

  node::CommonOptions common_;
  ControllerOptions opt_;
  node::NodeRuntime rt_;
  double period_s_;
  std::uint64_t ticks_;
  bool voltage_level_;
  bool lockstep_;
  bool compensated_;
  std::chrono::duration<double> peer_timeout_;
  pdds::Reader<msg::MotorFeedbackPubSubType> feedback_reader_;
  pdds::Writer<msg::ForceCommandPubSubType> command_writer_;
  pdds::Writer<msg::VelocityReferencePubSubType> reference_writer_;
  // The voltage command level: this node also runs the drive's current loop.
  pdds::Reader<msg::CurrentFeedbackPubSubType> current_reader_;
  pdds::Writer<msg::VoltageCommandPubSubType> voltage_writer_;
  CurrentController current_loop_;
  int current_steps_;
  pdds::Reader<msg::CompensatorOutputPubSubType> compensation_reader_;
  std::optional<VelocityController> controller_;
  // Live parameters (`pmlsm param set controller KEY VALUE`): the PI's gains and the filter slots,
  // taken at a tick boundary.
  LiveParameters live_;
  node::ParameterService parameters_;
  std::optional<ExternalReference> external_;
  std::optional<pdds::Reader<msg::VelocitySetpointPubSubType>> setpoint_reader_;
  msg::VelocitySetpoint setpoint_;
  std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
  bool external_was_stale_ = true;
  std::uint64_t reported_rejections_ = 0;

  msg::MotorFeedback feedback_;
  msg::ForceCommand command_;
  msg::VelocityReference reference_;
  msg::CurrentFeedback current_feedback_;
  msg::VoltageCommand voltage_command_;
  msg::CompensatorOutput compensator_output_;
  Compensation compensation_;
  std::uint64_t compensation_tick_ = 0;
  bool have_compensation_ = false;
  /// Output k-1 belongs to tick k; up to 3 ticks old it is used (realtime takes what is there).
  InputFreshness freshness_{3};
  std::uint64_t reported_lines_ = 0;
  bool guard_reported_ = false;
  std::uint64_t next_tick_ = 0;  // ticks up to here are done
  node::FeedbackFollower feedback_follower_{"controller", common_, rt_.cfg.clock, ticks_, period_s_};
  std::uint64_t rejected_ = 0;
  double last_velocity_ = 0.0;
  Phase phase_ = Phase::kFeedback;
  std::uint64_t tick_ = 0;  ///< the tick in hand
  double velocity_mps_ = 0.0;
  LoadWitness load_;      ///< the load sensor's reading of the tick, the standstill gate's witness
  double force_n_ = 0.0;  ///< the tick's force command, for the current loop
  int substep_ = 0;
};

double ControllerComponent::external_command(std::uint64_t k) {
  const double now_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  while (setpoint_reader_->take(setpoint_)) {
    const Setpoint sp{setpoint_.velocity_mps(), setpoint_.accel_limit_mps2(), setpoint_.session(),
                      setpoint_.sequence_number()};
    const SetpointVerdict verdict = external_->offer(sp, now_s);
    // Every rejection is counted; the first few are told (a flood would flood the log).
    if (verdict != SetpointVerdict::kAccepted && reported_rejections_ < 10) {
      ++reported_rejections_;
      char text[160];
      std::snprintf(text, sizeof text, "setpoint %.6g m/s from '%s' rejected: %s", sp.velocity_mps,
                    setpoint_.source().c_str(), to_string(verdict));
      std::fprintf(stderr, "controller: tick %llu: %s\n", static_cast<unsigned long long>(k), text);
      rt_.status.publish(node_state::STATE_RUNNING, k, period_s_, text);
    }
  }
  const ExternalReferenceOutput out = external_->step(now_s);
  if (out.stale != external_was_stale_) {
    external_was_stale_ = out.stale;
    char text[160];
    if (out.stale) {
      std::snprintf(text, sizeof text, "setpoint stale (none for %.3g s): reference ramps to zero from %.6g m/s",
                    external_->params().timeout_s, out.command_mps - out.accel_mps2 * period_s_);
    } else {
      std::snprintf(text, sizeof text, "following setpoints from '%s'", setpoint_.source().c_str());
    }
    std::fprintf(stderr, "controller: tick %llu: %s\n", static_cast<unsigned long long>(k), text);
    rt_.status.publish(node_state::STATE_RUNNING, k, period_s_, text);
  }
  return out.command_mps;
}

void ControllerComponent::follow_new_run() {
  controller_.emplace(live_.params(), rt_.cfg.scenario);
  have_compensation_ = false;
  freshness_.reset();
  compensation_ = {};
  last_velocity_ = 0.0;
}

bool ControllerComponent::take_compensation(std::uint64_t k) {
  while (compensation_reader_.take(compensator_output_)) {
    const std::uint64_t t = compensator_output_.stamp().tick();
    if ((have_compensation_ && t <= compensation_tick_) || !std::isfinite(compensator_output_.force_n()) ||
        !std::isfinite(compensator_output_.u_n())) {
      ++rejected_;
      continue;
    }
    compensation_tick_ = t;
    compensation_ = compensation_from_output(compensator_output_.force_n(), compensator_output_.u_n());
    have_compensation_ = true;
  }
  return have_compensation_ && compensation_tick_ + 1 >= k;
}

ControllerComponent::Update ControllerComponent::compensate() {
  // Output k-1 belongs to tick k; lockstep waits for it, realtime takes what is there.
  if (!take_compensation(tick_) && lockstep_) return Update::waiting();
  const InputFreshness::Step fresh =
      freshness_.step(tick_, have_compensation_ ? std::optional<std::uint64_t>(compensation_tick_) : std::nullopt);
  if (fresh.change != InputFreshness::Change::kNone) report_freshness(tick_, fresh);
  return answer(fresh.on_time ? compensation_ : Compensation{});
}

void ControllerComponent::report_freshness(std::uint64_t k, const InputFreshness::Step& fresh) {
  char text[200];
  if (fresh.change == InputFreshness::Change::kFirst) {
    // Said only when the start went without (a peer on another host, a late match): in lockstep
    // the first compensation is always there.
    if (fresh.gap_ticks == 0) return;
    std::printf("controller: tick %llu: compensation on time from here (PI alone for the %llu ticks before)\n",
                static_cast<unsigned long long>(k), static_cast<unsigned long long>(fresh.gap_ticks));
    return;
  }
  // Once per episode, the first few told (a flapping link would flood the log); all counted.
  if (++reported_lines_ > 20) return;
  if (fresh.change == InputFreshness::Change::kLate) {
    std::snprintf(text, sizeof text,
                  "compensation late (newest for tick %llu, more than %llu ticks old): PI alone until it is on time",
                  static_cast<unsigned long long>(compensation_tick_),
                  static_cast<unsigned long long>(freshness_.max_age_ticks()));
  } else {
    std::snprintf(text, sizeof text, "compensation on time again after %llu ticks without",
                  static_cast<unsigned long long>(fresh.gap_ticks));
  }
  std::fprintf(stderr, "controller: tick %llu: %s\n", static_cast<unsigned long long>(k), text);
  rt_.status.publish(node_state::STATE_RUNNING, k, period_s_, text);
}

void ControllerComponent::publish(std::uint64_t k, const VelocityControllerOutput& out, double applied_compensation_n) {
  command_.stamp(node::make_stamp(k, period_s_, feedback_follower_.run().current()));
  node::to_msg(out, applied_compensation_n, k, command_);
  command_writer_.write(command_);
  // After the command: the plant waits for it, the evaluator for this one.
  reference_.stamp(command_.stamp());
  node::to_msg(out, live_.version(), reference_);
  reference_writer_.write(reference_);
}

ControllerComponent::Update ControllerComponent::current_loop() {
  bool exchanged = false;
  while (substep_ < current_steps_ && current_reader_.take(current_feedback_)) {
    if (current_feedback_.stamp().tick() != tick_ ||
        current_feedback_.substep() != static_cast<std::uint32_t>(substep_)) {
      ++rejected_;
      continue;
    }
    // The current controller rejects (and counts) non-finite measurements itself.
    const CurrentControllerOutput u = current_loop_.step(
        {force_n_, current_feedback_.i_d_a(), current_feedback_.i_q_a(), current_feedback_.velocity_mps()});
    voltage_command_.stamp(current_feedback_.stamp());
    voltage_command_.substep(current_feedback_.substep());
    voltage_command_.u_d_v(u.u_d_v);
    voltage_command_.u_q_v(u.u_q_v);
    voltage_command_.i_d_ref_a(0.0);
    voltage_command_.i_q_ref_a(u.i_q_ref_a);
    voltage_command_.saturated(u.voltage_limited);
    voltage_writer_.write(voltage_command_);
    ++substep_;
    exchanged = true;
  }
  if (substep_ < current_steps_) return exchanged ? Update::worked() : Update::waiting();
  return tick_done();
}

void ControllerComponent::activate() {
  if (opt_.command_readers > 0 || opt_.reference_readers > 0) {
    phase_ = Phase::kReaders;
    rt_.status.publish(node_state::STATE_WAITING, 0, period_s_, "waiting for readers");
    return;
  }
  rt_.status.publish(node_state::STATE_RUNNING, 0, period_s_, "running");
}

ControllerComponent::Update ControllerComponent::update() {
  switch (phase_) {
    case Phase::kReaders:
      if (command_writer_.matched_readers() < static_cast<std::size_t>(opt_.command_readers) ||
          reference_writer_.matched_readers() < static_cast<std::size_t>(opt_.reference_readers)) {
        return Update::waiting();
      }
      rt_.status.publish(node_state::STATE_RUNNING, 0, period_s_, "running");
      phase_ = Phase::kFeedback;
      return Update::worked();
    case Phase::kFeedback: return take_feedback();
    case Phase::kCompensation: return compensate();
    case Phase::kCurrentLoop: return current_loop();
  }
  return Update::finished(kExitError);
}

ControllerComponent::Update ControllerComponent::take_feedback() {
  if (next_tick_ >= ticks_) return Update::finished(kExitOk);
  const auto next =
      feedback_follower_.try_next(feedback_reader_, feedback_, next_tick_, period_s_, rt_.status, rejected_);
  if (next == node::FeedbackFollower::Next::kNone) return Update::waiting();
  if (next == node::FeedbackFollower::Next::kEnded) return Update::finished(feedback_follower_.exit_code());
  if (next == node::FeedbackFollower::Next::kNewRun) follow_new_run();
  tick_ = feedback_.stamp().tick();
  if (parameters_.serve(tick_)) controller_->retune(live_.params());
  velocity_mps_ = feedback_.velocity_mps();
  if (!std::isfinite(velocity_mps_)) {
    ++rejected_;  // answer with the last good measurement rather than pass a NaN on
    velocity_mps_ = last_velocity_;
  }
  last_velocity_ = velocity_mps_;
  load_ = node::load_witness(feedback_);
  if (!compensated_ || tick_ == 0) return as_work(answer(Compensation{}));
  phase_ = Phase::kCompensation;
  return as_work(compensate());
}

ControllerComponent::Update ControllerComponent::answer(const Compensation& compensation) {
  const VelocityControllerOutput out =
      external_ ? controller_->step_command(external_command(tick_), velocity_mps_, compensation, load_)
                : controller_->step(tick_, velocity_mps_, compensation, load_);
  if (out.guard.tripped && !guard_reported_) {
    // Once: the compensation fades out and stays out; the controller goes on as PI alone.
    guard_reported_ = true;
    std::fprintf(stderr, "controller: tick %llu: vibration guard: %s; compensation faded out, PI alone from here\n",
                 static_cast<unsigned long long>(tick_), to_string(out.guard.reason));
    rt_.status.publish(node_state::STATE_RUNNING, tick_, period_s_,
                       std::string("vibration guard: compensation out: ") + to_string(out.guard.reason));
  }
  publish(tick_, out, out.compensation_applied_n);
  if (!voltage_level_) return tick_done();
  phase_ = Phase::kCurrentLoop;
  substep_ = 0;
  force_n_ = out.force_n;
  return as_work(current_loop());
}

ControllerComponent::Update ControllerComponent::tick_done() {
  next_tick_ = tick_ + 1;
  phase_ = Phase::kFeedback;
  return Update::worked();
}

int ControllerComponent::inputs_lost() {
  switch (phase_) {
    case Phase::kReaders:
      std::fprintf(stderr,
                   "controller: readers missing after %.1f s: %zu of %d ForceCommand readers, %zu of %d "
                   "VelocityReference readers\n",
                   common_.peer_timeout_s, command_writer_.matched_readers(), opt_.command_readers,
                   reference_writer_.matched_readers(), opt_.reference_readers);
      return kExitPeerMissing;
    case Phase::kFeedback: return feedback_follower_.lost(next_tick_, period_s_, rt_.status);
    case Phase::kCompensation:
      return node::end_of_failed_wait("controller", "CompensatorOutput", "compensator", tick_ - 1,
                                      common_.peer_timeout_s);
    case Phase::kCurrentLoop:
      return node::end_of_failed_wait("controller", "CurrentFeedback", "plant", tick_, common_.peer_timeout_s);
  }
  return kExitError;
}

int ControllerComponent::finish(int exit_code) {
  std::string external_note;
  if (external_) {
    const ExternalReferenceCounters& c = external_->counters();
    rejected_ += c.rejected;
    char text[200];
    std::snprintf(text, sizeof text,
                  "setpoints: %llu accepted, %llu rejected (%llu invalid), went stale %llu times (%llu mid-move)",
                  static_cast<unsigned long long>(c.accepted), static_cast<unsigned long long>(c.rejected),
                  static_cast<unsigned long long>(c.rejected_invalid),
                  static_cast<unsigned long long>(c.stale_episodes),
                  static_cast<unsigned long long>(c.lost_while_moving));
    external_note = text;
    std::printf("controller: %s\n", text);
    if ((c.rejected_invalid > 0 || c.lost_while_moving > 0) && exit_code == kExitOk) {
      std::fprintf(stderr, "controller: %s: the run is not valid\n", text);
      exit_code = kExitSafeState;
    }
  }
  rt_.status.status().rejected(rejected_);
  rt_.status.publish(node_state::STATE_STOPPING, next_tick_, period_s_,
                     external_note.empty() ? std::string("done") : "done; " + external_note);
  const auto flush_s = node::flush_timeout(exit_code);
  command_writer_.wait_for_acknowledgments(flush_s);
  if (voltage_level_) voltage_writer_.wait_for_acknowledgments(flush_s);
  reference_writer_.wait_for_acknowledgments(flush_s);
  const InputFreshness::Counters& late = freshness_.counters();
  std::printf(
      "controller: %llu ticks answered, %llu rejected, compensation %s (%llu ticks without; at the start %llu, "
      "then late %llu times, the longest %llu ticks)%s\n",
      static_cast<unsigned long long>(next_tick_), static_cast<unsigned long long>(rejected_),
      opt_.compensation.c_str(),
      static_cast<unsigned long long>(compensated_ ? late.ticks_before_first + late.late_ticks : 0),
      static_cast<unsigned long long>(late.ticks_before_first), static_cast<unsigned long long>(late.episodes),
      static_cast<unsigned long long>(late.longest_gap_ticks),
      guard_reported_ ? ", taken out by the vibration guard" : "");
  if (const StandstillGate* gate = controller_ ? controller_->standstill_gate() : nullptr) {
    const StandstillGateCounters& g = gate->counters();
    std::printf(
        "controller: standstill gate closed %llu times, reopened %llu; pushed the motor after the load's stretch for "
        "%llu ticks\n",
        static_cast<unsigned long long>(g.closings), static_cast<unsigned long long>(g.openings),
        static_cast<unsigned long long>(g.stretch_push_steps));
  }
  return exit_code;
}

}  // namespace

namespace pmlsm::node {

PMLSM_COMPONENT(controller, make_controller, 0);

MadeComponent make_controller(const ComponentContext& context, int argc, char** argv) {
  CommonOptions common;
  common.spin_us = 200.0;
  ControllerOptions opt;
  if (const auto code = parse_controller_command_line(argc, argv, common, opt)) return {nullptr, *code};
  return {std::make_unique<ControllerComponent>(context, std::move(common), opt)};
}

}  // namespace pmlsm::node

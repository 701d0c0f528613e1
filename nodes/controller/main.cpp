// controller: the motor-side velocity loop on DDS. For every MotorFeedback
// tick it runs the reference model (25) on the scenario's command and the
// velocity PI, and answers with ForceCommand (feedback_tick = that tick); it
// also publishes VelocityReference. It is event-driven: the same code serves
// the lockstep and the realtime clock.
//
// With --compensation topic the PI output gets the compensator's force
// (CompensatorOutput, Fig. 4's hybrid controller): output k-1 is applied at
// tick k (run_compensated in pmlsm/sim/closed_loop.hpp). Lockstep waits for it;
// realtime uses the newest one no older than 3 ticks and counts the ticks
// without (they get no compensation).
#include <cmath>
#include <cstdio>
#include <optional>

#include "CompensatorOutputPubSubTypes.h"
#include "CurrentFeedbackPubSubTypes.h"
#include "ForceCommandPubSubTypes.h"
#include "VoltageCommandPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "VelocityReferencePubSubTypes.h"
#include "msg_mapping.hpp"
#include "node_support.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/control/current_controller.hpp"
#include "pmlsm/sim/velocity_controller.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;

int run(int argc, char** argv) {
  CLI::App app{"Velocity loop (reference model + PI) of the PMLSM on DDS"};
  node::CommonOptions common;
  common.spin_us = 200.0;
  node::add_common_options(app, common);
  std::string compensation = "none";
  app.add_option("--compensation", compensation, "none (PI only) or topic (add CompensatorOutput to the PI output)")
      ->check(CLI::IsMember({"none", "topic"}))
      ->capture_default_str();
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  node::NodeRuntime rt("controller", common);
  const node::LoadedConfig& cfg = rt.cfg;
  const double period = rt.period_s;
  if (common.wake_batch_us > 0.0) {
    throw ConfigError("--wake-batch-us " + std::to_string(common.wake_batch_us) +
                      ": the controller is on the control chain; batching would pace the loop");
  }
  auto feedback_reader = rt.participant.make_reader<pmlsm_msgs::msg::MotorFeedbackPubSubType>(pdds::topics::kMotorFeedback, rt.wakeup);
  auto command_writer = rt.participant.make_writer<pmlsm_msgs::msg::ForceCommandPubSubType>(pdds::topics::kForceCommand);
  auto reference_writer = rt.participant.make_writer<pmlsm_msgs::msg::VelocityReferencePubSubType>(pdds::topics::kVelocityReference);
  // The voltage command level: this node also runs the drive's current loop.
  const bool voltage_level = cfg.command_level == node::CommandLevel::kVoltage;
  auto current_reader = rt.participant.make_reader<pmlsm_msgs::msg::CurrentFeedbackPubSubType>(pdds::topics::kCurrentFeedback, rt.wakeup);
  auto voltage_writer = rt.participant.make_writer<pmlsm_msgs::msg::VoltageCommandPubSubType>(pdds::topics::kVoltageCommand);
  CurrentController current_loop(cfg.params.current_controller_params());
  const int current_steps = cfg.params.timing.current_steps_per_tick();
  pmlsm_msgs::msg::CurrentFeedback current_feedback;
  pmlsm_msgs::msg::VoltageCommand voltage_command;

  const bool compensated = compensation == "topic";
  auto compensation_reader = rt.participant.make_reader<pmlsm_msgs::msg::CompensatorOutputPubSubType>(
      pdds::topics::kCompensatorOutput, rt.wakeup, pdds::kObserverProfile);
  pmlsm_msgs::msg::CompensatorOutput compensator_output;
  double compensation_n = 0.0;
  std::uint64_t compensation_tick = 0;
  bool have_compensation = false;
  std::uint64_t compensation_missing = 0;
  const bool lockstep = cfg.clock == node::Clock::kLockstep;

  std::optional<VelocityController> controller(std::in_place, cfg.params, cfg.scenario);
  const std::uint64_t ticks = scenario_ticks(cfg.scenario, period);
  rt.status.publish(node_state::STATE_RUNNING, 0, period, "running");

  pmlsm_msgs::msg::MotorFeedback feedback;
  pmlsm_msgs::msg::ForceCommand command;
  pmlsm_msgs::msg::VelocityReference reference;
  std::uint64_t next_tick = 0;  // ticks up to here are done
  node::TickFilter tick_filter;
  node::RunFollower run;
  bool new_run = false;
  std::uint64_t rejected = 0;
  double last_velocity = 0.0;
  const auto peer_timeout = std::chrono::duration<double>(common.peer_timeout_s);
  int exit_code = kExitOk;

  bool any_feedback = false;
  while (next_tick < ticks && !pdds::stop_requested()) {
    const bool ok = node::take_next_tick(rt.wakeup, feedback_reader, feedback, tick_filter, run, new_run, rejected,
                                         node::feedback_timeout(common, cfg.clock, any_feedback));
    if (!ok) {
      exit_code = node::end_of_feedback_wait("controller", common, cfg.clock, any_feedback, next_tick, period, rt.status);
      break;
    }
    any_feedback = true;
    if (new_run && run.restarts() > 0) {
      // The drive restarted: what this loop integrated belongs to the old run.
      std::printf("controller: the drive restarted (run %016llx -> %016llx) at its tick %llu: following the new run\n",
                  static_cast<unsigned long long>(run.previous()), static_cast<unsigned long long>(run.current()),
                  static_cast<unsigned long long>(feedback.stamp().tick()));
      controller.emplace(cfg.params, cfg.scenario);
      have_compensation = false;
      compensation_n = 0.0;
      last_velocity = 0.0;
      rt.status.publish(node_state::STATE_RUNNING, feedback.stamp().tick(), period, "drive restarted: new run followed");
    }
    const std::uint64_t k = feedback.stamp().tick();
    double velocity = feedback.velocity_mps();
    if (!std::isfinite(velocity)) {
      ++rejected;  // answer with the last good measurement rather than pass a NaN on
      velocity = last_velocity;
    }
    last_velocity = velocity;
    double applied_compensation_n = 0.0;
    if (compensated && k > 0) {
      // Output k-1 belongs to tick k; lockstep waits for it, realtime takes what is there.
      auto take_compensation = [&] {
        while (compensation_reader.take(compensator_output)) {
          const std::uint64_t t = compensator_output.stamp().tick();
          if ((have_compensation && t <= compensation_tick) || !std::isfinite(compensator_output.force_n())) {
            ++rejected;
            continue;
          }
          compensation_tick = t;
          compensation_n = compensator_output.force_n();
          have_compensation = true;
        }
        return have_compensation && compensation_tick + 1 >= k;
      };
      if (lockstep) {
        if (!node::wait_until(rt.wakeup, peer_timeout, take_compensation)) {
          exit_code = node::end_of_failed_wait("controller", "CompensatorOutput", "compensator", k - 1,
                                               common.peer_timeout_s);
          break;
        }
      } else {
        take_compensation();
      }
      if (have_compensation && compensation_tick + 3 >= k) {
        applied_compensation_n = compensation_n;
      } else {
        ++compensation_missing;
      }
    }
    const VelocityControllerOutput out = controller->step(k, velocity, applied_compensation_n);

    command.stamp(node::make_stamp(k, period, run.current()));
    node::to_msg(out, applied_compensation_n, k, command);
    command_writer.write(command);
    // After the command: the plant waits for it, the evaluator for this one.
    reference.stamp(command.stamp());
    node::to_msg(out, reference);
    reference_writer.write(reference);

    for (int sub = 0; voltage_level && sub < current_steps; ++sub) {
      bool got_current = false;
      const bool current_ok = node::wait_until(rt.wakeup, peer_timeout, [&] {
        while (!got_current && current_reader.take(current_feedback)) {
          if (current_feedback.stamp().tick() == k && current_feedback.substep() == static_cast<std::uint32_t>(sub)) {
            got_current = true;
          } else {
            ++rejected;
          }
        }
        return got_current;
      });
      if (!current_ok) break;
      // The current controller rejects (and counts) non-finite measurements itself.
      const CurrentControllerOutput u = current_loop.step(
          {out.force_n, current_feedback.i_d_a(), current_feedback.i_q_a(), current_feedback.velocity_mps()});
      voltage_command.stamp(current_feedback.stamp());
      voltage_command.substep(current_feedback.substep());
      voltage_command.u_d_v(u.u_d_v);
      voltage_command.u_q_v(u.u_q_v);
      voltage_command.i_d_ref_a(0.0);
      voltage_command.i_q_ref_a(u.i_q_ref_a);
      voltage_command.saturated(u.voltage_limited);
      voltage_writer.write(voltage_command);
    }
    next_tick = k + 1;
  }
  rt.status.status().rejected(rejected);
  rt.status.publish(node_state::STATE_STOPPING, next_tick, period, "done");
  command_writer.wait_for_acknowledgments(node::flush_timeout(exit_code));
  if (voltage_level) voltage_writer.wait_for_acknowledgments(node::flush_timeout(exit_code));
  reference_writer.wait_for_acknowledgments(node::flush_timeout(exit_code));
  std::printf("controller: %llu ticks answered, %llu rejected, compensation %s (%llu ticks without)\n",
              static_cast<unsigned long long>(next_tick), static_cast<unsigned long long>(rejected),
              compensation.c_str(), static_cast<unsigned long long>(compensation_missing));
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  return pmlsm::node::run_node("controller", [&] { return run(argc, argv); });
}

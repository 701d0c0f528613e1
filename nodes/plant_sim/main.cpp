// plant_sim: the simulated servo drive on DDS. Publishes MotorFeedback (what
// the drive measures) and PlantTruth (for evaluation only) every control tick
// and applies ForceCommand through the drive's own current loop.
//
// Clocks:
//  - lockstep: the plant is the clock. It publishes tick k and integrates to
//    k+1 only when the command answering tick k has arrived: deterministic,
//    as fast as the machine goes.
//  - realtime: ticks on absolute time (no drift). The plant never waits past
//    --command-deadline-us into the tick: it applies the newest command
//    (zero-order hold), counts late ones, and when the oldest feedback still
//    unanswered was published more than --watchdog-ms ago goes to its safe
//    state (zero force), latched until restart. Counting from the unanswered
//    feedback, not from the last command, means a plant thread that itself
//    stalled (its core taken by the host, say) does not blame the controller
//    for ticks it never asked about. The watchdog arms with the first
//    command, as a drive's does when enabled; until then the force is zero.
#include <time.h>

#include <chrono>
#include <cmath>
#include <algorithm>
#include <cstdio>
#include <vector>

#include "CurrentFeedbackPubSubTypes.h"
#include "ForceCommandPubSubTypes.h"
#include "VoltageCommandPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "PlantTruthPubSubTypes.h"
#include "node_support.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/simulated_drive.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
using pmlsm_msgs::msg::ForceCommand;
using pmlsm_msgs::msg::MotorFeedback;
using pmlsm_msgs::msg::PlantTruth;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;
namespace flags = pmlsm_msgs::msg::MotorFeedback_Constants;

struct PlantOptions {
  int peers = 2;
  double watchdog_ms = 3.0;
  double command_deadline_us = 500.0;
  double wake_early_us = 0.0;
};

void fill_truth(const SimulatedDrive& drive, double force_n, PlantTruth& out) {
  const pmlsm::PlantTruth t = drive.plant().truth();
  out.motor_position_m(t.state.motor_position_m);
  out.motor_velocity_mps(t.state.motor_velocity_mps);
  out.motor_acceleration_mps2(t.motor_accel_mps2);
  out.load_position_m(t.state.load_position_m);
  out.load_velocity_mps(t.state.load_velocity_mps);
  out.load_acceleration_mps2(t.load_accel_mps2);
  out.spring_force_n(t.spring_force_n);
  out.thrust_force_n(t.thrust_n);
  out.ripple_force_n(t.ripple_n);
  out.friction_force_n(t.friction_n);
  out.command_force_n(force_n);
  out.psi_d_wb(t.state.psi_d_wb);
  out.psi_q_wb(t.state.psi_q_wb);
  out.psi_damper_d_wb(t.state.psi_dd_wb);
  out.psi_damper_q_wb(t.state.psi_qq_wb);
  out.i_d_a(t.i_d_a);
  out.i_q_a(t.i_q_a);
  out.i_damper_d_a(t.i_dd_a);
  out.i_damper_q_a(t.i_qq_a);
  out.u_d_v(drive.last_u_d_v());
  out.u_q_v(drive.last_u_q_v());
}

struct Counters {
  std::uint64_t late = 0;       // ticks whose command missed them (realtime) or stale answers (lockstep)
  std::uint64_t rejected = 0;   // non-finite or out-of-order commands
  std::uint64_t deadline_misses = 0;
};

// A command is applied only if finite, newer than the last applied one and
// answering a tick already published (a future tick is malformed: taken, it
// would make every genuine answer after it look stale).
bool acceptable(const ForceCommand& cmd, std::uint64_t last_tick, bool any_yet, std::uint64_t current_tick) {
  return std::isfinite(cmd.force_n()) && cmd.feedback_tick() <= current_tick &&
         (!any_yet || cmd.feedback_tick() > last_tick);
}

timespec add_ns(timespec t, std::int64_t ns) {
  const std::int64_t total = static_cast<std::int64_t>(t.tv_nsec) + ns;
  std::int64_t sec = total / 1000000000LL;
  std::int64_t nsec = total % 1000000000LL;
  if (nsec < 0) {
    nsec += 1000000000LL;
    --sec;
  }
  t.tv_sec += static_cast<time_t>(sec);
  t.tv_nsec = static_cast<long>(nsec);
  return t;
}

std::int64_t diff_ns(const timespec& a, const timespec& b) {
  return (static_cast<std::int64_t>(a.tv_sec) - b.tv_sec) * 1000000000LL + (a.tv_nsec - b.tv_nsec);
}

int run(int argc, char** argv) {
  CLI::App app{"Simulated PMLSM servo drive (plant + drive current loop) on DDS"};
  node::CommonOptions common;
  common.spin_us = 200.0;
  PlantOptions opt;
  node::add_common_options(app, common);
  app.add_option("--peers", opt.peers, "MotorFeedback readers to wait for before tick 0")
      ->check(CLI::Range(1, 64));
  app.add_option("--watchdog-ms", opt.watchdog_ms, "realtime: the oldest unanswered feedback this old -> safe state")
      ->check(CLI::PositiveNumber);
  app.add_option("--command-deadline-us", opt.command_deadline_us,
                 "realtime: how long into a tick the plant waits for that tick's command")
      ->check(CLI::Range(0.0, 1e6));
  app.add_option("--wake-early-us", opt.wake_early_us,
                 "realtime: sleep until this long before each tick, then poll the clock to its start "
                 "(a sleeping thread may wake tens of microseconds late)")
      ->check(CLI::Range(0.0, 900.0));
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  node::NodeRuntime rt("plant_sim", common);
  const node::LoadedConfig& cfg = rt.cfg;
  const double period = rt.period_s;
  if (opt.wake_early_us * 1e-6 >= period) {
    throw ConfigError("--wake-early-us " + std::to_string(opt.wake_early_us) +
                      ": must be shorter than the control period (" + std::to_string(period * 1e6) + " us)");
  }
  if (common.wake_batch_us > 0.0) {
    throw ConfigError("--wake-batch-us " + std::to_string(common.wake_batch_us) +
                      ": plant_sim is on the control chain; batching would pace the loop");
  }
  auto feedback_writer = rt.participant.make_writer<pmlsm_msgs::msg::MotorFeedbackPubSubType>(pdds::topics::kMotorFeedback);
  auto truth_writer = rt.participant.make_writer<pmlsm_msgs::msg::PlantTruthPubSubType>(pdds::topics::kPlantTruth);
  auto command_reader = rt.participant.make_reader<pmlsm_msgs::msg::ForceCommandPubSubType>(pdds::topics::kForceCommand, rt.wakeup);
  // The voltage command level: the current loop runs in the controller.
  const bool voltage_level = cfg.command_level == node::CommandLevel::kVoltage;
  auto current_writer = rt.participant.make_writer<pmlsm_msgs::msg::CurrentFeedbackPubSubType>(pdds::topics::kCurrentFeedback);
  auto voltage_reader = rt.participant.make_reader<pmlsm_msgs::msg::VoltageCommandPubSubType>(pdds::topics::kVoltageCommand, rt.wakeup);

  SimulatedDrive drive(cfg.params, scenario_initial_condition(cfg.scenario));
  const std::uint64_t ticks = scenario_ticks(cfg.scenario, period);
  const double km = cfg.params.plant.electrical.motor_constant_n_per_a;

  rt.status.publish(node_state::STATE_WAITING, 0, period, "waiting for peers");
  const auto peer_timeout = std::chrono::duration<double>(common.peer_timeout_s);
  if (!node::wait_until(rt.wakeup, peer_timeout, [&] {
        return feedback_writer.matched_readers() >= static_cast<std::size_t>(opt.peers) &&
               command_reader.matched_writers() >= 1 &&
               (!voltage_level || (current_writer.matched_readers() >= 1 && voltage_reader.matched_writers() >= 1));
      })) {
    if (pdds::stop_requested()) return kExitOk;
    std::fprintf(stderr, "plant_sim: peers missing after %.1f s: %zu of %d MotorFeedback readers, %zu ForceCommand writers\n",
                 common.peer_timeout_s, feedback_writer.matched_readers(), opt.peers,
                 command_reader.matched_writers());
    return kExitPeerMissing;
  }
  std::printf("plant_sim: %s clock, %s command level, %llu ticks of %.3g ms, scenario %s\n",
              cfg.clock == node::Clock::kLockstep ? "lockstep" : "realtime", voltage_level ? "voltage" : "force",
              static_cast<unsigned long long>(ticks), period * 1e3, cfg.scenario.name.c_str());
  std::fflush(stdout);
  rt.status.publish(node_state::STATE_RUNNING, 0, period, "running");

  MotorFeedback feedback;
  PlantTruth truth;
  ForceCommand command;
  pmlsm_msgs::msg::CurrentFeedback current_feedback;
  pmlsm_msgs::msg::VoltageCommand voltage_command;
  double u_d_v = 0.0, u_q_v = 0.0;  // held voltage at the voltage command level
  Counters counters;
  double force_n = 0.0;          // zero-order hold of the applied command
  std::uint64_t applied_tick = 0;
  bool any_command = false;
  bool safe_state = false;
  int exit_code = kExitOk;

  timespec next_tick{};
  clock_gettime(CLOCK_MONOTONIC, &next_tick);
  const auto period_ns = static_cast<std::int64_t>(std::llround(period * 1e9));

  // Chain latency per tick: MotorFeedback written -> its ForceCommand received
  // (the reader's reception time, wall clock on both ends), late answers
  // included; a tick whose answer never came, or was rejected, has none.
  // Publish times of the last kPublishRing ticks: wall clock (compared with the
  // reader's reception time) and monotonic (for the watchdog).
  constexpr std::uint64_t kPublishRing = 4096;
  std::vector<std::int64_t> published_ns(kPublishRing, 0);
  std::vector<std::int64_t> published_mono_ns(kPublishRing, 0);
  std::vector<double> latency_us;
  latency_us.reserve(ticks);
  eprosima::fastdds::dds::SampleInfo info;
  const auto loop_start = std::chrono::steady_clock::now();
  std::uint64_t k = 0;
  auto record_latency = [&](std::uint64_t answered_tick) {
    if (answered_tick > k || k - answered_tick >= kPublishRing) return;
    std::int64_t received_ns = info.reception_timestamp.to_ns();
    if (received_ns <= 0) received_ns = wall_time_ns();
    latency_us.push_back(static_cast<double>(received_ns - published_ns[answered_tick % kPublishRing]) * 1e-3);
  };
  struct {
    double sum_k = 0, sum_t = 0, sum_kk = 0, sum_kt = 0;
  } start_fit;  // running sums for the period's least-squares fit
  timespec first_tick_start{}, tick_start{};
  for (; k < ticks && !pdds::stop_requested(); ++k) {
    clock_gettime(CLOCK_MONOTONIC, &tick_start);
    if (k == 0) first_tick_start = tick_start;
    {
      const double kk = static_cast<double>(k);
      const double t = static_cast<double>(diff_ns(tick_start, first_tick_start)) * 1e-9;
      start_fit.sum_k += kk;
      start_fit.sum_t += t;
      start_fit.sum_kk += kk * kk;
      start_fit.sum_kt += kk * t;
    }
    const DriveFeedback fb = drive.sample();
    std::uint32_t status_bits = flags::STATUS_SIMULATED;
    if (safe_state) status_bits |= flags::STATUS_SAFE_STATE | flags::STATUS_WATCHDOG_TRIPPED;
    feedback.stamp(node::make_stamp(k, period));
    feedback.position_m(fb.encoder_position_m);
    feedback.velocity_mps(fb.velocity_mps);
    feedback.i_d_a(fb.i_d_a);
    feedback.i_q_a(fb.i_q_a);
    feedback.thrust_force_n(km * fb.i_q_a);
    feedback.applied_force_n(force_n);
    feedback.applied_command_tick(applied_tick);
    feedback.status(status_bits);
    fill_truth(drive, force_n, truth);
    truth.stamp(feedback.stamp());
    published_ns[k % kPublishRing] = wall_time_ns();
    published_mono_ns[k % kPublishRing] = monotonic_ns();
    feedback_writer.write(feedback);
    truth_writer.write(truth);

    if (cfg.clock == node::Clock::kLockstep) {
      bool answered = false;
      const bool ok = node::wait_until(rt.wakeup, peer_timeout, [&] {
        while (!answered && command_reader.take(command, info)) {
          if (command.feedback_tick() != k) {
            ++counters.late;  // an answer to another tick: stale or out of order
          } else if (!std::isfinite(command.force_n())) {
            ++counters.rejected;  // held: the last finite force stays applied
            answered = true;
          } else {
            force_n = command.force_n();
            applied_tick = k;
            any_command = true;
            answered = true;
            record_latency(k);
          }
        }
        return answered;
      });
      if (!ok) {
        if (pdds::stop_requested()) break;
        std::fprintf(stderr, "plant_sim: no ForceCommand for tick %llu within %.1f s: controller lost; safe state\n",
                     static_cast<unsigned long long>(k), common.peer_timeout_s);
        rt.status.publish(node_state::STATE_SAFE, k, period, "controller lost");
        exit_code = kExitPeerLost;
        break;
      }
    } else {
      // Wait into the tick for its command, then apply the newest acceptable one.
      const timespec command_deadline =
          add_ns(next_tick, static_cast<std::int64_t>(opt.command_deadline_us * 1e3));
      bool fresh = false;
      auto drain = [&] {
        while (command_reader.take(command, info)) {
          if (!acceptable(command, applied_tick, any_command, k)) {
            ++counters.rejected;
            continue;
          }
          if (!any_command) {
            std::printf("plant_sim: first command applied at tick %llu; watchdog armed\n",
                        static_cast<unsigned long long>(k));
          }
          force_n = command.force_n();
          applied_tick = command.feedback_tick();
          any_command = true;
          record_latency(applied_tick);
          if (applied_tick == k) fresh = true;
        }
        return fresh;
      };
      timespec now{};
      clock_gettime(CLOCK_MONOTONIC, &now);
      const double wait_s = std::max(0.0, static_cast<double>(diff_ns(command_deadline, now)) * 1e-9);
      node::wait_until(rt.wakeup, std::chrono::duration<double>(wait_s), drain);
      drain();
      if (!fresh) ++counters.late;
      // The oldest unanswered feedback: tick applied_tick + 1, or, beyond the
      // ring, the oldest remembered one (which is younger: the trip comes no earlier).
      const std::uint64_t oldest_unanswered =
          std::max(applied_tick + 1, k + 1 >= kPublishRing ? k + 1 - kPublishRing : std::uint64_t{0});
      if (!safe_state && any_command && oldest_unanswered <= k &&
          static_cast<double>(monotonic_ns() - published_mono_ns[oldest_unanswered % kPublishRing]) >
              opt.watchdog_ms * 1e6) {
        safe_state = true;
        std::fprintf(stderr, "plant_sim: watchdog: tick %llu unanswered for %.1f ms at tick %llu: safe state (zero force)\n",
                     static_cast<unsigned long long>(oldest_unanswered), opt.watchdog_ms,
                     static_cast<unsigned long long>(k));
        rt.status.publish(node_state::STATE_SAFE, k, period, "watchdog: feedback unanswered, zero force");
      }
      if (safe_state) force_n = 0.0;
    }

    if (!voltage_level) {
      drive.apply_force(force_n);
    } else {
      // 32 exchanges per tick: currents out, the controller's voltage back.
      bool lost = false;
      for (int sub = 0; sub < drive.current_steps_per_tick() && !lost; ++sub) {
        const PlantMeasurement& m = drive.measurement();
        current_feedback.stamp(feedback.stamp());
        current_feedback.substep(static_cast<std::uint32_t>(sub));
        current_feedback.i_d_a(m.i_d_a);
        current_feedback.i_q_a(m.i_q_a);
        current_feedback.velocity_mps(drive.tick_velocity_mps());
        current_feedback.position_m(m.encoder_position_m);
        current_writer.write(current_feedback);
        bool answered = false;
        lost = !node::wait_until(rt.wakeup, peer_timeout, [&] {
          while (!answered && voltage_reader.take(voltage_command)) {
            if (voltage_command.stamp().tick() != k || voltage_command.substep() != static_cast<std::uint32_t>(sub)) {
              ++counters.late;
            } else {
              if (std::isfinite(voltage_command.u_d_v()) && std::isfinite(voltage_command.u_q_v())) {
                u_d_v = voltage_command.u_d_v();
                u_q_v = voltage_command.u_q_v();
              } else {
                ++counters.rejected;  // the last finite voltage is held
              }
              answered = true;
            }
          }
          return answered;
        });
        if (!lost) drive.apply_voltage(u_d_v, u_q_v);
      }
      if (lost) {
        if (pdds::stop_requested()) break;
        std::fprintf(stderr, "plant_sim: no VoltageCommand in tick %llu within %.1f s: controller lost; safe state\n",
                     static_cast<unsigned long long>(k), common.peer_timeout_s);
        rt.status.publish(node_state::STATE_SAFE, k, period, "controller lost");
        exit_code = kExitPeerLost;
        break;
      }
    }

    if (cfg.clock == node::Clock::kRealtime) {
      next_tick = add_ns(next_tick, period_ns);
      timespec now{};
      clock_gettime(CLOCK_MONOTONIC, &now);
      if (diff_ns(now, next_tick) > 0) ++counters.deadline_misses;
      const timespec wake = add_ns(next_tick, -static_cast<std::int64_t>(opt.wake_early_us * 1e3));
      clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &wake, nullptr);
      // No yield while polling: the poll is short, and at SCHED_FIFO a yield would hand the core
      // to this node's own threads only at the moment the tick must start.
      while (opt.wake_early_us > 0.0 && diff_ns(now, next_tick) < 0) clock_gettime(CLOCK_MONOTONIC, &now);
    }
    if (k % 1000 == 999) {
      auto& s = rt.status.status();
      s.late(counters.late);
      s.rejected(counters.rejected);
      s.deadline_misses(counters.deadline_misses);
      rt.status.publish(safe_state ? node_state::STATE_SAFE : node_state::STATE_RUNNING, k, period);
    }
  }

  auto& s = rt.status.status();
  s.late(counters.late);
  s.rejected(counters.rejected);
  s.deadline_misses(counters.deadline_misses);
  rt.status.publish(node_state::STATE_STOPPING, k, period, "done");
  feedback_writer.wait_for_acknowledgments(node::kFlushTimeout);
  truth_writer.wait_for_acknowledgments(node::kFlushTimeout);
  if (voltage_level) current_writer.wait_for_acknowledgments(node::kFlushTimeout);
  const double loop_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - loop_start).count();
  if (cfg.clock == node::Clock::kRealtime && k > 1) {
    // Absolute-time scheduling: the period, as the least-squares slope of the
    // tick start times against the tick index, must equal the nominal one (no
    // drift); single late ticks barely move it.
    const double n = static_cast<double>(k);
    const double mean_period = (n * start_fit.sum_kt - start_fit.sum_k * start_fit.sum_t) /
                               (n * start_fit.sum_kk - start_fit.sum_k * start_fit.sum_k);
    std::printf("plant_sim: mean tick period %.3f us (nominal %.3f us, %+.1f ppm)\n", mean_period * 1e6,
                period * 1e6, (mean_period / period - 1.0) * 1e6);
  }
  if (!latency_us.empty()) {
    std::sort(latency_us.begin(), latency_us.end());
    auto at = [&](double q) { return latency_us[static_cast<std::size_t>(q * static_cast<double>(latency_us.size() - 1))]; };
    std::printf("plant_sim: chain latency feedback -> command over %zu ticks: p50 %.1f us, p99 %.1f us, max %.1f us\n",
                latency_us.size(), at(0.5), at(0.99), latency_us.back());
  }
  if (latency_us.size() < k) {
    std::printf("plant_sim: %llu of %llu ticks got no acceptable command\n",
                static_cast<unsigned long long>(k - latency_us.size()), static_cast<unsigned long long>(k));
  }
  std::printf("plant_sim: %llu ticks in %.3f s (%.1fx real time), late %llu, rejected %llu, deadline misses %llu%s\n",
              static_cast<unsigned long long>(k), loop_s, static_cast<double>(k) * period / loop_s,
              static_cast<unsigned long long>(counters.late),
              static_cast<unsigned long long>(counters.rejected),
              static_cast<unsigned long long>(counters.deadline_misses), safe_state ? ", ended in safe state" : "");
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  return pmlsm::node::run_node("plant_sim", [&] { return run(argc, argv); });
}

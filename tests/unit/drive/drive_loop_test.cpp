// The drive loop's policy without DDS: arbitration, ownership, watchdog arming and tripping,
// lost controller, safe-tick accounting, statistics; and, with the simulated drive as its
// backend, that the loop hands the plant exactly the commanded forces.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "pmlsm/config/config.hpp"
#include "pmlsm/drive/drive_loop.hpp"
#include "pmlsm/drive/loop_statistics.hpp"
#include "pmlsm/drive/tick_clock.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/simulated_drive.hpp"
#include "pmlsm/util/clock.hpp"

namespace pmlsm::drive {
namespace {

constexpr std::int64_t kMs = 1000000;
constexpr std::uint64_t kRun = 0xABCDEF;
constexpr std::uint64_t kWriter = 11;

/// A backend that records what it is asked to apply, with a real CiA 402 state machine.
class RecordingDrive final : public Drive {
 public:
  Measurement sample() override {
    power_.step();
    Measurement m;
    m.applied_force_n = own_loops_force_n;
    m.load_sensor_saturated = load_sensor_saturated;
    return m;
  }
  void apply(double force_n) override { applied.push_back(power_.force_allowed() ? force_n : 0.0); }
  void apply_setpoint(const Setpoint& setpoint) override {
    setpoints.push_back(setpoint);
    Drive::apply_setpoint(setpoint);
  }
  TransitionResult request(DriveCommand c) override { return power_.request(c); }
  void fault(std::uint16_t code) override { power_.fault(code); }
  PowerState power_state() const override { return power_.state(); }
  std::uint16_t error_code() const override { return power_.error_code(); }
  std::uint64_t fault_count() const override { return power_.fault_count(); }
  bool simulated() const override { return true; }
  std::vector<double> applied;
  std::vector<Setpoint> setpoints;
  /// What sample() reports as the force its own loops applied (NaN: it does not say).
  double own_loops_force_n = std::numeric_limits<double>::quiet_NaN();
  bool load_sensor_saturated = false;

 private:
  PowerStateMachine power_;
};

DriveLoopParams params(bool realtime) {
  DriveLoopParams p;
  p.period_s = 1e-3;
  p.realtime = realtime;
  p.watchdog_s = 3e-3;
  p.watchdog_arm_ticks = 3;
  p.controller_lost_s = 0.05;
  p.first_command_timeout_s = 1.0;
  p.expected_ticks = 10000;
  return p;
}

void enable(DriveLoop& loop, Drive& drive, std::int64_t now) {
  drive.sample();  // initialisation: switch on disabled
  while (const auto next = next_command_towards_operation_enabled(drive.power_state())) {
    ASSERT_TRUE(loop.request(*next, now).accepted);
  }
  ASSERT_EQ(drive.power_state(), PowerState::kOperationEnabled);
}

ForceCommandIn cmd(std::uint64_t tick, double force, std::uint64_t writer = kWriter, std::uint64_t run = kRun) {
  return ForceCommandIn{run, tick, force, writer, 0};
}

/// One realtime tick starting at t0 + k ms; `answer` commands for tick `answer_tick` (or none).
TickEvents realtime_tick(DriveLoop& loop, std::uint64_t k, bool answer, std::uint64_t answer_tick, double force = 1.0) {
  const std::int64_t start = static_cast<std::int64_t>(k) * kMs;
  loop.begin_tick(k, start);
  loop.published(start, start);
  if (answer) loop.offer(cmd(answer_tick, force));
  return loop.end_tick(start + kMs / 2);
}

TEST(DriveLoop, LockstepTakesOnlyTheAnswerToTheTickAndHoldsTheLastFiniteForce) {
  RecordingDrive drive;
  DriveLoop loop(params(false), drive);
  loop.set_run_id(kRun);
  enable(loop, drive, 0);
  loop.begin_tick(0, 0);
  EXPECT_EQ(loop.offer(cmd(1, 5.0)), Verdict::kFutureTick);
  EXPECT_FALSE(loop.answered());
  EXPECT_EQ(loop.offer(cmd(0, 7.0)), Verdict::kAccepted);
  EXPECT_TRUE(loop.answered());
  loop.end_tick(0);
  loop.begin_tick(1, 0);
  EXPECT_EQ(loop.offer(cmd(0, 9.0)), Verdict::kStale);
  EXPECT_EQ(loop.offer(cmd(1, std::numeric_limits<double>::quiet_NaN())), Verdict::kNonFinite);
  EXPECT_TRUE(loop.answered());  // answered, but the last finite force stays
  loop.end_tick(0);
  EXPECT_EQ(drive.applied, (std::vector<double>{7.0, 7.0}));
  EXPECT_EQ(loop.counters().late, 2u);
  EXPECT_EQ(loop.counters().rejected, 1u);
  EXPECT_EQ(loop.counters().safe_ticks, 0u);
}

TEST(DriveLoop, TheWholeSetpointIsHeldAndPassedOnAndADriveClosingItsOwnLoopsReportsTheForce) {
  RecordingDrive drive;
  DriveLoop loop(params(true), drive);
  loop.set_run_id(kRun);
  enable(loop, drive, 0);
  ForceCommandIn c = cmd(0, 40.0);
  c.feedforward_force_n = 7.0;
  c.velocity_mps = 0.2;
  c.position_m = 0.01;
  loop.begin_tick(0, 0);
  loop.published(0, 0);
  EXPECT_EQ(loop.offer(c), Verdict::kAccepted);
  loop.end_tick(kMs / 2);
  ASSERT_EQ(drive.setpoints.size(), 1u);
  EXPECT_EQ(drive.setpoints[0].force_n, 40.0);
  EXPECT_EQ(drive.setpoints[0].feedforward_force_n, 7.0);
  EXPECT_EQ(drive.setpoints[0].velocity_mps, 0.2);
  EXPECT_EQ(drive.setpoints[0].position_m, 0.01);

  // A reference that is not finite is refused like a force that is not: the last setpoint holds.
  ForceCommandIn bad = cmd(1, 41.0);
  bad.velocity_mps = std::numeric_limits<double>::quiet_NaN();
  drive.own_loops_force_n = 33.0;  // the drive's loops applied 33 N over the last tick
  const TickReport& report = loop.begin_tick(1, kMs);
  EXPECT_EQ(report.applied_force_n, 33.0) << "the drive's account, not the force the loop held";
  loop.published(kMs, kMs);
  EXPECT_EQ(loop.offer(bad), Verdict::kNonFinite);
  loop.end_tick(kMs + kMs / 2);
  EXPECT_EQ(drive.setpoints.back().velocity_mps, 0.2);

  // Out of operation enabled: no force, no feedforward; the references go on for the drive to hold.
  ASSERT_TRUE(loop.request(DriveCommand::kDisableOperation, 2 * kMs).accepted);
  loop.begin_tick(2, 2 * kMs);
  loop.published(2 * kMs, 2 * kMs);
  loop.end_tick(2 * kMs + kMs / 2);
  EXPECT_EQ(drive.setpoints.back().force_n, 0.0);
  EXPECT_EQ(drive.setpoints.back().feedforward_force_n, 0.0);
  EXPECT_EQ(drive.setpoints.back().position_m, 0.01);
}

TEST(DriveLoop, ALoadSensorAtItsRailIsFlaggedInTheTicksStatus) {
  RecordingDrive drive;
  DriveLoop loop(params(false), drive);
  EXPECT_EQ(loop.begin_tick(0, 0).status & status::kLoadSensorSaturated, 0u);
  drive.load_sensor_saturated = true;
  EXPECT_EQ(loop.begin_tick(1, kMs).status & status::kLoadSensorSaturated, status::kLoadSensorSaturated);
}

TEST(DriveLoop, AnotherRunsCommandIsRejected) {
  RecordingDrive drive;
  DriveLoop loop(params(false), drive);
  loop.set_run_id(kRun);
  enable(loop, drive, 0);
  loop.begin_tick(0, 0);
  EXPECT_EQ(loop.offer(cmd(0, 3.0, kWriter, kRun + 1)), Verdict::kOtherRun);
  EXPECT_EQ(loop.offer(cmd(0, 3.0, kWriter, 0)), Verdict::kOtherRun);
  EXPECT_FALSE(loop.answered());
  EXPECT_EQ(loop.counters().other_run, 2u);
}

TEST(DriveLoop, ASecondWriterIsRefusedAndFlaggedNeverApplied) {
  RecordingDrive drive;
  DriveLoop loop(params(true), drive);
  loop.set_run_id(kRun);
  enable(loop, drive, 0);
  for (std::uint64_t k = 0; k < 6; ++k) {
    const std::int64_t t = static_cast<std::int64_t>(k) * kMs;
    const TickReport& report = loop.begin_tick(k, t);
    if (k >= 2) {
      EXPECT_NE(report.status & status::kForeignCommand, 0u) << k;
    }
    loop.published(t, t);
    EXPECT_EQ(loop.offer(cmd(k, 1.0, kWriter)), Verdict::kAccepted);
    EXPECT_EQ(loop.offer(cmd(k, -100.0, 99)), Verdict::kForeignWriter);
    loop.end_tick(t + kMs / 2);
  }
  std::uint64_t writer = 0;
  EXPECT_TRUE(loop.take_new_foreign_writer(writer));
  EXPECT_EQ(writer, 99u);
  EXPECT_FALSE(loop.take_new_foreign_writer(writer));  // reported once
  EXPECT_EQ(loop.owner_writer_id(), kWriter);
  EXPECT_EQ(loop.counters().foreign, 6u);
  for (double f : drive.applied) EXPECT_EQ(f, 1.0);
}

TEST(DriveLoop, RealtimeRejectsFutureNonFiniteAndOlderCommandsAndHoldsTheNewest) {
  RecordingDrive drive;
  DriveLoop loop(params(true), drive);
  loop.set_run_id(kRun);
  enable(loop, drive, 0);
  loop.begin_tick(0, 0);
  loop.published(0, 0);
  EXPECT_EQ(loop.offer(cmd(5, 1.0)), Verdict::kFutureTick);
  EXPECT_EQ(loop.offer(cmd(0, std::numeric_limits<double>::infinity())), Verdict::kNonFinite);
  EXPECT_EQ(loop.offer(cmd(0, 2.0)), Verdict::kAccepted);
  loop.end_tick(kMs / 2);
  loop.begin_tick(1, kMs);
  loop.published(kMs, kMs);
  EXPECT_EQ(loop.offer(cmd(0, 3.0)), Verdict::kStale);
  loop.end_tick(kMs + kMs / 2);  // no fresh command: late, the newest (2.0) held
  EXPECT_EQ(drive.applied, (std::vector<double>{2.0, 2.0}));
  EXPECT_EQ(loop.counters().late, 1u);
  EXPECT_EQ(loop.counters().rejected, 3u);
}

TEST(DriveLoop, WatchdogDoesNotArmWhileTheControllerWorksThroughABacklog) {
  RecordingDrive drive;
  DriveLoop loop(params(true), drive);
  loop.set_run_id(kRun);
  enable(loop, drive, 0);
  // The controller answers old feedback, always 10 ticks behind (a backlog), for 100 ticks:
  // each answer is accepted, none is fresh, the watchdog never arms and never trips.
  for (std::uint64_t k = 0; k < 100; ++k) {
    const TickEvents e = realtime_tick(loop, k, k >= 10, k >= 10 ? k - 10 : 0);
    EXPECT_FALSE(e.watchdog_tripped) << k;
  }
  EXPECT_FALSE(loop.watchdog_armed());
  EXPECT_EQ(loop.counters().watchdog_trips, 0u);
  EXPECT_EQ(drive.power_state(), PowerState::kOperationEnabled);
}

TEST(DriveLoop, WatchdogArmsAfterFreshAnswersAndTripsWithinWatchdogPlusOneTick) {
  RecordingDrive drive;
  DriveLoop loop(params(true), drive);
  loop.set_run_id(kRun);
  enable(loop, drive, 0);
  std::uint64_t k = 0;
  for (; k < 2; ++k) realtime_tick(loop, k, true, k);
  EXPECT_FALSE(loop.watchdog_armed());
  realtime_tick(loop, k, true, k);
  ++k;
  EXPECT_TRUE(loop.watchdog_armed());
  for (; k < 20; ++k) realtime_tick(loop, k, true, k);
  // The controller dies after answering tick 19: tick 20 is the first unanswered feedback.
  const std::uint64_t last_answered = k - 1;
  std::uint64_t tripped_at = 0;
  for (; k < 40; ++k) {
    const TickEvents e = realtime_tick(loop, k, false, 0);
    if (e.watchdog_tripped) {
      tripped_at = k;
      EXPECT_EQ(e.unanswered_tick, last_answered + 1);
      break;
    }
  }
  ASSERT_NE(tripped_at, 0u);
  // Published at (last + 1) ms, checked half a tick into each tick: the trip comes in the tick
  // in which its age first exceeds 3 ms, at most watchdog + 1 tick after the feedback.
  EXPECT_LE(tripped_at - (last_answered + 1), 4u);
  EXPECT_GE(tripped_at - (last_answered + 1), 3u);
  EXPECT_EQ(drive.power_state(), PowerState::kFaultReactionActive);
  EXPECT_EQ(drive.error_code(), kErrorCommandTimeout);
  EXPECT_EQ(drive.applied.back(), 0.0);  // zero force in the very tick it trips
  // Latched: answers again do not bring force back.
  for (std::uint64_t j = 0; j < 5; ++j, ++k) {
    const TickReport& r = loop.begin_tick(k, static_cast<std::int64_t>(k) * kMs);
    EXPECT_NE(r.status & status::kWatchdogTripped, 0u);
    EXPECT_NE(r.status & status::kSafeState, 0u);
    loop.published(static_cast<std::int64_t>(k) * kMs, static_cast<std::int64_t>(k) * kMs);
    loop.offer(cmd(k, 1.0));
    loop.end_tick(static_cast<std::int64_t>(k) * kMs + kMs / 2);
    EXPECT_EQ(drive.applied.back(), 0.0);
  }
  EXPECT_EQ(drive.power_state(), PowerState::kFault);
  EXPECT_GT(loop.counters().safe_ticks, 0u);
  // Fault reset and enable: force again, the watchdog re-arms from scratch.
  EXPECT_TRUE(loop.request(DriveCommand::kFaultReset, 0).accepted);
  EXPECT_TRUE(loop.request(DriveCommand::kShutdown, 0).accepted);
  EXPECT_TRUE(loop.request(DriveCommand::kEnableOperation, 0).accepted);
  EXPECT_FALSE(loop.watchdog_armed());
  realtime_tick(loop, k, true, k);
  EXPECT_EQ(drive.applied.back(), 1.0);
}

TEST(DriveLoop, WatchdogWaitsWhileTheDriveItselfRunsLateThenTrips) {
  RecordingDrive drive;
  DriveLoop loop(params(true), drive);
  loop.set_run_id(kRun);
  enable(loop, drive, 0);
  std::uint64_t k = 0;
  for (; k < 10; ++k) realtime_tick(loop, k, true, k);
  ASSERT_TRUE(loop.watchdog_armed());
  // The host holds the drive's thread for 6 ms after tick 10 was published: ticks 11..16 start
  // late (back to back, catching up). The controller's answer to 10 is not its fault; no trip.
  loop.begin_tick(10, 10 * kMs);
  loop.published(10 * kMs, 10 * kMs);
  loop.end_tick(10 * kMs + kMs / 2);
  const std::int64_t resumed = 16 * kMs + kMs / 2;
  for (k = 11; k <= 16; ++k) {
    loop.begin_tick(k, resumed, static_cast<std::int64_t>(k) * kMs);
    loop.published(resumed, resumed);
    const TickEvents e = loop.end_tick(resumed);
    EXPECT_FALSE(e.watchdog_tripped) << k;
  }
  // Ticks 11..15 started more than a period late; tick 16, half a tick late, is on time again
  // but spared: the controller, held with the drive, has had no time yet.
  EXPECT_EQ(loop.counters().drive_stalls, 5u);
  EXPECT_EQ(drive.power_state(), PowerState::kOperationEnabled);
  // A tick later and still no answer: the check at the tick's start trips.
  loop.begin_tick(17, 17 * kMs, 17 * kMs);
  EXPECT_EQ(drive.power_state(), PowerState::kFaultReactionActive);
  loop.published(17 * kMs, 17 * kMs);
  const TickEvents e = loop.end_tick(17 * kMs + kMs / 2);
  EXPECT_TRUE(e.watchdog_tripped);
  EXPECT_EQ(e.tripped_mono_ns, 17 * kMs);  // at the tick's start, not half a tick later
}

TEST(DriveLoop, ARefusedRequestLeavesTheStateAndSaysWhy) {
  RecordingDrive drive;
  DriveLoop loop(params(true), drive);
  drive.sample();
  const TransitionResult r = loop.request(DriveCommand::kEnableOperation, 0);
  EXPECT_FALSE(r.accepted);
  EXPECT_EQ(r.from, PowerState::kSwitchOnDisabled);
  EXPECT_EQ(drive.power_state(), PowerState::kSwitchOnDisabled);
  EXPECT_STRNE(r.reason, "");
}

TEST(DriveLoop, ASilentControllerIsLostAfterItsTimeoutOnce) {
  RecordingDrive drive;
  DriveLoop loop(params(true), drive);
  loop.set_run_id(kRun);
  enable(loop, drive, 0);
  std::uint64_t k = 0;
  for (; k < 10; ++k) realtime_tick(loop, k, true, k);
  std::uint64_t lost_at = 0;
  int reports = 0;
  for (; k < 200; ++k) {
    if (realtime_tick(loop, k, false, 0).controller_lost) {
      if (reports++ == 0) lost_at = k;
    }
  }
  EXPECT_EQ(reports, 1);
  // Last command taken at tick 9's start (9 ms); lost once more than 50 ms passed, checked at
  // half a tick: tick 59 (59.5 ms).
  EXPECT_EQ(lost_at, 59u);
}

TEST(DriveLoop, TicksBeforeTheFirstEnableAreNotSafeTicksTheOnesAfterAre) {
  RecordingDrive drive;
  DriveLoop loop(params(false), drive);
  loop.set_run_id(kRun);
  for (std::uint64_t k = 0; k < 5; ++k) {
    loop.begin_tick(k, 0);
    loop.offer(cmd(k, 4.0));
    loop.end_tick(0);
  }
  EXPECT_EQ(loop.counters().safe_ticks, 0u);
  EXPECT_FALSE(loop.ever_enabled());
  for (double f : drive.applied) EXPECT_EQ(f, 0.0);  // never force before enable
  while (const auto next = next_command_towards_operation_enabled(drive.power_state())) loop.request(*next, 0);
  for (std::uint64_t k = 5; k < 10; ++k) {
    loop.begin_tick(k, 0);
    loop.offer(cmd(k, 4.0));
    loop.end_tick(0);
  }
  EXPECT_TRUE(loop.ever_enabled());
  EXPECT_EQ(drive.applied.back(), 4.0);
  loop.request(DriveCommand::kQuickStop, 0);
  for (std::uint64_t k = 10; k < 13; ++k) {
    loop.begin_tick(k, 0);
    loop.offer(cmd(k, 4.0));
    loop.end_tick(0);
  }
  EXPECT_EQ(loop.counters().safe_ticks, 3u);
  EXPECT_EQ(drive.applied.back(), 0.0);
}

TEST(DriveLoop, ParametersAreValidatedWithTheValue) {
  RecordingDrive drive;
  DriveLoopParams p = params(true);
  p.watchdog_s = 0.5e-3;
  try {
    DriveLoop loop(p, drive);
    FAIL() << "accepted a watchdog shorter than a period";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("watchdog_s"), std::string::npos) << e.what();
  }
  p = params(true);
  p.watchdog_arm_ticks = 0;
  EXPECT_THROW(DriveLoop(p, drive), std::invalid_argument);
  p = params(true);
  p.controller_lost_s = std::nan("");
  EXPECT_THROW(DriveLoop(p, drive), std::invalid_argument);
  EXPECT_THROW(TickClock(0, true), std::invalid_argument);
  EXPECT_THROW(TickClock(1000000, true, 1000000), std::invalid_argument);
}

TEST(TickClock, RealtimeTicksOnAbsoluteTimesAndNamesAnOverrunLockstepDoesNotPace) {
  TickClock realtime(1'000'000'000, true, 200'000);
  const std::int64_t before = monotonic_ns();
  realtime.start();
  const std::int64_t t0 = realtime.tick_start_ns();
  EXPECT_EQ(t0 % 1'000'000'000, 0) << "tick 0 on the whole periods of CLOCK_MONOTONIC";
  EXPECT_GE(t0, before);
  EXPECT_LT(t0 - before, 1'000'000'000);
  EXPECT_FALSE(realtime.advance()) << "a second-long tick just started cannot have overrun";
  EXPECT_EQ(realtime.tick_start_ns(), t0 + 1'000'000'000) << "t_k = t_0 + k T: no drift from the time spent";
  EXPECT_EQ(realtime.wake_early_ns(), 200'000);
  TickClock fast(1'000, true);  // a 1 us tick: the time to advance overruns it
  fast.start();
  const std::int64_t start = monotonic_ns();
  while (monotonic_ns() - start < 10'000) {
  }
  EXPECT_TRUE(fast.advance());
  TickClock lockstep(1'000, false);
  lockstep.start();
  EXPECT_FALSE(lockstep.advance());
}

TEST(LoopStatistics, PeriodFitAndPercentiles) {
  LoopStatistics s(100);
  // One start 0.4 ms late, in the middle: the least-squares slope does not move.
  for (std::uint64_t k = 0; k <= 100; ++k) {
    s.record_tick_start(k, 5000 + static_cast<std::int64_t>(k) * 1000000 + (k == 50 ? 400000 : 0));
  }
  EXPECT_NEAR(s.mean_period_s(), 1e-3, 1e-12);
  for (int i = 1; i <= 100; ++i) s.record_latency_ns(i * 1000);
  s.record_latency_ns(1);  // beyond the reserved room: counted, not kept
  const LatencySummary l = s.latency();
  EXPECT_EQ(l.count, 100u);
  EXPECT_EQ(s.latencies_dropped(), 1u);
  EXPECT_DOUBLE_EQ(l.p50_us, 50.0);
  EXPECT_DOUBLE_EQ(l.p99_us, 99.0);
  EXPECT_DOUBLE_EQ(l.max_us, 100.0);
}

TEST(DriveLoop, WithTheSimulatedDriveTheTraceEqualsTheDriveDrivenDirectly) {
  const SystemParams p = load_system_params(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml", {});
  const Scenario scenario =
      load_scenario(std::string(PMLSM_SOURCE_DIR) + "/configs/scenarios/pulse.yaml", p.timing.control_period_s);
  SimulatedDrive direct(p, scenario_initial_condition(scenario));
  SimulatedDriveBackend backend(p, scenario_initial_condition(scenario));
  DriveLoop loop(params(false), backend);
  loop.set_run_id(kRun);
  while (const auto next = next_command_towards_operation_enabled(backend.power_state())) loop.request(*next, 0);
  for (std::uint64_t k = 0; k < 300; ++k) {
    const DriveFeedback a = direct.sample();
    const TickReport& b = loop.begin_tick(k, 0);
    ASSERT_EQ(a.encoder_position_m, b.measurement.position_m) << k;
    ASSERT_EQ(a.velocity_mps, b.measurement.velocity_mps) << k;
    ASSERT_EQ(a.i_q_a, b.measurement.i_q_a) << k;
    const double force = 200.0 * std::sin(0.05 * static_cast<double>(k)) - 10.0 * a.velocity_mps;
    direct.apply_force(force);
    loop.offer(cmd(k, force));
    loop.end_tick(0);
  }
  EXPECT_EQ(direct.plant().truth().state.load_velocity_mps,
            backend.simulated_drive().plant().truth().state.load_velocity_mps);
}

// The simulated drive faults (0x6100) when its plant diverges: zero force, finite readings,
// the state named; a fault reset cannot clear it.
TEST(DriveLoop, ADivergingSimulatedPlantFaultsTheDrive) {
  const SystemParams p = load_system_params(std::string(PMLSM_SOURCE_DIR) + "/configs/system.yaml", {});
  PlantInitialCondition far;
  far.load_position_m = 5e5;
  SimulatedDriveBackend backend(p, far);
  DriveLoop loop(params(false), backend);
  loop.set_run_id(kRun);
  while (const auto next = next_command_towards_operation_enabled(backend.power_state())) loop.request(*next, 0);
  ASSERT_EQ(backend.power_state(), PowerState::kOperationEnabled);
  EXPECT_STREQ(backend.fault_detail(), "");
  for (std::uint64_t k = 0; k < 5; ++k) {
    const TickReport& r = loop.begin_tick(k, 0);
    for (double x :
         {r.measurement.position_m, r.measurement.velocity_mps, r.measurement.i_q_a, r.measurement.thrust_force_n}) {
      ASSERT_TRUE(std::isfinite(x)) << k;
    }
    if (k > 1) {
      EXPECT_EQ(r.applied_force_n, 0.0) << k;  // tick 0 had its force; it diverged at its end
    }
    loop.offer(cmd(k, 100.0));
    loop.end_tick(0);
  }
  EXPECT_EQ(backend.error_code(), kErrorPlantDiverged);
  EXPECT_EQ(backend.fault_count(), 1u);
  EXPECT_NE(std::string(backend.fault_detail()).find("plant state "), std::string::npos) << backend.fault_detail();
  EXPECT_NE(std::string(backend.fault_detail()).find("in tick 0"), std::string::npos) << backend.fault_detail();
  // Fault reset: the next tick faults again.
  loop.request(DriveCommand::kFaultReset, 0);
  loop.begin_tick(5, 0);
  EXPECT_TRUE(backend.power_state() == PowerState::kFaultReactionActive || backend.power_state() == PowerState::kFault);
}

}  // namespace
}  // namespace pmlsm::drive

// RunValidity, RunIdTracker and the results row: when the evaluator (and the in-process loop)
// may present a run as valid, and what they print when not. No DDS.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "results_table.hpp"
#include "run_validity.hpp"

namespace pmlsm::node {
namespace {

constexpr std::uint32_t kSafe = kFeedbackStatusSafeState;
constexpr std::uint32_t kFault = kFeedbackStatusFault;
constexpr std::uint32_t kSimulated = 64;      // STATUS_SIMULATED
constexpr std::uint32_t kForceSaturated = 2;  // STATUS_FORCE_SATURATED
constexpr std::uint32_t kCommandLate = 8;     // STATUS_COMMAND_LATE
constexpr std::uint8_t kEnabled = kPowerOperationEnabled;

DriveTickStatus good() { return {kSimulated, kEnabled, 0}; }

TEST(RunValidity, AllTicksInOperationEnabledIsValid) {
  RunValidity v;
  for (std::uint64_t k = 0; k < 100; ++k) v.add(k, good());
  EXPECT_TRUE(v.valid());
  EXPECT_EQ(v.ticks(), 100u);
  EXPECT_EQ(v.bad_ticks(), 0u);
  EXPECT_EQ(v.reason(), "");
}

TEST(RunValidity, NoTicksIsValid) { EXPECT_TRUE(RunValidity{}.valid()); }

TEST(RunValidity, StatusBitsOtherThanSafeStateAndFaultKeepTheRunValid) {
  RunValidity v;
  v.add(0, {kSimulated | kForceSaturated | kCommandLate, kEnabled, 0});
  EXPECT_TRUE(v.valid());
}

TEST(RunValidity, AnOldErrorCodeAloneKeepsTheRunValid) {
  // 0x603F keeps the last fault's code after its reset: enabled again, the run is fine.
  RunValidity v;
  v.add(0, {kSimulated, kEnabled, 0x8130});
  EXPECT_TRUE(v.valid());
}

TEST(RunValidity, AFaultForTheRestOfTheRun) {
  RunValidity v;
  v.add(0, good());
  v.add(1, good());
  v.add(2, {kSafe | kFault, kPowerFaultReactionActive, 0x8130});
  for (std::uint64_t k = 3; k < 2000; ++k) v.add(k, {kSafe | kFault, kPowerFault, 0x8130});
  EXPECT_FALSE(v.valid());
  EXPECT_EQ(v.bad_ticks(), 1998u);
  EXPECT_EQ(v.first_bad_tick(), 2u);
  EXPECT_EQ(v.error_code(), 0x8130u);
  EXPECT_EQ(v.reason(), "drive force off for 1998 ticks from tick 2 (fault 0x8130, power state fault reaction active)");
}

TEST(RunValidity, EachConditionAloneMakesATickBad) {
  for (const DriveTickStatus s : {DriveTickStatus{kSafe, kEnabled, 0}, DriveTickStatus{kFault, kEnabled, 0},
                                  DriveTickStatus{0, 3 /* switched on */, 0}}) {
    RunValidity v;
    v.add(0, good());
    v.add(1, s);
    EXPECT_FALSE(v.valid()) << s.status << " " << int{s.power_state};
    EXPECT_EQ(v.bad_ticks(), 1u);
  }
}

TEST(RunValidity, SafeStateWithoutFault) {
  RunValidity v;
  for (std::uint64_t k = 0; k < 10; ++k) v.add(k, good());
  for (std::uint64_t k = 10; k < 13; ++k) v.add(k, {kSafe | 16 /* watchdog */, kEnabled, 0});
  EXPECT_EQ(v.reason(), "drive force off for 3 ticks from tick 10 (safe state)");
}

TEST(RunValidity, SafeStateWithTheCodeOfAnEarlierFault) {
  RunValidity v;
  v.add(4, {kSafe, kEnabled, 0x2310});
  EXPECT_EQ(v.reason(), "drive force off for 1 tick from tick 4 (safe state, last error 0x2310)");
}

TEST(RunValidity, NeverEnabled) {
  RunValidity v;
  for (std::uint64_t k = 0; k < 5; ++k) v.add(k, {kSimulated, 1 /* switch on disabled */, 0});
  EXPECT_EQ(v.reason(), "drive force off for 5 ticks from tick 0 (power state switch on disabled)");
}

TEST(RunValidity, FaultWithoutAnErrorCode) {
  RunValidity v;
  v.add(7, {kFault, kPowerFault, 0});
  EXPECT_EQ(v.reason(), "drive force off for 1 tick from tick 7 (fault, power state fault)");
}

TEST(RunValidity, AFaultPowerStateCountsAsAFaultWithoutTheBit) {
  RunValidity v;
  v.add(7, {0, kPowerFault, 0x5400});
  EXPECT_EQ(v.reason(), "drive force off for 1 tick from tick 7 (fault 0x5400, power state fault)");
}

TEST(RunValidity, AnUnknownPowerStateIsNamedSo) {
  RunValidity v;
  v.add(0, {0, 200, 0});
  EXPECT_EQ(v.reason(), "drive force off for 1 tick from tick 0 (power state unknown)");
}

TEST(RunValidity, BadTicksApartAreGivenAsARange) {
  RunValidity v;
  for (std::uint64_t k = 0; k < 50; ++k) {
    v.add(k, k == 10 || k == 20 || k == 40 ? DriveTickStatus{kSafe, kEnabled, 0} : good());
  }
  EXPECT_EQ(v.bad_ticks(), 3u);
  EXPECT_EQ(v.reason(), "drive force off for 3 ticks, ticks 10..40 (safe state)");
}

TEST(RunValidity, TheOrderOfTheTicksDoesNotMatter) {
  // Earliest tick wins for the error code and the power state, whatever order they came in.
  RunValidity forward, backward;
  const auto status_of = [](std::uint64_t k) -> DriveTickStatus {
    if (k < 5) return good();
    if (k < 8) return {kSafe, 3 /* switched on */, static_cast<std::uint16_t>(0x1000 + k)};
    return {kSafe | kFault, kPowerFault, static_cast<std::uint16_t>(0x2000 + k)};
  };
  for (std::uint64_t k = 0; k < 12; ++k) forward.add(k, status_of(k));
  for (std::uint64_t k = 12; k-- > 0;) backward.add(k, status_of(k));
  EXPECT_EQ(forward.reason(), "drive force off for 7 ticks from tick 5 (fault 0x1005, power state switched on)");
  EXPECT_EQ(backward.reason(), forward.reason());
  EXPECT_EQ(backward.first_bad_tick(), 5u);
}

TEST(RunValidity, PowerStateNames) {
  EXPECT_STREQ(power_state_name(0), "not ready to switch on");
  EXPECT_STREQ(power_state_name(kPowerOperationEnabled), "operation enabled");
  EXPECT_STREQ(power_state_name(kPowerFaultReactionActive), "fault reaction active");
  EXPECT_STREQ(power_state_name(kPowerFault), "fault");
  EXPECT_STREQ(power_state_name(8), "unknown");
}

// ---- RunIdTracker -------------------------------------------------------------------------

TEST(RunIdTracker, ZeroIsIgnoredAndTheFirstRunIsKept) {
  RunIdTracker t;
  EXPECT_FALSE(t.observe(0, 0));
  EXPECT_EQ(t.run_id(), 0u);
  EXPECT_FALSE(t.observe(0x1a2b, 1));
  EXPECT_EQ(t.run_id(), 0x1a2bu);
  EXPECT_FALSE(t.observe(0x1a2b, 2));
  EXPECT_FALSE(t.observe(0, 3));  // a node that follows no run yet
  EXPECT_EQ(t.run_id(), 0x1a2bu);
}

TEST(RunIdTracker, AnotherRunIsAChange) {
  RunIdTracker t;
  t.observe(0x1a2b, 0);
  const auto change = t.observe(0x3c4d, 812);
  ASSERT_TRUE(change);
  EXPECT_EQ(change->from_run, 0x1a2bu);
  EXPECT_EQ(change->to_run, 0x3c4du);
  EXPECT_EQ(change->tick, 812u);
  EXPECT_EQ(t.run_id(), 0x1a2bu);  // the first run stays the reference
  EXPECT_TRUE(t.observe(0x5e6f, 813));
}

TEST(RunIdTracker, RestartMessage) {
  EXPECT_EQ(restart_message("evaluator", {0x1a2b, 0xfedcba9876543210, 812}),
            "evaluator: the drive restarted (run 0000000000001a2b -> fedcba9876543210) at its tick 812: results "
            "would mix two runs; none written");
}

// ---- the results row ----------------------------------------------------------------------

ScenarioMetrics some_metrics() {
  ScenarioMetrics m;
  m.cost_true = 65.25;
  m.cost_estimated = 48.515;
  m.load_vibration_rms_mps = 0.083231;
  m.load_tracking_rms_mps = 0.083436;
  m.load_settling_time_s = std::numeric_limits<double>::infinity();
  m.peak_force_command_n = 145.9;
  m.est_load_velocity_rms_error_mps = 0.02977;
  m.applied_force_rms_n = 120.5;
  return m;
}

TEST(ResultsRow, AValidRunIsTheRowAlone) {
  EXPECT_EQ(results_row("pulse pi", some_metrics()),
            "pulse pi                     65.250     48.515         83.231         83.436  not settled        "
            "145.9         29.770        120.5           0");
}

TEST(ResultsRow, AnInvalidRunKeepsItsNumbersAndSaysWhyOnTheSameLine) {
  const std::string valid = results_row("pulse pi", some_metrics());
  const std::string invalid =
      results_row("pulse pi", some_metrics(), "drive force off for 1998 ticks from tick 2 (fault 0x8130)");
  EXPECT_EQ(invalid, valid + "  INVALID: drive force off for 1998 ticks from tick 2 (fault 0x8130)");
  EXPECT_EQ(invalid.find('\n'), std::string::npos);
}

TEST(ResultsRow, WithoutPlantTruthTheTrueLoadsColumnsReadNaAndTheRowSaysSo) {
  ScenarioMetrics m = some_metrics();
  m.cost_true = std::numeric_limits<double>::quiet_NaN();  // what a trace of nan truth gives
  EXPECT_EQ(results_row("pulse virtual_rig", m, "", false),
            "pulse virtual_rig               n/a     48.515            n/a            n/a          n/a        "
            "145.9            n/a        120.5           0  (no PlantTruth)");
  EXPECT_EQ(
      results_row("pulse virtual_rig", m, "drive force off", false).find("  (no PlantTruth)  INVALID: drive force off"),
      std::string("pulse virtual_rig               n/a     48.515            n/a            n/a          n/a        "
                  "145.9            n/a        120.5           0")
          .size());
}

TEST(ResultsRow, ALongScenarioNameIsNotCut) {
  const std::string name(300, 'x');
  EXPECT_EQ(results_row(name, some_metrics()).rfind(name, 0), 0u);
}

}  // namespace
}  // namespace pmlsm::node

// The scenario references a rig needs (pmlsm/sim/scenario.hpp): ramp, trapezoid, S-curve,
// chirp, multi-sine and CSV profiles; their loading from YAML (every key known and present,
// the CSV checked once with file, line and value), the reference-model bypass and the
// settling metric over constant segments.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "config_edit.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/control/external_reference.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/metrics.hpp"
#include "pmlsm/sim/velocity_controller.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

constexpr double kPeriod = 1e-3;
constexpr double kPi = 3.14159265358979323846;

Scenario move(CommandShape shape) {
  Scenario s;
  s.name = "move";
  s.duration_s = 2.0;
  s.shape = shape;
  s.amplitude_mps = 0.3;
  s.accel_mps2 = 3.0;
  s.jerk_mps3 = 60.0;
  s.hold_s = 0.5;
  s.start_s = 0.1;
  s.cost_window_s = 1.0;
  s.settling_band = 0.02;
  return s;
}

struct Extremes {
  double max_accel = 0;  // largest |dv/dt| by differences at dt
  double max_jerk = 0;   // largest |d2v/dt2| by second differences
};

Extremes extremes(const Scenario& s, double dt) {
  Extremes e;
  double prev_a = 0;
  for (double t = dt; t < s.duration_s; t += dt) {
    const double a = (s.command_mps(t) - s.command_mps(t - dt)) / dt;
    e.max_accel = std::max(e.max_accel, std::abs(a));
    e.max_jerk = std::max(e.max_jerk, std::abs(a - prev_a) / dt);
    prev_a = a;
  }
  return e;
}

// ------------------------------------------------------------------ shapes

TEST(ReferenceShapes, RampRisesAtItsSlopeAndHolds) {
  Scenario s = move(CommandShape::kRamp);
  s.accel_mps2 = 1.5;
  s.validate(kPeriod);
  EXPECT_EQ(s.command_mps(0.05), 0.0);
  EXPECT_NEAR(s.command_mps(0.2), 0.15, 1e-12);  // 0.1 s into the ramp at 1.5 m/s^2
  EXPECT_EQ(s.command_mps(0.3), 0.3);            // reached at 0.1 + 0.2 s, exactly
  EXPECT_EQ(s.command_mps(1.9), 0.3);            // and held to the end
  EXPECT_NEAR(extremes(s, 1e-4).max_accel, 1.5, 1e-6);
}

TEST(ReferenceShapes, TrapezoidRespectsItsAccelerationAndHoldsExactly) {
  const Scenario s = move(CommandShape::kTrapezoid);
  s.validate(kPeriod);
  // rise 0.1..0.2 s, hold to 0.7 s, fall to 0.8 s, rest.
  EXPECT_EQ(s.command_mps(0.0999), 0.0);
  EXPECT_NEAR(s.command_mps(0.15), 0.15, 1e-12);
  EXPECT_EQ(s.command_mps(0.2), 0.3);
  EXPECT_EQ(s.command_mps(0.69), 0.3);
  EXPECT_NEAR(s.command_mps(0.75), 0.15, 1e-12);
  EXPECT_EQ(s.command_mps(0.8), 0.0);
  EXPECT_EQ(s.command_mps(1.5), 0.0);
  EXPECT_LE(extremes(s, 1e-4).max_accel, 3.0 * (1 + 1e-9));
  EXPECT_GT(extremes(s, 1e-4).max_accel, 2.99);
}

TEST(ReferenceShapes, SCurveRespectsAccelerationAndJerkLimits) {
  const Scenario s = move(CommandShape::kSCurve);
  s.validate(kPeriod);
  // dv = 0.3 >= a^2/j = 0.15: tj = 0.05 s, constant acceleration 0.05 s, rise 0.15 s.
  const VelocityTransition rise{0.3, 3.0, 60.0};
  EXPECT_NEAR(rise.duration_s(), 0.3 / 3.0 + 3.0 / 60.0, 1e-12);
  EXPECT_NEAR(s.command_mps(0.1 + 0.05), 0.5 * 60.0 * 0.05 * 0.05, 1e-12);  // end of the jerk phase
  EXPECT_NEAR(s.command_mps(0.1 + 0.075), 0.15, 1e-12);                     // half way, by symmetry
  EXPECT_EQ(s.command_mps(0.25), 0.3);
  EXPECT_EQ(s.command_mps(0.74), 0.3);                    // hold ends at 0.1 + 0.15 + 0.5
  EXPECT_NEAR(s.command_mps(0.75 + 0.075), 0.15, 1e-12);  // fall, half way
  EXPECT_EQ(s.command_mps(0.9), 0.0);
  const Extremes e = extremes(s, 1e-4);
  EXPECT_LE(e.max_accel, 3.0 * (1 + 1e-6));
  EXPECT_GT(e.max_accel, 2.99);
  EXPECT_LE(e.max_jerk, 60.0 * (1 + 1e-3));
  EXPECT_GT(e.max_jerk, 59.0);
}

TEST(ReferenceShapes, ShortSCurveNeverReachesItsAccelerationLimit) {
  // dv = 0.05 < a^2/j = 0.15: a triangular acceleration peaking at sqrt(dv j) = 1.73 m/s^2.
  const VelocityTransition small{-0.05, 3.0, 60.0};
  EXPECT_NEAR(small.duration_s(), 2.0 * std::sqrt(0.05 / 60.0), 1e-12);
  double peak = 0;
  for (double t = 1e-5; t < small.duration_s(); t += 1e-5) {
    peak = std::max(peak, std::abs(small.velocity_mps(t) - small.velocity_mps(t - 1e-5)) / 1e-5);
  }
  EXPECT_NEAR(peak, std::sqrt(0.05 * 60.0), 1e-3);
  EXPECT_EQ(small.velocity_mps(1.0), -0.05);
  EXPECT_LT(small.velocity_mps(0.5 * small.duration_s()), 0.0);  // the sign follows the change
  EXPECT_NEAR(small.velocity_mps(0.5 * small.duration_s()), -0.025, 1e-12);
}

TEST(ReferenceShapes, ChirpSweepsItsFrequencyPhaseContinuously) {
  Scenario s = move(CommandShape::kChirp);
  s.duration_s = 6.0;
  s.amplitude_mps = 0.1;
  s.frequency_hz = 1.0;
  s.end_frequency_hz = 9.0;
  s.sweep_s = 4.0;
  s.validate(kPeriod);
  // Zero crossings per second give twice the frequency: about 2 Hz at 0.5-1.5 s (f(1 s) = 3 Hz
  // ... f(0.5 s) = 2 Hz), 9 Hz after the sweep.
  const auto crossings = [&](double from, double to) {
    int n = 0;
    for (double t = from + 1e-4; t < to; t += 1e-4) {
      if ((s.command_mps(t) > 0) != (s.command_mps(t - 1e-4) > 0)) ++n;
    }
    return n;
  };
  EXPECT_NEAR(crossings(0.0, 1.0), 2 * 2, 1);  // mean frequency over [0, 1] s: 2 Hz
  EXPECT_NEAR(crossings(4.0, 6.0), 2 * 9 * 2, 1);
  // Phase-continuous at the end of the sweep: no jump bigger than one step of the sine.
  EXPECT_NEAR(s.command_mps(4.0 + 1e-9), s.command_mps(4.0 - 1e-9), 1e-6);
  EXPECT_LE(extremes(s, 1e-4).max_accel, 0.1 * 2 * kPi * 9.0 * 1.01);
}

TEST(ReferenceShapes, MultiSineIsTheSumOfItsTerms) {
  Scenario s = move(CommandShape::kMultiSine);
  s.components = {{0.1, 1.0, 0.0}, {0.05, 3.0, 0.5}};
  s.validate(kPeriod);
  for (double t : {0.0, 0.13, 0.77, 1.5}) {
    EXPECT_NEAR(s.command_mps(t), 0.1 * std::sin(2 * kPi * t) + 0.05 * std::sin(2 * kPi * 3 * t + 0.5), 1e-12);
  }
  EXPECT_NEAR(s.command_scale_mps(), 0.15, 1e-15);
  s.components.push_back({0.05, 600.0, 0.0});  // above Nyquist at 1 ms
  EXPECT_THROW(s.validate(kPeriod), std::invalid_argument);
  s.components.clear();
  EXPECT_THROW(s.validate(kPeriod), std::invalid_argument);
}

TEST(ReferenceShapes, InvalidMoveLimitsAreRefusedByName) {
  const auto message = [](Scenario s) {
    try {
      s.validate(kPeriod);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  Scenario s = move(CommandShape::kSCurve);
  s.jerk_mps3 = 0;
  EXPECT_NE(message(s).find("command.jerk_mps3"), std::string::npos) << message(s);
  s = move(CommandShape::kTrapezoid);
  s.accel_mps2 = -1;
  EXPECT_NE(message(s).find("command.accel_mps2"), std::string::npos) << message(s);
  s = move(CommandShape::kTrapezoid);
  s.hold_s = NAN;
  EXPECT_NE(message(s).find("command.hold_s"), std::string::npos) << message(s);
  s = move(CommandShape::kRamp);
  s.start_s = 5.0;  // after the end of the run
  EXPECT_NE(message(s).find("command.start_s"), std::string::npos) << message(s);
}

// ------------------------------------------------------------------ CSV profiles

std::string csv_error(const std::string& text, double max_gap_s = 1.0) {
  try {
    parse_velocity_profile(text, "p.csv", max_gap_s, 10.0);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "accepted";
}

TEST(ReferenceCsv, ReadsAndInterpolates) {
  Scenario s = move(CommandShape::kCsv);
  s.max_gap_s = 1.0;
  s.profile = parse_velocity_profile("time_s,velocity_mps\r\n0.5,0.1\r\n1.0, 0.3\r\n1.5,-0.1\r\n", "p.csv", 1.0, 10.0);
  ASSERT_EQ(s.profile.size(), 3u);
  s.validate(kPeriod);
  EXPECT_EQ(s.command_mps(0.0), 0.1);  // before the first row: its velocity
  EXPECT_NEAR(s.command_mps(0.75), 0.2, 1e-12);
  EXPECT_NEAR(s.command_mps(1.25), 0.1, 1e-12);
  EXPECT_EQ(s.command_mps(1.0), 0.3);
  EXPECT_EQ(s.command_mps(1.9), -0.1);  // after the last: its velocity
  EXPECT_NEAR(s.command_scale_mps(), 0.3, 1e-15);
}

TEST(ReferenceCsv, BadRowsAreRejectedWithFileLineAndValue) {
  struct Case {
    const char* what;
    std::string text;
    std::vector<std::string> expected;
  };
  const std::string header = "time_s,velocity_mps\n";
  const std::vector<Case> cases = {
      {"no header", "0,0\n1,0\n", {"p.csv:1:", "header", "'0,0'"}},
      {"empty file", "", {"p.csv:1:", "empty file"}},
      {"blank line", header + "0,0\n\n1,0\n", {"p.csv:3:", "empty line"}},
      {"empty time cell", header + "0,0\n,0.1\n", {"p.csv:3:", "time_s: empty cell"}},
      {"empty velocity cell", header + "0,0\n0.1,\n", {"p.csv:3:", "velocity_mps: empty cell"}},
      {"NaN velocity", header + "0,0\n0.1,nan\n", {"p.csv:3:", "velocity_mps: must be finite", "'nan'"}},
      {"infinite time", header + "0,0\ninf,0\n", {"p.csv:3:", "time_s: must be finite", "'inf'"}},
      {"text", header + "0,0\n0.1,fast\n", {"p.csv:3:", "velocity_mps: not a number", "'fast'"}},
      {"trailing text", header + "0,0\n0.1,0.2m\n", {"p.csv:3:", "not a number", "'0.2m'"}},
      {"time repeated", header + "0,0\n0.5,0.1\n0.5,0.2\n", {"p.csv:4:", "time_s: must increase", "'0.5'"}},
      {"time going back", header + "0,0\n0.5,0.1\n0.4,0.2\n", {"p.csv:4:", "time_s: must increase", "'0.4'"}},
      {"gap in time", header + "0,0\n0.5,0.1\n2.0,0.2\n", {"p.csv:4:", "gap of 1.5 s", "max_gap_s 1", "'2'"}},
      {"three columns", header + "0,0\n0.1,0.1,7\n", {"p.csv:3:", "expected 2 columns", "'0.1,0.1,7'"}},
      {"one column", header + "0,0\n0.1\n", {"p.csv:3:", "expected 2 columns", "'0.1'"}},
      {"negative time", header + "-0.1,0\n0.1,0\n", {"p.csv:2:", "time_s: must be >= 0", "'-0.1'"}},
      {"too fast", header + "0,0\n0.1,12\n", {"p.csv:3:", "velocity_mps: must be in [-10, 10]", "'12'"}},
      {"one row", header + "0,0\n", {"p.csv:2:", "at least 2 rows"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    const std::string message = csv_error(c.text);
    for (const std::string& part : c.expected) {
      EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' not in: " << message;
    }
  }
}

// ------------------------------------------------------------------ YAML

using test::Edit;
using test::edited;
using test::read_text;
using test::source_path;

std::string scenario_error(const std::string& file, const std::vector<Edit>& edits, const std::string& origin) {
  const std::string text = edited(read_text("configs/scenarios/" + file), edits);
  try {
    parse_scenario(text, origin, kPeriod);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "accepted";
}

void expect_parts(const std::string& message, const std::vector<std::string>& parts) {
  for (const std::string& part : parts) {
    EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' not in: " << message;
  }
}

TEST(ReferenceYaml, ShippedScenariosLoadWithSourcedValues) {
  for (const char* name :
       {"ramp", "trapezoid", "s_curve", "chirp", "multi_sine", "csv_profile", "sine_1hz", "sine_2hz", "sine_5hz"}) {
    SCOPED_TRACE(name);
    const Scenario s = test::shipped_scenario(name);
    EXPECT_EQ(s.name, name);
    for (const SourcedLeaf& leaf :
         list_leaf_sources(read_text(std::string("configs/scenarios/") + name + ".yaml"), name)) {
      if (leaf.key_path == "name") continue;
      EXPECT_TRUE(leaf.source.rfind("paper", 0) == 0 || leaf.source.rfind("chosen:", 0) == 0) << leaf.key_path;
    }
  }
  EXPECT_EQ(test::shipped_scenario("s_curve").shape, CommandShape::kSCurve);
  EXPECT_FALSE(test::shipped_scenario("s_curve").use_reference_model);
  EXPECT_TRUE(test::shipped_scenario("sine_2hz").use_reference_model);
  EXPECT_TRUE(test::shipped_scenario("pulse").use_reference_model);  // absent: the paper's model
  EXPECT_EQ(test::shipped_scenario("multi_sine").components.size(), 3u);
  const Scenario csv = test::shipped_scenario("csv_profile");
  EXPECT_EQ(csv.profile.size(), 10u);
  EXPECT_NEAR(csv.command_mps(0.15), 0.1, 1e-12);
}

TEST(ReferenceYaml, KeysOfEachShapeAreRequiredAndOthersUnknown) {
  const std::string o = "configs/scenarios/t.yaml";
  expect_parts(scenario_error("trapezoid.yaml", {{"command.frequency_hz", "{value: 1, source: 'chosen: x'}"}}, o),
               {o, "command.frequency_hz: unknown key"});
  expect_parts(scenario_error("trapezoid.yaml", {{"command.hold_s", std::nullopt}}, o),
               {o, "command.hold_s: missing key"});
  expect_parts(scenario_error("s_curve.yaml", {{"command.jerk_mps3.value", "-5"}}, o),
               {o, "command.jerk_mps3: must be in", "got -5"});
  expect_parts(scenario_error("chirp.yaml", {{"command.end_frequency_hz.value", "900"}}, o),
               {o, "command.end_frequency_hz: must be in", "got 900"});
  expect_parts(scenario_error("multi_sine.yaml", {{"command.components", "[]"}}, o),
               {o, "command.components: expected a non-empty list"});
  expect_parts(
      scenario_error("multi_sine.yaml", {{"command.components", "[{amplitude_mps: 0.1, frequency_hz: 1}]"}}, o),
      {o, "command.components[0].phase_rad: missing key"});
  expect_parts(scenario_error("sine_2hz.yaml", {{"reference_model.value", "maybe"}}, o),
               {o, "reference_model: expected true or false", "'maybe'"});
  expect_parts(scenario_error("sine_2hz.yaml", {{"command.shape.value", "square"}}, o),
               {o, "command.shape", "'square'", "trapezoid, s_curve, chirp, multi_sine, csv"});
}

TEST(ReferenceYaml, BadProfileFileIsRejectedWithScenarioFileLineAndValue) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "pmlsm_reference_yaml_test";
  std::filesystem::create_directories(dir / "profiles");
  {
    std::ofstream out(dir / "profiles" / "bad.csv");
    out << "time_s,velocity_mps\n0.0,0.0\n0.1,0.1\n0.1,0.2\n";
  }
  const std::string origin = (dir / "s.yaml").string();
  const std::string message = scenario_error("csv_profile.yaml", {{"command.file.value", "profiles/bad.csv"}}, origin);
  expect_parts(message, {origin, "command.file",
                         (dir / "profiles" / "bad.csv").string() + ":4:", "time_s: must increase", "'0.1'"});
  expect_parts(scenario_error("csv_profile.yaml", {{"command.file.value", "profiles/none.csv"}}, origin),
               {origin, "command.file", "none.csv: cannot open file"});
  expect_parts(scenario_error("csv_profile.yaml", {{"command.max_gap_s.value", "0"}}, origin),
               {origin, "command.max_gap_s: must be in", "got 0"});
  std::filesystem::remove_all(dir);
}

// ------------------------------------------------------------------ in the loop

TEST(ReferenceLoop, WithoutTheReferenceModelVrefIsTheCommand) {
  const SystemParams& params = test::shipped_params();
  Scenario s = test::shipped_scenario("trapezoid");
  ASSERT_FALSE(s.use_reference_model);
  VelocityController bypass(params, s);
  s.use_reference_model = true;
  VelocityController shaped(params, s);
  double max_gap_shaped = 0;
  for (std::uint64_t k = 0; k < 400; ++k) {
    const VelocityControllerOutput a = bypass.step(k, 0.0, {});
    const VelocityControllerOutput b = shaped.step(k, 0.0, {});
    EXPECT_EQ(a.v_ref_mps, a.command_mps);
    EXPECT_LE(std::abs(a.a_ref_mps2), 3.0 + 1e-9);
    max_gap_shaped = std::max(max_gap_shaped, std::abs(b.v_ref_mps - b.command_mps));
  }
  EXPECT_GT(max_gap_shaped, 0.01);  // the model (25) lags the ramp: the bypass is not a no-op
}

TEST(ReferenceLoop, ThePositionReferenceIsTheSumOfTheVelocityReferenceBeforeTheTick) {
  const SystemParams& params = test::shipped_params();
  VelocityController controller(params, test::shipped_scenario("trapezoid"));
  const double period_s = params.timing.control_period_s;
  double sum_m = 0.0;
  for (std::uint64_t k = 0; k < 1500; ++k) {
    const VelocityControllerOutput out = controller.step(k, 0.0, {});
    ASSERT_NEAR(out.x_ref_m, sum_m, 1e-12) << "tick " << k;
    sum_m += out.v_ref_mps * period_s;
  }
  EXPECT_GT(sum_m, 0.01) << "the trapezoid moved the reference";
}

TEST(ReferenceLoop, SettlingIsMeasuredOverConstantSegmentsOnly) {
  const Scenario s = move(CommandShape::kTrapezoid);
  std::vector<TickRecord> trace(2000);
  for (std::size_t k = 0; k < trace.size(); ++k) {
    const double t = static_cast<double>(k) * kPeriod;
    trace[k].time_s = t;  // the segments are the scenario's raw command at each tick's time
    trace[k].command_mps = s.command_mps(t);
    trace[k].v_ref_mps = trace[k].command_mps;
    // Lags the rise and fall by far (never within the band there), settles 30 ms into the hold
    // and 50 ms into the rest.
    trace[k].load_velocity_mps = trace[k].command_mps;
    if ((t > 0.1005 && t < 0.23) || (t > 0.7005 && t < 0.85)) trace[k].load_velocity_mps += 0.05;
  }
  const ScenarioMetrics m = compute_metrics(trace, s, kPeriod);
  EXPECT_NEAR(m.load_settling_time_s, 0.05, 1.5e-3);
  trace.back().load_velocity_mps = 0.1;  // out of the band at the end: never settled
  EXPECT_TRUE(std::isinf(compute_metrics(trace, s, kPeriod).load_settling_time_s));
}

TEST(ReferenceLoop, JerkLimitExcitesTheLoadLessThanTheTrapezoid) {
  // PI alone: the S-curve's gradual acceleration leaves the 10.2 Hz load mode less to ring.
  const SystemParams& params = test::shipped_params();
  const auto run = [&](const char* name) {
    const Scenario s = test::shipped_scenario(name);
    return compute_metrics(run_scenario(params, s), s, params.timing.control_period_s);
  };
  const ScenarioMetrics trapezoid = run("trapezoid");
  const ScenarioMetrics s_curve = run("s_curve");
  std::printf("[ references ] vibration RMS: trapezoid %.1f mm/s, s_curve %.1f mm/s\n",
              1e3 * trapezoid.load_vibration_rms_mps, 1e3 * s_curve.load_vibration_rms_mps);
  EXPECT_LT(s_curve.load_vibration_rms_mps, 0.7 * trapezoid.load_vibration_rms_mps);
  EXPECT_LT(s_curve.peak_force_command_n, params.velocity_loop.force_limit_n);
  EXPECT_EQ(s_curve.force_off_ticks, 0u);
}

// ------------------------------------------------------------------ external setpoints

ExternalReferenceParams external_params() {
  ExternalReferenceParams p;
  p.timeout_s = 0.2;
  p.max_speed_mps = 0.5;
  p.max_accel_mps2 = 2.0;
  p.period_s = kPeriod;
  return p;
}

/// Steps the policy from tick `from` to `to` (exclusive) at 1 ms; the largest |change| a tick.
double run_ticks(ExternalReference& ref, int from, int to, ExternalReferenceOutput& last) {
  double max_step = 0;
  double previous = last.command_mps;
  for (int k = from; k < to; ++k) {
    last = ref.step(k * kPeriod);
    max_step = std::max(max_step, std::abs(last.command_mps - previous));
    previous = last.command_mps;
  }
  return max_step;
}

TEST(ExternalReference, FollowsAFreshSetpointAtTheRateLimit) {
  ExternalReference ref(external_params());
  ExternalReferenceOutput out;
  run_ticks(ref, 0, 10, out);
  EXPECT_TRUE(out.stale);  // nothing yet: zero
  EXPECT_EQ(out.command_mps, 0.0);
  EXPECT_EQ(ref.counters().stale_episodes, 0u);  // never fresh: not an episode
  ASSERT_EQ(ref.offer({0.3, 0.0, 7, 1}, 0.010), SetpointVerdict::kAccepted);
  const double max_step = run_ticks(ref, 10, 100, out);
  EXPECT_FALSE(out.stale);
  EXPECT_LE(max_step, 2.0 * kPeriod + 1e-15);               // never a jump
  EXPECT_NEAR(out.command_mps, 2.0 * 90 * kPeriod, 1e-12);  // 90 ticks at 2 m/s^2
  run_ticks(ref, 100, 200, out);
  EXPECT_DOUBLE_EQ(out.command_mps, 0.3);
  EXPECT_EQ(out.accel_mps2, 0.0);
  // A gentler rate asked by the source applies; a steeper one does not.
  ASSERT_EQ(ref.offer({0.0, 0.5, 7, 2}, 0.200), SetpointVerdict::kAccepted);
  run_ticks(ref, 200, 210, out);
  EXPECT_NEAR(out.command_mps, 0.3 - 0.5 * 10 * kPeriod, 1e-12);
  ASSERT_EQ(ref.offer({0.3, 50.0, 7, 3}, 0.210), SetpointVerdict::kAccepted);
  EXPECT_LE(run_ticks(ref, 210, 220, out), 2.0 * kPeriod + 1e-15);
}

TEST(ExternalReference, StaleSetpointRampsToZeroAndCountsALostMove) {
  ExternalReference ref(external_params());
  ExternalReferenceOutput out;
  ref.offer({0.2, 0.0, 1, 1}, 0.0);
  run_ticks(ref, 0, 200, out);  // fresh until 0.2 s
  EXPECT_FALSE(out.stale);
  EXPECT_DOUBLE_EQ(out.command_mps, 0.2);
  out = ref.step(0.201);
  EXPECT_TRUE(out.stale);
  EXPECT_EQ(out.target_mps, 0.0);
  EXPECT_NEAR(out.command_mps, 0.2 - 2.0 * kPeriod, 1e-12);  // ramps, does not drop
  const double max_step = run_ticks(ref, 202, 400, out);
  EXPECT_LE(max_step, 2.0 * kPeriod + 1e-15);
  EXPECT_EQ(out.command_mps, 0.0);
  EXPECT_EQ(ref.counters().stale_episodes, 1u);
  EXPECT_EQ(ref.counters().lost_while_moving, 1u);
  // A source that said 0 and then went quiet stopped on purpose: stale, but not lost.
  ref.offer({0.0, 0.0, 1, 2}, 0.400);
  run_ticks(ref, 400, 700, out);
  EXPECT_EQ(ref.counters().stale_episodes, 2u);
  EXPECT_EQ(ref.counters().lost_while_moving, 1u);
}

TEST(ExternalReference, RejectsInvalidOutOfOrderAndForeignSetpoints) {
  ExternalReference ref(external_params());
  EXPECT_EQ(ref.offer({NAN, 0.0, 1, 1}, 0.0), SetpointVerdict::kNonFinite);
  EXPECT_EQ(ref.offer({INFINITY, 0.0, 1, 1}, 0.0), SetpointVerdict::kNonFinite);
  EXPECT_EQ(ref.offer({0.51, 0.0, 1, 1}, 0.0), SetpointVerdict::kBeyondLimit);
  EXPECT_EQ(ref.offer({-0.51, 0.0, 1, 1}, 0.0), SetpointVerdict::kBeyondLimit);
  EXPECT_EQ(ref.offer({0.1, -1.0, 1, 1}, 0.0), SetpointVerdict::kBadAccelLimit);
  EXPECT_EQ(ref.offer({0.1, NAN, 1, 1}, 0.0), SetpointVerdict::kBadAccelLimit);
  EXPECT_EQ(ref.counters().rejected_invalid, 6u);
  ExternalReferenceOutput out = ref.step(0.0);
  EXPECT_EQ(out.command_mps, 0.0);  // none of them moved anything
  EXPECT_TRUE(out.stale);
  EXPECT_EQ(ref.offer({0.1, 0.0, 1, 5}, 0.001), SetpointVerdict::kAccepted);
  EXPECT_EQ(ref.offer({0.4, 0.0, 1, 5}, 0.002), SetpointVerdict::kOutOfOrder);    // repeated
  EXPECT_EQ(ref.offer({0.4, 0.0, 1, 4}, 0.002), SetpointVerdict::kOutOfOrder);    // older
  EXPECT_EQ(ref.offer({-0.4, 0.0, 2, 1}, 0.003), SetpointVerdict::kOtherSource);  // while 1 is fresh
  EXPECT_EQ(ref.counters().rejected, 9u);
  EXPECT_EQ(ref.counters().rejected_invalid, 6u);
  out = ref.step(0.003);
  EXPECT_EQ(out.target_mps, 0.1);
  // Once session 1 is quiet, another source may take over (from a fresh start of its own).
  EXPECT_EQ(ref.offer({-0.2, 0.0, 2, 1}, 0.3), SetpointVerdict::kAccepted);
  EXPECT_EQ(ref.step(0.3).target_mps, -0.2);
  EXPECT_STREQ(to_string(SetpointVerdict::kOtherSource), "another source holds the reference");
}

TEST(ExternalReference, ParametersAreValidatedByName) {
  ExternalReferenceParams p = external_params();
  p.timeout_s = 0;
  EXPECT_THROW({ ExternalReference r(p); }, std::invalid_argument);
  p = external_params();
  p.max_accel_mps2 = NAN;
  try {
    ExternalReference r(p);
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_accel_mps2"), std::string::npos) << e.what();
  }
}

TEST(ExternalReference, ExternalScenarioLoadsAndIsRefusedInProcess) {
  const Scenario s = test::shipped_scenario("external");
  EXPECT_EQ(s.shape, CommandShape::kExternal);
  const ExternalReferenceParams p = external_reference_params(s, kPeriod);
  EXPECT_NO_THROW(p.validate());
  EXPECT_EQ(s.command_mps(1.0), 0.0);
  try {
    ClosedLoop loop(test::shipped_params(), s);
    ADD_FAILURE() << "an external scenario ran in process";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("external"), std::string::npos) << e.what();
  }
  expect_parts(scenario_error("external.yaml", {{"command.timeout_s.value", "0"}}, "e.yaml"),
               {"e.yaml", "command.timeout_s: must be in", "got 0"});
  expect_parts(scenario_error("external.yaml", {{"command.duty_cycle", "{value: 0.5, source: 'chosen: x'}"}}, "e.yaml"),
               {"e.yaml", "command.duty_cycle: unknown key"});
}

}  // namespace
}  // namespace pmlsm

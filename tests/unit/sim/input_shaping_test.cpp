// Input shaping in the loop (SystemParams::loop_vibration_mode, a scenario's input_shaper): the
// mode the shaper is timed to is the one the loop rings at, and a shaped pulse leaves the load
// quieter than the paper's reference on the nominal plant and off it.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "config_edit.hpp"
#include "pmlsm/analysis/compensated_run.hpp"
#include "pmlsm/sim/metrics.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

using test::shipped_params;
using test::shipped_scenario;

/// The frequency the spring stretch x_L - x_M rings at in a free vibration under PI alone, from
/// its zero crossings about the final stretch over the first `window_s`.
double ringing_frequency_hz(const std::vector<TickRecord>& trace, double window_s) {
  const double rest = trace.back().load_position_m - trace.back().motor_position_m;
  double first = -1, last = -1;
  int crossings = 0;
  for (std::size_t k = 1; k < trace.size() && trace[k].time_s <= window_s; ++k) {
    const double a = trace[k - 1].load_position_m - trace[k - 1].motor_position_m - rest;
    const double b = trace[k].load_position_m - trace[k].motor_position_m - rest;
    if ((a < 0) != (b < 0)) {
      const double t = trace[k - 1].time_s + (trace[k].time_s - trace[k - 1].time_s) * a / (a - b);
      if (first < 0) first = t;
      last = t;
      ++crossings;
    }
  }
  return crossings < 3 ? 0.0 : 0.5 * (crossings - 1) / (last - first);
}

TEST(LoopVibrationMode, LiesBetweenTheHeldAndTheFreeResonanceAndIsWhereTheLoadRings) {
  const SystemParams& p = shipped_params();
  const VibrationMode mode = p.loop_vibration_mode();
  const double held_hz = std::sqrt(p.kalman.model.spring_n_per_m / p.kalman.model.load_mass_kg) / (2 * M_PI);
  const double free_hz =
      std::sqrt(p.kalman.model.spring_n_per_m * (1 / p.kalman.model.load_mass_kg + 1 / p.kalman.model.motor_mass_kg)) /
      (2 * M_PI);
  EXPECT_GT(mode.frequency_hz, held_hz);
  EXPECT_LT(mode.frequency_hz, free_hz);
  EXPECT_GT(mode.damping_ratio, 0.0);
  EXPECT_LT(mode.damping_ratio, 0.5);
  // The nonlinear plant (friction, ripple, the current loop) rings within 3 % of it.
  const auto trace = run_with_compensator(p, shipped_scenario("free_vibration"), CompensatorSetup{});
  const double ringing_hz = ringing_frequency_hz(trace, 1.0);
  EXPECT_NEAR(ringing_hz, mode.frequency_hz, 0.03 * mode.frequency_hz) << "mode " << mode.frequency_hz;
  // The identified model moves the mode: a heavier load rings lower.
  SystemParams heavy = p;
  heavy.kalman.model.load_mass_kg = 8.0;
  EXPECT_LT(heavy.loop_vibration_mode().frequency_hz, 0.8 * mode.frequency_hz);
}

ScenarioMetrics shaped_metrics(const SystemParams& params, const std::string& scenario_name, ShaperKind kind) {
  Scenario scenario = shipped_scenario(scenario_name);
  scenario.input_shaper = kind;
  const auto trace = run_with_compensator(params, scenario, CompensatorSetup{});
  return compute_metrics(trace, scenario, params.timing.control_period_s);
}

// PI alone. The shapers are timed to the model's mode, so the light, stiff plant (3 kg,
// 16,000 N/m against the model's 4 kg, 13,700 N/m: its mode 14 % higher) tests their robustness.
TEST(InputShapingInTheLoop, ShapedMovesLeaveTheLoadQuieterAndZvdAndEiStayQuietOffTheModel) {
  SystemParams light_stiff = shipped_params();
  light_stiff.plant.mechanics.load_mass_kg = 3.0;
  light_stiff.plant.mechanics.spring_n_per_m = 16000.0;
  const SystemParams* const nominal = &shipped_params();
  for (const SystemParams* params : {nominal, static_cast<const SystemParams*>(&light_stiff)}) {
    const std::string plant = params == nominal ? " nominal" : " off the model";
    const ScenarioMetrics paper = shaped_metrics(*params, "pulse", ShaperKind::kNone);
    const ScenarioMetrics zv = shaped_metrics(*params, "pulse", ShaperKind::kZv);
    for (const ShaperKind kind : {ShaperKind::kZv, ShaperKind::kZvd, ShaperKind::kEi}) {
      SCOPED_TRACE(std::string(to_string(kind)) + plant);
      const ScenarioMetrics pulse = shaped_metrics(*params, "pulse", kind);
      EXPECT_LT(pulse.load_vibration_rms_mps, 0.5 * paper.load_vibration_rms_mps)
          << pulse.load_vibration_rms_mps << " vs " << paper.load_vibration_rms_mps;
      EXPECT_LT(pulse.cost_true, 0.5 * paper.cost_true) << pulse.cost_true << " vs " << paper.cost_true;
      if (kind != ShaperKind::kZv && params != nominal) {
        EXPECT_LT(pulse.load_vibration_rms_mps, 0.8 * zv.load_vibration_rms_mps) << "ZV " << zv.load_vibration_rms_mps;
      }
      // The move settles in its 2 % band once shaped by ZVD or EI; unshaped it never does.
      if (kind != ShaperKind::kZv) {
        EXPECT_LT(shaped_metrics(*params, "trapezoid", kind).load_settling_time_s, 0.6);
      }
    }
    EXPECT_FALSE(std::isfinite(shaped_metrics(*params, "trapezoid", ShaperKind::kNone).load_settling_time_s)) << plant;
  }
}

TEST(InputShapingInTheLoop, AScenarioNamesItsShaperAndABadOneIsRefusedByKey) {
  const std::string origin = "pulse_shaped.yaml";
  std::string text = test::read_text("configs/scenarios/pulse.yaml");
  text += "input_shaper: {value: zvd, source: \"chosen: test\"}\n";
  EXPECT_EQ(parse_scenario(text, origin, 1e-3).input_shaper, ShaperKind::kZvd);
  const std::string bad =
      test::read_text("configs/scenarios/pulse.yaml") + "input_shaper: {value: zvdd, source: \"chosen: test\"}\n";
  const std::string error = test::error_of([&] { parse_scenario(bad, origin, 1e-3); });
  EXPECT_NE(error.find("input_shaper: expected none, zv, zvd or ei, got 'zvdd'"), std::string::npos) << error;
}

}  // namespace
}  // namespace pmlsm

// The commissioning's decisions (pmlsm/commissioning/commissioning.hpp) on the shipped plant's
// measured response, without the command: what it writes, how it judges and tunes the loop, when
// it refuses.
#include "pmlsm/commissioning/commissioning.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <sstream>
#include <string>

#include "pmlsm/analysis/analysis_params.hpp"
#include "pmlsm/sim/live_parameters.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

/// The shipped plant's response, measured and evaluated by the commissioning (once per binary).
const FrequencyResponseResult& measured_nominal() {
  static const FrequencyResponseResult kResult = [] {
    std::string why;
    const std::optional<FrequencyResponseResult> r = measured_response(test::shipped_params(), why);
    if (!r) throw std::runtime_error("the shipped plant's measurement: " + why);
    return *r;
  }();
  return kResult;
}

std::map<std::string, double> as_map(const std::vector<std::pair<std::string, double>>& values) {
  return {values.begin(), values.end()};
}

TEST(Commissioning, WritesTheFittedTwoMassModelIntoBothModelsAndTheFrictionOnlyFromATimeDomainFit) {
  TwoMassFit fit;
  fit.motor_mass_kg = 21.0;
  fit.load_mass_kg = 4.5;
  fit.spring_n_per_m = 14000.0;
  const auto from_frequency = as_map(commissioned_parameters(fit, std::nullopt));
  EXPECT_EQ(from_frequency.size(), 6u);
  for (const std::string model : {"kalman.model.", "compensator.state_feedback.model."}) {
    EXPECT_EQ(from_frequency.at(model + "motor_mass_kg"), 21.0) << model;
    EXPECT_EQ(from_frequency.at(model + "load_mass_kg"), 4.5) << model;
    EXPECT_EQ(from_frequency.at(model + "spring_n_per_m"), 14000.0) << model;
  }
  // A time-domain fit adds its friction; its mass and spring give way to the frequency response's.
  IdentifiedLoad time_domain;
  time_domain.load_mass_kg = 9.0;
  time_domain.spring_n_per_m = 1.0;
  time_domain.coulomb_n = 17.0;
  time_domain.viscous_n_s_per_m = 3.0;
  const auto with_time_domain = as_map(commissioned_parameters(fit, time_domain));
  EXPECT_GT(with_time_domain.size(), from_frequency.size());
  for (const auto& [key, value] : with_time_domain) {
    if (key.find("load_mass_kg") != std::string::npos) {
      EXPECT_EQ(value, 4.5) << key;
    }
    if (key.find("spring_n_per_m") != std::string::npos) {
      EXPECT_EQ(value, 14000.0) << key;
    }
  }
  const bool friction_written = std::any_of(with_time_domain.begin(), with_time_domain.end(), [](const auto& entry) {
    return entry.first.find("coulomb") != std::string::npos && entry.second == 17.0;
  });
  EXPECT_TRUE(friction_written);
}

TEST(Commissioning, TunesTheShippedLoopToItsTargetsAndWritesTheGainsAndTheModel) {
  const SystemParams& shipped = test::shipped_params();
  const FrequencyResponseResult& r = measured_nominal();
  CommissioningChoices choices;
  choices.simulate = true;
  choices.tune = true;
  std::ostringstream csv;
  Transcript transcript{{}, false};
  const CommissionDecision d = decide(choices, shipped, r, std::nullopt, csv, "", transcript);
  ASSERT_EQ(d.exit_code, kExitOk) << transcript.text;
  ASSERT_TRUE(d.loop.tuned);
  const TuningTargets targets = tuning_targets(shipped);
  EXPECT_GE(d.loop.tuned->after.phase_margin_deg, targets.min_phase_margin_deg);
  EXPECT_GE(d.loop.tuned->after.gain_margin_db, targets.min_gain_margin_db);
  const auto values = as_map(d.values);
  EXPECT_EQ(values.at("velocity_loop.kp_n_s_per_m"), d.loop.tuned->kp_n_s_per_m);
  EXPECT_EQ(values.at("velocity_loop.ki_n_per_m"), d.loop.tuned->ki_n_per_m);
  ASSERT_TRUE(d.commissioned);
  EXPECT_EQ(d.commissioned->kalman.model.load_mass_kg, r.fit.load_mass_kg);
  EXPECT_EQ(d.commissioned->velocity_loop.kp_n_s_per_m, d.loop.tuned->kp_n_s_per_m);
  // Simulated: the plant is the one measured, not the fit.
  EXPECT_EQ(d.commissioned->plant.mechanics.load_mass_kg, shipped.plant.mechanics.load_mass_kg);
  EXPECT_FALSE(d.verification);
  EXPECT_NE(transcript.text.find("velocity loop tuned to 45 deg and 8 dB"), std::string::npos) << transcript.text;
  // The fit finds the shipped plant (the nominal 4 kg, 13,700 N/m of Table 2) within 1 %.
  EXPECT_NEAR(r.fit.load_mass_kg / shipped.plant.mechanics.load_mass_kg, 1.0, 0.01);
  EXPECT_NEAR(r.fit.spring_n_per_m / shipped.plant.mechanics.spring_n_per_m, 1.0, 0.01);
}

// The position loop on the load's encoder judged from the same measurement (with a load encoder):
// a K_x beyond its margins refused with nothing written, --tune writing the K_x they allow.
TEST(Commissioning, JudgesTheDualLoopFromTheLoadSideAndWritesTheGainItsMarginsAllow) {
  SystemParams p = test::shipped_params();
  p.load_sensor.kind = LoadSensorKind::kEncoder;
  p.position_loop.closes_on = PositionFeedback::kLoad;
  p.position_loop.gain_per_s = 5.0;
  p.validate();
  std::string why;
  const std::optional<FrequencyResponseResult> r = measured_response(p, why);
  ASSERT_TRUE(r) << why;
  CommissioningChoices choices;
  choices.simulate = true;
  std::ostringstream csv;
  Transcript refused{{}, false};
  const CommissionDecision too_fast = decide(choices, p, *r, std::nullopt, csv, "", refused);
  EXPECT_EQ(too_fast.exit_code, kExitVerdictFailed) << refused.text;
  EXPECT_FALSE(too_fast.commissioned);
  EXPECT_NE(refused.text.find("position loop on the load's encoder at K_x 5 1/s"), std::string::npos) << refused.text;
  EXPECT_NE(refused.text.find("the position loop's gain leaves it short of its margins; nothing written"),
            std::string::npos)
      << refused.text;

  choices.tune = true;
  Transcript tuned{{}, false};
  const CommissionDecision d = decide(choices, p, *r, std::nullopt, csv, "", tuned);
  ASSERT_EQ(d.exit_code, kExitOk) << tuned.text;
  const double gain_per_s = as_map(d.values).at("position_loop.gain_per_s");
  // Bounded by the load's mode on the velocity loop: well under one per second on the paper's plant.
  EXPECT_GT(gain_per_s, 0.2);
  EXPECT_LT(gain_per_s, 2.0);
  ASSERT_TRUE(d.commissioned);
  EXPECT_EQ(d.commissioned->position_loop.gain_per_s, gain_per_s);
  EXPECT_NE(tuned.text.find("position loop: the margins allow K_x up to"), std::string::npos) << tuned.text;
}

TEST(Commissioning, RefusesTargetsNoGainMeetsAndWritesNothing) {
  SystemParams strict = test::shipped_params();
  set_parameter(strict, "commissioning.tuning.min_phase_margin_deg", "89");
  set_parameter(strict, "commissioning.tuning.min_gain_margin_db", "40");
  strict.validate();
  CommissioningChoices choices;
  choices.simulate = true;
  choices.tune = true;
  std::ostringstream csv;
  Transcript transcript{{}, false};
  const CommissionDecision d = decide(choices, strict, measured_nominal(), std::nullopt, csv, "", transcript);
  EXPECT_EQ(d.exit_code, kExitVerdictFailed);
  EXPECT_FALSE(d.loop.tuned);
  EXPECT_TRUE(d.values.empty());
  EXPECT_FALSE(d.commissioned);
  EXPECT_NE(transcript.text.find("--tune: no gains meet the margins; nothing written"), std::string::npos)
      << transcript.text;
}

TEST(Commissioning, RefusesForceCommandFiltersThatLeaveTheLoopShortOfItsMargins) {
  SystemParams filtered = test::shipped_params();
  // A 30 Hz low-pass well inside the loop's bandwidth: it costs the phase margin.
  set_parameter(filtered, "filters.force_command.slot_1.kind", "low_pass");
  set_parameter(filtered, "filters.force_command.slot_1.frequency_hz", "30");
  set_parameter(filtered, "filters.force_command.slot_1.damping", "0.7");
  filtered.validate();
  Transcript transcript{{}, false};
  const LoopVerdict verdict =
      judge_loop(filtered, measured_nominal(), FilterChain(filtered.force_command_filter_params()), false, transcript);
  EXPECT_TRUE(verdict.filters_refused) << transcript.text;
  EXPECT_NE(transcript.text.find("the force command's filters are refused"), std::string::npos) << transcript.text;
  // Without them the same response passes.
  Transcript plain{{}, false};
  const SystemParams& shipped = test::shipped_params();
  EXPECT_FALSE(judge_loop(shipped, measured_nominal(), FilterChain(shipped.force_command_filter_params()), false, plain)
                   .filters_refused);
}

TEST(Commissioning, MarginsAreMetOnlyWithBothCrossoversAtOrAboveTheTargets) {
  TuningTargets targets;
  LoopMargins m{true, 50.0, 40.0, true, 9.0, 170.0};
  EXPECT_TRUE(margins_met(m, targets));
  m.phase_margin_deg = targets.min_phase_margin_deg - 0.1;
  EXPECT_FALSE(margins_met(m, targets));
  m.phase_margin_deg = 50.0;
  m.phase_crossover_found = false;
  EXPECT_FALSE(margins_met(m, targets));
}

TEST(Commissioning, ATranscriptKeepsWhatIsSaidAndEchoesOnlyWhenAsked) {
  Transcript quiet{{}, false};
  testing::internal::CaptureStdout();
  say(quiet, "Kp %.1f N s/m\n", 2100.0);
  EXPECT_EQ(testing::internal::GetCapturedStdout(), "");
  EXPECT_EQ(quiet.text, "Kp 2100.0 N s/m\n");
  Transcript loud;
  testing::internal::CaptureStdout();
  say(loud, "x%d", 2);
  EXPECT_EQ(testing::internal::GetCapturedStdout(), "x2");
  EXPECT_EQ(loud.text, "x2");
}

}  // namespace
}  // namespace pmlsm

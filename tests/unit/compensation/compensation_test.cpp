// The compensators in the in-process loop: the acceleration-feedback baseline,
// the training cost (23) of the weight search, and the paper's claim with the
// shipped weights (configs/rnn_weights.yaml).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "pmlsm/compensation/accel_feedback.hpp"
#include "pmlsm/compensation/jordan_rnn.hpp"
#include "pmlsm/analysis/identification.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/analysis/compensated_run.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/sim/metrics.hpp"
#include "pmlsm/analysis/rnn_training.hpp"
#include "pmlsm/config/sweep_file.hpp"
#include "pmlsm/config/weights_file.hpp"
#include "config_edit.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

using test::shipped_params;
using test::shipped_scenario;

std::string source(const std::string& rel) { return std::string(PMLSM_SOURCE_DIR) + "/" + rel; }

TEST(AccelFeedback, ValidatesItsParameters) {
  EXPECT_THROW(AccelFeedback({-1.0, 675.0, true}), std::invalid_argument);
  EXPECT_THROW(AccelFeedback({100.0, 0.0, true}), std::invalid_argument);
  try {
    AccelFeedback({std::nan(""), 675.0, true});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("gain_kg"), std::string::npos) << e.what();
  }
}

TEST(AccelFeedback, OpposesTheLoadAccelerationWithinTheLimit) {
  AccelFeedback f({160.0, 675.0, false});
  // The paper's form ignores the reference's acceleration.
  EXPECT_DOUBLE_EQ(f.step({2.0, 5.0}), -320.0);
  EXPECT_DOUBLE_EQ(f.step({-1.0, 0.0}), 160.0);
  EXPECT_DOUBLE_EQ(f.step({10.0, 0.0}), -675.0);
  EXPECT_EQ(f.counters().saturated, 1u);
  EXPECT_DOUBLE_EQ(f.step({std::numeric_limits<double>::quiet_NaN(), 0.0}), 0.0);
  EXPECT_EQ(f.counters().rejected_inputs, 1u);
  EXPECT_EQ(f.counters().steps, 4u);
}

TEST(AccelFeedback, OnTheReferenceErrorOpposesOnlyTheUncommandedAcceleration) {
  AccelFeedback f({160.0, 675.0, true});
  EXPECT_DOUBLE_EQ(f.step({2.0, 2.0}), 0.0);     // the load accelerates as commanded
  EXPECT_DOUBLE_EQ(f.step({2.0, 0.5}), -240.0);  // 1.5 m/s^2 more than commanded
  EXPECT_DOUBLE_EQ(f.step({0.0, 1.0}), 160.0);   // lagging: pushed along
  EXPECT_DOUBLE_EQ(f.step({0.0, -10.0}), -675.0);
  EXPECT_EQ(f.counters().saturated, 1u);
  EXPECT_DOUBLE_EQ(f.step({0.0, std::numeric_limits<double>::infinity()}), 0.0);
  EXPECT_EQ(f.counters().rejected_inputs, 1u);
}

// Why the shipped acceleration feedback works on the error to the reference: on a smooth
// reference the paper's form resists the commanded acceleration (K_a of extra inertia) and
// tracks worse than PI alone; on the error it tracks better, and the pulse gets cheaper too.
TEST(AccelFeedback, OnTheReferenceErrorTracksASineBetterThanPiAlone) {
  const SystemParams& shipped = shipped_params();
  ASSERT_TRUE(shipped.compensator.acceleration_feedback.on_reference_error);
  const auto cost = [&](const char* scenario_name, bool on_error, bool compensated) {
    SystemParams p = shipped;
    p.compensator.acceleration_feedback.on_reference_error = on_error;
    const Scenario s = shipped_scenario(scenario_name);
    AccelFeedback feedback(p.accel_feedback_params());
    const auto trace = run_compensated(p, s, [&](const CompensatorView& v) {
      return compensated ? clamped_compensation(feedback.step(accel_feedback_input(v)), feedback.params().force_limit_n)
                         : Compensation{};
    });
    return compute_metrics(trace, s, p.timing.control_period_s).cost_true;
  };
  const double pi_sine = cost("sine_2hz", true, false);
  const double paper_sine = cost("sine_2hz", false, true), error_sine = cost("sine_2hz", true, true);
  const double paper_pulse = cost("pulse", false, true), error_pulse = cost("pulse", true, true);
  std::printf("[ accel fb   ] 2 Hz sine: PI %.2f, a_L %.2f, a_L - a_ref %.2f; pulse: a_L %.2f, a_L - a_ref %.2f\n",
              pi_sine, paper_sine, error_sine, paper_pulse, error_pulse);
  EXPECT_GT(paper_sine, pi_sine);       // measured 38.10 against 19.21
  EXPECT_LT(error_sine, pi_sine);       // measured 8.13
  EXPECT_LT(error_pulse, paper_pulse);  // measured 5.82 against 8.56
}

TEST(AccelFeedback, DampsThePulseTestInTheLoop) {
  const SystemParams& p = shipped_params();
  const Scenario pulse = shipped_scenario("pulse");
  const double pi_cost = compute_metrics(run_scenario(p, pulse), pulse, p.timing.control_period_s).cost_true;
  const auto trace = run_with_compensator(p, pulse, {CompensatorKind::kAccel, {}, false});
  const ScenarioMetrics m = compute_metrics(trace, pulse, p.timing.control_period_s);
  EXPECT_LT(m.cost_true, pi_cost / 3) << "PI only " << pi_cost;
  // The force of tick k's estimate is applied at tick k+1.
  ASSERT_GT(trace.size(), 100u);
  EXPECT_EQ(trace[0].compensation_force_n, 0.0);
  AccelFeedback replay(p.accel_feedback_params());
  EXPECT_DOUBLE_EQ(trace[50].compensation_force_n, replay.step({trace[49].est_load_accel_mps2, trace[49].a_ref_mps2}));
}

// The free-vibration target (Fig. 10): the load within 2 % of the 0.02 m start in
// under 0.5 s. Acceleration feedback reaches it only with the shipped filter (the
// modelled friction and ripple in its input, Q trusting v_M's model); with the
// paper's filter the estimate never finds the unknown start and nothing settles.
TEST(AccelFeedback, SettlesTheFreeVibrationOnlyWithTheShippedFilter) {
  const Scenario free = shipped_scenario("free_vibration");
  const auto settling_s = [&](const SystemParams& p) {
    const auto trace = run_with_compensator(p, free, {CompensatorKind::kAccel, {}, false});
    return compute_metrics(trace, free, p.timing.control_period_s).load_settling_time_s;
  };
  SystemParams paper = shipped_params();
  paper.kalman.friction_input.enabled = false;
  paper.kalman.ripple_input.enabled = false;
  paper.kalman.process_noise_diag = Eigen::Vector3d(100.0, 10.0, 1.0);  // (35)
  const double shipped_s = settling_s(shipped_params()), paper_s = settling_s(paper);
  std::printf("[ accel fb   ] free vibration settles in %.3f s (paper's filter: %.3f s)\n", shipped_s, paper_s);
  EXPECT_LT(shipped_s, 0.5);  // measured 0.426 s
  EXPECT_GT(paper_s, 2.0);    // measured: never (inf)
}

TEST(TrainingConfig, ShippedFileLoadsWithTable1Values) {
  const TrainingParams t = load_training_params(source("configs/training.yaml"), 1e-3);
  EXPECT_EQ(t.optimiser, "de");
  EXPECT_EQ(t.search.population_size, 120u);
  EXPECT_DOUBLE_EQ(t.search.mutation_factor, 0.8);
  EXPECT_DOUBLE_EQ(t.search.crossover_rate, 0.7);
  EXPECT_DOUBLE_EQ(t.search.init_lower, -1.0);
  EXPECT_DOUBLE_EQ(t.search.init_upper, 1.0);
  ASSERT_FALSE(t.scenarios.empty());
  EXPECT_EQ(t.scenarios[0].scenario.name, "pulse");
}

// The search over commissioned plants (configs/training_commissioned.yaml): from the law, every
// plant fitted first, judged by the identified sweep's own verdict, the worst plant counting.
TEST(TrainingConfig, TheCommissionedSearchFitsEveryPlantAndJudgesByTheIdentifiedSweep) {
  const TrainingParams t = load_training_params(source("configs/training_commissioned.yaml"), 1e-3);
  EXPECT_EQ(t.start, TrainingStart::kAccelerationFeedback);
  EXPECT_TRUE(t.identify_models);
  EXPECT_EQ(t.identification_scenario.name, "identification");
  EXPECT_EQ(t.plant_objective, PlantObjective::kWorstRatioToPi);
  ASSERT_TRUE(t.judge_runs);
  const VerdictParams sweep = load_sweep_verdict(source("configs/sweeps/plant_family_identified.yaml"));
  EXPECT_EQ(t.verdict.limit_cycle_amplitude_m, sweep.limit_cycle_amplitude_m);
  EXPECT_EQ(t.verdict.min_decay_rate_per_s, sweep.min_decay_rate_per_s);
  ASSERT_EQ(t.plants.size(), 11u);
  EXPECT_TRUE(t.plants[0].values.empty()) << "the configured plant first";
  EXPECT_FALSE(t.plants[0].commission) << "the configured plant judged on the models the main job runs";
  for (std::size_t i = 1; i < t.plants.size(); ++i) EXPECT_TRUE(t.plants[i].commission) << t.plants[i].name;
  for (const PlantVariant& plant : t.plants)
    EXPECT_TRUE(plant.models.empty()) << plant.name << ": fitted by the trainer, not the file";
}

// An optional verdict_from_sweep: each run judged whole by that sweep file's verdict; only with
// the worst-ratio objective; a missing file or a bad threshold there is named.
TEST(TrainingConfig, ASweepsVerdictJudgesRunsWithTheWorstRatioObjectiveOnly) {
  const std::string robust = source("configs/training_robust.yaml");
  const std::string paper = source("configs/training.yaml");
  EXPECT_FALSE(load_training_params(paper, 1e-3).judge_runs);
  const TrainingParams judged = load_training_params(robust, 1e-3);
  EXPECT_TRUE(judged.judge_runs);
  const VerdictParams sweep = load_sweep_verdict(source("configs/sweeps/plant_family.yaml"));
  EXPECT_EQ(judged.verdict.tail_s, sweep.tail_s);
  EXPECT_EQ(judged.verdict.tail_windows, sweep.tail_windows);
  EXPECT_EQ(judged.verdict.limit_cycle_amplitude_m, sweep.limit_cycle_amplitude_m);
  EXPECT_EQ(judged.verdict.min_decay_rate_per_s, sweep.min_decay_rate_per_s);
  EXPECT_EQ(judged.verdict.max_saturated_tail_share, sweep.max_saturated_tail_share);
  EXPECT_EQ(judged.verdict.max_free_vibration_settling_s, sweep.max_free_vibration_settling_s);
  EXPECT_EQ(judged.verdict.rest_command_band_mps, sweep.rest_command_band_mps);
  EXPECT_EQ(judged.verdict.min_rest_s, sweep.min_rest_s);
  EXPECT_EQ(judged.verdict.max_rest_stretch_peak_m, sweep.max_rest_stretch_peak_m);
  EXPECT_EQ(judged.verdict.max_rest_compensation_rms_n, sweep.max_rest_compensation_rms_n);
  EXPECT_EQ(judged.verdict.max_forced_ratio_to_pi, sweep.max_forced_ratio_to_pi);
  const std::string from_sweep = "verdict_from_sweep: {value: sweeps/plant_family.yaml, source: \"chosen: test\"}\n";
  try {
    parse_training_params(test::read_text("configs/training.yaml") + from_sweep, paper, 1e-3);
    ADD_FAILURE() << "a verdict with the weighted-sum objective was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("worst_ratio_to_pi"), std::string::npos) << e.what();
  }
  try {
    load_training_params(robust, 1e-3, {ConfigOverride::parse("verdict_from_sweep=sweeps/nothing.yaml")});
    ADD_FAILURE() << "a missing sweep file was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("sweeps/nothing.yaml"), std::string::npos) << e.what();
  }
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("pmlsm_verdict_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::string sweep_text = test::read_text("configs/sweeps/plant_family.yaml");
  const auto at = sweep_text.find("  tail_windows:");
  ASSERT_NE(at, std::string::npos);
  sweep_text.insert(at, "  tail_ms: {value: 1, source: \"chosen: test\"}\n");
  std::ofstream(dir / "sweep.yaml") << sweep_text;
  try {
    load_training_params(robust, 1e-3, {ConfigOverride::parse("verdict_from_sweep=" + (dir / "sweep.yaml").string())});
    ADD_FAILURE() << "an unknown verdict key was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("verdict.tail_ms: unknown key"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

TEST(TrainingConfig, BadValuesNameTheKey) {
  const std::string path = source("configs/training.yaml");
  const std::vector<std::pair<std::string, std::string>> cases{
      {"crossover_rate=2", "crossover_rate"},
      {"optimiser=pso", "optimiser"},
      {"population_size=3", "population_size"},
      {"cost_velocity=measured", "cost_velocity"},
      {"nonsense=1", "nonsense"},
  };
  for (const auto& [override_text, key] : cases) {
    try {
      load_training_params(path, 1e-3, {ConfigOverride::parse(override_text)});
      ADD_FAILURE() << override_text << " was accepted";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  }
}

// `start: acceleration_feedback`: the network's equivalent of the configured law. For small
// signals its force is acceleration feedback's (within 1 %), on the same signal; it bends below
// the law as it nears G_n. Both must read the same signal; the file's key is optional (random)
// and a bad value is named.
TEST(TrainingStart, TheNetworkEquivalentOfAccelerationFeedback) {
  SystemParams p = shipped_params();
  p.compensator.rnn.on_reference_error = true;
  p.compensator.acceleration_feedback.on_reference_error = true;
  RnnCompensator rnn(p.rnn_compensator_params(false));
  rnn.set_weights(rnn_weights_from_acceleration_feedback(p));
  AccelFeedback law(p.accel_feedback_params());
  for (const auto& [a_load, a_ref] : std::vector<std::pair<double, double>>{{0.2, 0.0}, {-0.3, 0.1}, {0.5, 0.6}}) {
    const double expected = law.step({a_load, a_ref});
    EXPECT_NEAR(rnn.step({a_load, 0.0, 0.0, a_ref}).force_n, expected, 0.01 * std::abs(expected)) << a_load;
  }
  EXPECT_LT(std::abs(rnn.step({4.0, 0.0, 0.0, 0.0}).force_n), std::abs(law.step({4.0, 0.0})));
  p.compensator.rnn.on_reference_error = false;
  try {
    rnn_weights_from_acceleration_feedback(p);
    ADD_FAILURE() << "a network on a_L was started from the law on the error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("compensator.rnn.on_reference_error"), std::string::npos) << e.what();
  }
  const std::string path = source("configs/training.yaml");
  EXPECT_EQ(load_training_params(path, 1e-3).start, TrainingStart::kRandom);
  EXPECT_EQ(load_training_params(source("configs/training_from_accel.yaml"), 1e-3).start,
            TrainingStart::kAccelerationFeedback);
  try {
    load_training_params(path, 1e-3, {ConfigOverride::parse("start=best_guess")});
    ADD_FAILURE() << "start=best_guess was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("start: expected 'random' or 'acceleration_feedback', got 'best_guess'"),
              std::string::npos)
        << e.what();
  }
}

// Plants commissioned for training: each variant carries what identify_load fitted on it (the
// models' keys of identified_parameters), applied after its moves; the same as the sweep's
// commissioning (with_identified_load). Only those keys may follow a plant.
TEST(RnnCost, CommissionedPlantsCarryTheirIdentifiedModels) {
  const SystemParams& p = shipped_params();
  const Scenario identification = shipped_scenario("identification");
  const PlantVariant light{
      "light_stiff", {{"plant.mechanics.load_mass_kg", 2.0}, {"plant.mechanics.spring_n_per_m", 27400.0}}, 1.0};
  const std::vector<PlantVariant> plants = commissioned_plants(p, {light}, identification);
  ASSERT_EQ(plants.size(), 1u);
  const SystemParams on_plant = apply_plant_variant(p, light);
  const IdentifiedLoad fit = identify_load(on_plant, identification_samples(run_scenario(on_plant, identification)));
  EXPECT_EQ(plants[0].models, identified_parameters(fit));
  const SystemParams commissioned = apply_plant_variant(p, plants[0]);
  EXPECT_EQ(commissioned.kalman.model.load_mass_kg, with_identified_load(on_plant, fit).kalman.model.load_mass_kg);
  EXPECT_NEAR(commissioned.kalman.model.load_mass_kg, 2.0, 0.3);
  EXPECT_EQ(commissioned.plant.mechanics.load_mass_kg, 2.0);
  PlantVariant as_configured = light;
  as_configured.commission = false;
  const std::vector<PlantVariant> kept = commissioned_plants(p, {as_configured, light}, identification);
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_TRUE(kept[0].models.empty()) << "commission: false keeps the configured models";
  EXPECT_EQ(kept[1].models, plants[0].models);
  PlantVariant bad = light;
  bad.models = {{"velocity_loop.kp_n_s_per_m", 1.0}};
  try {
    apply_plant_variant(p, bad);
    ADD_FAILURE() << "a controller gain passed as an identified model";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("not a model commissioning identifies"), std::string::npos) << e.what();
  }
  const std::string path = source("configs/training_robust.yaml");
  const std::string text = test::read_text("configs/training_robust.yaml");
  EXPECT_FALSE(parse_training_params(text, path, 1e-3).identify_models);
  const TrainingParams t = parse_training_params(
      text +
          "models:\n  identified: {value: true, source: \"chosen: test\"}\n"
          "  identification_scenario: {value: scenarios/identification.yaml, source: \"chosen: test\"}\n",
      path, 1e-3);
  EXPECT_TRUE(t.identify_models);
  EXPECT_EQ(t.identification_scenario.name, "identification");
  for (const PlantVariant& plant : t.plants)
    EXPECT_TRUE(plant.commission) << plant.name << ": commissioned unless told";
  const std::string commissioned_path = source("configs/training_commissioned.yaml");
  const std::string commissioned_file = test::read_text("configs/training_commissioned.yaml");
  std::string commissioned_text = commissioned_file;
  const std::string configured_models = "commission: {value: false";
  const std::size_t at = commissioned_text.find(configured_models);
  ASSERT_NE(at, std::string::npos);
  commissioned_text.replace(at, configured_models.size(), "commission: {value: maybe");
  try {
    parse_training_params(commissioned_text, commissioned_path, 1e-3);
    ADD_FAILURE() << "commission: maybe was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("commission"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("maybe"), std::string::npos) << e.what();
  }
  // Without commissioning the key would say nothing: refused, named.
  std::string uncommissioned = commissioned_file;
  const std::size_t models_at = uncommissioned.find("\nmodels:");
  ASSERT_NE(models_at, std::string::npos);
  uncommissioned.erase(models_at + 1);
  try {
    parse_training_params(uncommissioned, commissioned_path, 1e-3);
    ADD_FAILURE() << "a plant's commission key without models.identified was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("plants[0].commission: only with models.identified: true"), std::string::npos)
        << e.what();
  }
}

TEST(RnnCost, ZeroWeightsCostWhatPiOnlyCosts) {
  // tanh(0) = 0: a zero network adds no force, so the cost is the PI loop's.
  const SystemParams& p = shipped_params();
  const Scenario pulse = shipped_scenario("pulse");
  const RnnCost cost(p, {{pulse, "pulse", 1.0}}, CostVelocity::truth);
  ASSERT_EQ(cost.dimension(), 91u);
  const double pi_cost = compute_metrics(run_scenario(p, pulse), pulse, p.timing.control_period_s).cost_true;
  EXPECT_DOUBLE_EQ(cost(std::vector<double>(91, 0.0)), pi_cost);
}

// Over plant variants: the costs per plant and the worst ratio to PI alone. A zero network is
// PI alone on every plant, so its worst ratio is exactly 1; the light, stiff plant changes the cost.
TEST(RnnCost, PlantVariantsAndTheWorstRatioToPi) {
  const SystemParams& p = shipped_params();
  const Scenario pulse = shipped_scenario("pulse");
  const std::vector<PlantVariant> plants{
      {"configured", {}, 1.0},
      {"light_stiff", {{"plant.mechanics.load_mass_kg", 2.0}, {"plant.mechanics.spring_n_per_m", 27400.0}}, 1.0}};
  const std::vector<double> zero(91, 0.0);
  const RnnCost worst(p, {{pulse, "pulse", 1.0}}, CostVelocity::truth, plants, PlantObjective::kWorstRatioToPi);
  EXPECT_DOUBLE_EQ(worst(zero), 1.0);
  const RnnCost sum(p, {{pulse, "pulse", 1.0}}, CostVelocity::truth, plants, PlantObjective::kWeightedSum);
  const RnnCost nominal(p, {{pulse, "pulse", 1.0}}, CostVelocity::truth);
  SystemParams light = p;
  light.plant.mechanics.load_mass_kg = 2.0;
  light.plant.mechanics.spring_n_per_m = 27400.0;
  const RnnCost light_only(light, {{pulse, "pulse", 1.0}}, CostVelocity::truth);
  EXPECT_DOUBLE_EQ(sum(zero), nominal(zero) + light_only(zero));
  EXPECT_NE(nominal(zero), light_only(zero));
  // Only the plant moves; a model key or an unknown one is refused, naming the variant.
  EXPECT_THROW(RnnCost(p, {{pulse, "pulse", 1.0}}, CostVelocity::truth,
                       {{"m", {{"kalman.model.load_mass_kg", 2.0}}, 1.0}}, PlantObjective::kWeightedSum),
               std::invalid_argument);
  EXPECT_THROW(RnnCost(p, {{pulse, "pulse", 1.0}}, CostVelocity::truth, {{"x", {{"plant.nothing", 2.0}}, 1.0}},
                       PlantObjective::kWeightedSum),
               std::invalid_argument);
}

// Runs judged whole: the shipped weights on the light, stiff plant (2 kg, 27,400 N/m) sustain an
// oscillation the guard takes out at 0.5 s, after which the cost window's ratio alone hides
// nothing: the judged objective is the plain one plus the fault penalty. On the nominal plant
// their run is clean and both objectives agree. A verdict needs the worst-ratio objective.
TEST(RnnCost, JudgedRunsPayForAFaultAfterTheirCost) {
  const SystemParams& p = shipped_params();
  const Scenario pulse = shipped_scenario("pulse");
  const std::vector<double> weights = load_rnn_weights(source("configs/rnn_weights.yaml")).weights;
  const VerdictParams verdict = load_sweep_verdict(source("configs/sweeps/plant_family.yaml"));
  const std::vector<PlantVariant> light_stiff{
      {"light_stiff", {{"plant.mechanics.load_mass_kg", 2.0}, {"plant.mechanics.spring_n_per_m", 27400.0}}, 1.0}};
  const std::vector<PlantVariant> nominal{{"configured", {}, 1.0}};
  const auto objective = PlantObjective::kWorstRatioToPi;
  const double plain = RnnCost(p, {{pulse, "pulse", 1.0}}, CostVelocity::truth, light_stiff, objective)(weights);
  const double judged =
      RnnCost(p, {{pulse, "pulse", 1.0}}, CostVelocity::truth, light_stiff, objective, verdict)(weights);
  EXPECT_GT(plain, 1.0);  // worse than PI alone there already
  EXPECT_DOUBLE_EQ(judged, plain + RnnCost::kFaultPenalty);
  const double nominal_plain = RnnCost(p, {{pulse, "pulse", 1.0}}, CostVelocity::truth, nominal, objective)(weights);
  EXPECT_LT(nominal_plain, 0.2);
  EXPECT_DOUBLE_EQ(RnnCost(p, {{pulse, "pulse", 1.0}}, CostVelocity::truth, nominal, objective, verdict)(weights),
                   nominal_plain);
  EXPECT_THROW(RnnCost(p, {{pulse, "pulse", 1.0}}, CostVelocity::truth, nominal, PlantObjective::kWeightedSum, verdict),
               std::invalid_argument);
}

TEST(RnnCost, RejectsWrongSizeAndNonFiniteSetsAsWorst) {
  const SystemParams& p = shipped_params();
  const RnnCost cost(p, {{shipped_scenario("pulse"), "pulse", 1.0}}, CostVelocity::estimated);
  EXPECT_TRUE(std::isinf(cost(std::vector<double>(90, 0.0))));
  std::vector<double> w(91, 0.1);
  w[7] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(std::isinf(cost(w)));
}

TEST(RnnCost, WeightsScenariosAndIsDeterministic) {
  const SystemParams& p = shipped_params();
  const Scenario pulse = shipped_scenario("pulse");
  std::vector<double> w(91);
  for (std::size_t i = 0; i < w.size(); ++i) w[i] = 0.3 * std::sin(1.7 * static_cast<double>(i));
  const RnnCost once(p, {{pulse, "pulse", 1.0}}, CostVelocity::truth);
  const RnnCost twice(p, {{pulse, "pulse", 2.0}}, CostVelocity::truth);
  EXPECT_DOUBLE_EQ(once(w), once(w));
  EXPECT_DOUBLE_EQ(twice(w), 2.0 * once(w));
}

// The paper's claim (Figs. 11-12, cost (23)): PI + RNN leaves much less load
// error than PI only and than the paper's acceleration feedback (-K_a a_L), with the
// weights the trainer made (configs/rnn_weights.yaml), and than the shipped acceleration feedback,
// which works on the error to the reference (printed; README).
TEST(ShippedWeights, RnnBeatsPiOnlyAndThePapersAccelerationFeedbackOnThePulseTest) {
  const SystemParams& p = shipped_params();
  const Scenario pulse = shipped_scenario("pulse");
  const RnnWeightsFile file = load_rnn_weights(source("configs/rnn_weights.yaml"));
  ASSERT_EQ(file.layer_sizes, p.compensator.rnn.layer_sizes);
  ASSERT_EQ(file.gain_n, p.compensator.rnn.gain_n);
  ASSERT_EQ(file.input_scale_s2_per_m, p.compensator.rnn.input_scale_s2_per_m);
  ASSERT_EQ(file.on_reference_error, p.compensator.rnn.on_reference_error);
  const double period = p.timing.control_period_s;
  const ScenarioMetrics pi = compute_metrics(run_scenario(p, pulse), pulse, period);
  const auto accel_cost = [&](bool on_reference_error) {
    SystemParams q = p;
    q.compensator.acceleration_feedback.on_reference_error = on_reference_error;
    return compute_metrics(run_with_compensator(q, pulse, {CompensatorKind::kAccel, {}, false}), pulse, period)
        .cost_true;
  };
  const double papers_accel = accel_cost(false), shipped_accel = accel_cost(true);
  const ScenarioMetrics rnn = compute_metrics(run_with_rnn(p, pulse, file.weights, false), pulse, period);
  std::printf("[ rnn        ] pulse %.3f; acceleration feedback: the paper's %.3f, on the reference error %.3f\n",
              rnn.cost_true, papers_accel, shipped_accel);
  EXPECT_LT(rnn.cost_true, pi.cost_true / 5) << "PI only " << pi.cost_true;
  EXPECT_LT(rnn.cost_true, papers_accel) << "the paper's acceleration feedback";
  // Searched from the shipped law (configs/training_commissioned.yaml): the target is the RNN at
  // most acceleration feedback (measured 5.04 against 5.41; with the compensators' force nudged
  // in its sixth digit 5.04-5.69 against 5.41-5.69, README).
  EXPECT_LT(rnn.cost_true, shipped_accel) << "acceleration feedback on the reference error";
  EXPECT_LT(rnn.load_vibration_rms_mps, pi.load_vibration_rms_mps / 3);
  // The file records the objective it was trained to: its training file's, recomputed here on
  // the plants commissioned as the trainer commissions them, with the system overrides the
  // search ran with (the source's ", --set k=v ...)"; the shipped set: the schedule's limit at 2).
  std::vector<ConfigOverride> overrides;
  const std::string::size_type set_at = file.source.find(", --set ");
  if (set_at != std::string::npos) {
    std::istringstream searched_with(file.source.substr(set_at + 8, file.source.rfind(')') - set_at - 8));
    for (std::string item; searched_with >> item;) overrides.push_back(ConfigOverride::parse(item));
  }
  const SystemParams searched = load_system_params(source("configs/system.yaml"), overrides);
  const TrainingParams t = load_training_params(source("configs/training_commissioned.yaml"), period);
  ASSERT_TRUE(t.judge_runs);
  ASSERT_TRUE(t.identify_models);
  const std::vector<PlantVariant> plants = commissioned_plants(searched, t.plants, t.identification_scenario);
  const RnnCost objective(searched, t.scenarios, t.cost_velocity, plants, t.plant_objective, t.verdict);
  EXPECT_NEAR(objective(file.weights), file.cost, 1e-9 * file.cost);
}

// The free-vibration target (Fig. 10) with the shipped weights: the load within
// 2 % of the 0.02 m start in under 0.5 s (the search judges the free vibration too).
TEST(ShippedWeights, RnnSettlesTheFreeVibrationInUnderHalfASecond) {
  const SystemParams& p = shipped_params();
  const Scenario free = shipped_scenario("free_vibration");
  const RnnWeightsFile file = load_rnn_weights(source("configs/rnn_weights.yaml"));
  const ScenarioMetrics m =
      compute_metrics(run_with_rnn(p, free, file.weights, false), free, p.timing.control_period_s);
  std::printf("[ rnn        ] free vibration settles in %.3f s\n", m.load_settling_time_s);
  EXPECT_LT(m.load_settling_time_s, 0.5);  // measured 0.441 s
}

}  // namespace
}  // namespace pmlsm

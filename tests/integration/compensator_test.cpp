// The compensated control loop as separate processes on real DDS: evaluator,
// Kalman estimator, controller (--compensation topic), a compensator node
// (accel_feedback, state_feedback or rnn_compensator) and the plant in lockstep. The trace
// must equal the in-process run_compensated loop's byte for byte.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <sstream>

#include "child_process.hpp"
#include "integration_support.hpp"
#include "pmlsm/compensation/accel_feedback.hpp"
#include "pmlsm/compensation/state_feedback.hpp"
#include "pmlsm/sim/compensator_law.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/analysis/compensated_run.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/compensation/jordan_rnn.hpp"
#include "pmlsm/analysis/rnn_training.hpp"
#include "pmlsm/config/weights_file.hpp"
#include "spring_force_feedback/spring_force_feedback.hpp"
#include "trace_csv.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;
using std::chrono::seconds;

using test::bin;
using test::read_file;
using test::source;
using test::test_domain;

fs::path fresh_dir(const std::string& name) { return test::fresh_dir("pmlsm_comp", name); }

const std::string kScenarioName = "pulse";
std::string scenario_path() { return source("configs/scenarios/" + kScenarioName + ".yaml"); }

std::vector<std::string> scenario_node_args(const std::string& exe, const std::string& domain,
                                            std::vector<std::string> extra = {}) {
  return test::node_args(exe, domain, scenario_path(), std::move(extra));
}

using test::trace_column;
using test::trainer_args;

SystemParams system_params() { return load_system_params(source("configs/system.yaml")); }
Scenario scenario(const SystemParams& params) { return load_scenario(scenario_path(), params.timing.control_period_s); }

/// Weights in [-0.5, 0.5] from a fixed seed, sized and tagged as configs/system.yaml's network.
RnnWeightsFile pseudo_random_weights(const SystemParams& params, std::uint64_t seed) {
  RnnWeightsFile w;
  w.layer_sizes = params.compensator.rnn.layer_sizes;
  w.input_scale_s2_per_m = params.compensator.rnn.input_scale_s2_per_m;
  w.on_reference_error = params.compensator.rnn.on_reference_error;
  w.gain_n = params.compensator.rnn.gain_n;
  w.cost = -1;
  w.source = "compensator_test seed " + std::to_string(seed);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  w.weights.resize(JordanRnn::parameter_count(w.layer_sizes));
  for (double& x : w.weights) x = u(rng);
  return w;
}

std::size_t nonzero_count(const std::vector<double>& v) {
  return static_cast<std::size_t>(std::count_if(v.begin(), v.end(), [](double x) { return x != 0.0; }));
}

struct CompensatedRun {
  std::string trace;               ///< the evaluator's CSV
  std::string compensator_output;  ///< stdout + stderr of the compensator node
};

/// Runs evaluator, estimator, controller --compensation topic and plant in
/// lockstep around an already running compensator (or one started here).
/// Every process must end with exit 0 within the deadline.
CompensatedRun run_loop(const fs::path& dir, const std::string& domain, test::ChildProcess& compensator,
                        std::vector<std::string> controller_extra = {}) {
  CompensatedRun result;
  test::ChildProcess evaluator(scenario_node_args("evaluator", domain, {"--out", dir.string(), "--label", "comp"}),
                               (dir / "evaluator.log").string());
  test::ChildProcess estimator(scenario_node_args("kalman_estimator", domain), (dir / "estimator.log").string());
  controller_extra.insert(controller_extra.begin(), {"--compensation", "topic"});
  test::ChildProcess controller(scenario_node_args("controller", domain, controller_extra),
                                (dir / "controller.log").string());
  test::ChildProcess plant(scenario_node_args("plant_sim", domain, {"--peers", "3"}), (dir / "plant.log").string());
  for (auto* p : {&plant, &controller, &compensator, &estimator, &evaluator}) {
    const auto code = p->wait_for(seconds(60));
    EXPECT_TRUE(code.has_value()) << "still running:\n" << p->output();
    if (code) {
      EXPECT_EQ(*code, 0) << p->output();
    }
  }
  EXPECT_NE(controller.output().find("compensation topic (0 ticks without;"), std::string::npos) << controller.output();
  EXPECT_NE(plant.output().find("late 0, rejected 0"), std::string::npos) << plant.output();
  result.trace = read_file(dir / (kScenarioName + "_comp.csv"));
  EXPECT_FALSE(result.trace.empty()) << evaluator.output();
  result.compensator_output = compensator.output();
  return result;
}

/// The distributed trace equals the in-process one, and the compensation was really on.
void expect_same_trace(const fs::path& dir, const CompensatedRun& run, const std::vector<TickRecord>& in_process) {
  write_trace_csv((dir / "in_process.csv").string(), in_process);
  const std::string expected = read_file(dir / "in_process.csv");
  EXPECT_TRUE(run.trace == expected) << "the distributed trace differs from the in-process one (" << dir << ")";
  const std::size_t distributed_nonzero = nonzero_count(trace_column(run.trace, "compensation_force_n"));
  EXPECT_GT(distributed_nonzero, in_process.size() / 2)
      << "compensation_force_n is (almost) always zero: the compensator is not in the loop";
  EXPECT_GT(nonzero_count(trace_column(expected, "compensation_force_n")), in_process.size() / 2);
}

TEST(CompensatorDistributed, AccelFeedbackTraceEqualsInProcess) {
  const fs::path dir = fresh_dir("accel");
  const std::string domain = test_domain(10);
  test::ChildProcess compensator(scenario_node_args("accel_feedback", domain), (dir / "accel_feedback.log").string());
  const CompensatedRun run = run_loop(dir, domain, compensator);

  const SystemParams params = system_params();
  const auto in_process = run_with_compensator(params, scenario(params), {CompensatorKind::kAccel, {}, false});
  expect_same_trace(dir, run, in_process);
  EXPECT_NE(run.compensator_output.find("2000 ticks answered"), std::string::npos) << run.compensator_output;
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

// The filter slots in the controller node (a low-pass on the compensator's force, a shallow notch
// on the force command) give the in-process loop's trace with the same filters, byte for byte, and
// a trace other than the unfiltered one.
TEST(CompensatorDistributed, FilterSlotsTraceEqualsInProcess) {
  const fs::path dir = fresh_dir("filters");
  const std::string domain = test_domain(95);
  const std::vector<std::string> filters{
      "filters.compensation.slot_1.kind=low_pass",      "filters.compensation.slot_1.frequency_hz=40",
      "filters.compensation.slot_1.damping=0.7",        "filters.force_command.slot_3.kind=notch",
      "filters.force_command.slot_3.frequency_hz=10.2", "filters.force_command.slot_3.damping=0.1",
      "filters.force_command.slot_3.second_damping=0.2"};
  test::ChildProcess compensator(scenario_node_args("accel_feedback", domain), (dir / "accel_feedback.log").string());
  std::vector<std::string> set{"--set"};
  set.insert(set.end(), filters.begin(), filters.end());
  const CompensatedRun run = run_loop(dir, domain, compensator, set);

  const SystemParams params = load_system_params(source("configs/system.yaml"), parse_overrides(filters));
  const auto in_process = run_with_compensator(params, scenario(params), {CompensatorKind::kAccel, {}, false});
  expect_same_trace(dir, run, in_process);
  const SystemParams plain = system_params();
  write_trace_csv((dir / "unfiltered.csv").string(),
                  run_with_compensator(plain, scenario(plain), {CompensatorKind::kAccel, {}, false}));
  EXPECT_NE(read_file(dir / "unfiltered.csv"), run.trace) << "the filters changed nothing";
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

TEST(CompensatorDistributed, StateFeedbackTraceEqualsInProcess) {
  const fs::path dir = fresh_dir("state");
  const std::string domain = test_domain(78);
  test::ChildProcess compensator(scenario_node_args("state_feedback", domain), (dir / "state_feedback.log").string());
  const CompensatedRun run = run_loop(dir, domain, compensator);

  const SystemParams params = system_params();
  const auto in_process = run_with_compensator(params, scenario(params), {CompensatorKind::kState, {}, false});
  expect_same_trace(dir, run, in_process);
  EXPECT_NE(run.compensator_output.find("2000 ticks answered"), std::string::npos) << run.compensator_output;
  EXPECT_NE(run.compensator_output.find("0 rejected, 0 model restarts, 0 skipped"), std::string::npos)
      << run.compensator_output;
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

void expect_rnn_trace_equals_in_process(bool online_learning, int domain_offset) {
  const fs::path dir = fresh_dir(online_learning ? "rnn_online" : "rnn");
  const std::string domain = test_domain(domain_offset);
  const SystemParams params = system_params();
  const RnnWeightsFile weights = pseudo_random_weights(params, 7);
  const std::string weights_path = (dir / "w.yaml").string();
  save_rnn_weights(weights_path, weights);

  std::vector<std::string> extra{"--weights", weights_path};
  if (online_learning) extra.push_back("--online-learning");
  test::ChildProcess compensator(scenario_node_args("rnn_compensator", domain, extra), (dir / "rnn.log").string());
  const CompensatedRun run = run_loop(dir, domain, compensator);

  expect_same_trace(dir, run, run_with_rnn(params, scenario(params), weights.weights, online_learning));
  const std::string& out = run.compensator_output;
  EXPECT_NE(out.find("2000 ticks answered"), std::string::npos) << out;
  EXPECT_NE(out.find("0 weight set(s) taken, 0 refused"), std::string::npos) << out;
  if (online_learning) {
    // The learning rule must really have run, or the comparison proves nothing about it.
    std::smatch m;
    ASSERT_TRUE(std::regex_search(out, m, std::regex(R"(online learning on: (\d+) updates)"))) << out;
    EXPECT_GT(std::stoull(m[1].str()), 0u) << out;
  }
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

TEST(CompensatorDistributed, RnnTraceEqualsInProcess) { expect_rnn_trace_equals_in_process(false, 11); }

TEST(CompensatorDistributed, RnnWithOnlineLearningTraceEqualsInProcess) {
  expect_rnn_trace_equals_in_process(true, 12);
}

TEST(CompensatorDistributed, RnnRefusesBadWeightsFile) {
  const fs::path dir = fresh_dir("badweights");
  const SystemParams params = system_params();
  const RnnWeightsFile good = pseudo_random_weights(params, 3);
  save_rnn_weights((dir / "good.yaml").string(), good);
  const std::string good_text = read_file(dir / "good.yaml");

  // Derived from a valid file by one textual change each, so that only that change is wrong.
  const std::string first = "weights: [\n";
  const auto at = good_text.find(first);
  ASSERT_NE(at, std::string::npos) << good_text;
  const auto value_begin = good_text.find_first_not_of(' ', at + first.size());
  const auto value_end = good_text.find(',', value_begin);
  ASSERT_NE(value_end, std::string::npos);
  {
    std::string nan_text = good_text;
    nan_text.replace(value_begin, value_end - value_begin, ".nan");
    std::ofstream(dir / "nan.yaml") << nan_text;
    std::string short_text = good_text;
    short_text.erase(value_begin, value_end + 1 - value_begin);  // one value fewer
    std::ofstream(dir / "short.yaml") << short_text;
  }
  RnnWeightsFile other = good;  // valid on its own, but another network
  other.layer_sizes = {3, 4, 1};
  other.weights.assign(JordanRnn::parameter_count(other.layer_sizes), 0.1);
  save_rnn_weights((dir / "other_net.yaml").string(), other);
  RnnWeightsFile other_gain = good;
  other_gain.gain_n = good.gain_n * 2;
  save_rnn_weights((dir / "other_gain.yaml").string(), other_gain);

  const std::size_t count = JordanRnn::parameter_count(good.layer_sizes);
  const std::vector<std::pair<std::string, std::string>> cases{
      {"nan.yaml", "weights[0]: must be finite"},
      {"short.yaml", "expected " + std::to_string(count) + " values"},
      {"other_net.yaml", "layer sizes differ"},
      {"other_gain.yaml", "gain"},
  };
  for (const auto& [file, why] : cases) {
    test::ChildProcess p(scenario_node_args("rnn_compensator", test_domain(13), {"--weights", (dir / file).string()}),
                         (dir / (file + ".log")).string());
    const auto code = p.wait_for(seconds(30));
    ASSERT_TRUE(code.has_value()) << file << " still running:\n" << p.output();
    EXPECT_EQ(*code, 2) << file << ": " << p.output();
    EXPECT_NE(p.output().find(file), std::string::npos) << "the message must name the file: " << p.output();
    EXPECT_NE(p.output().find(why), std::string::npos) << file << ": " << p.output();
  }
  // The unchanged file is accepted (so the refusals above are about the changes).
  test::ChildProcess p(scenario_node_args("rnn_compensator", test_domain(13),
                                          {"--weights", (dir / "good.yaml").string(), "--peer-timeout-s", "0.5"}),
                       (dir / "good.log").string());
  const auto code = p.wait_for(seconds(30));
  ASSERT_TRUE(code.has_value()) << p.output();
  EXPECT_EQ(*code, 4) << "good file: expected to run and lose its (absent) peers: " << p.output();
  EXPECT_NE(p.output().find("weights from"), std::string::npos) << p.output();
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

// A trainer of another network (layer sizes 3-4-1) publishes NetworkWeights on
// the domain; the compensator must refuse them and keep its file's weights.
// Sequence, so that timing cannot decide it: the compensator is up first (its
// NetworkWeights reader exists from the start), the trainer runs to the end
// (it waits up to 2 s at exit for the set to be acknowledged), then the loop
// runs; the compensator takes the set at tick 0 and must refuse it.
TEST(CompensatorDistributed, RnnRefusesWrongSizeWeightsFromTopicAndKeepsItsOwn) {
  const fs::path dir = fresh_dir("topic_refuse");
  const std::string domain = test_domain(14);
  const SystemParams params = system_params();
  const RnnWeightsFile weights = pseudo_random_weights(params, 11);
  const std::string weights_path = (dir / "w.yaml").string();
  save_rnn_weights(weights_path, weights);

  test::ChildProcess compensator(
      scenario_node_args("rnn_compensator", domain, {"--weights", weights_path, "--peer-timeout-s", "60"}),
      (dir / "rnn.log").string());
  ASSERT_TRUE(compensator.wait_for_output("weights from", seconds(30))) << compensator.output();
  {
    test::ChildProcess trainer(
        trainer_args(domain, {"--weights-readers", "1", "--set", "compensator.rnn.layer_sizes=[3,4,1]", "--train-set",
                              "population_size=16", "max_evaluations=64", "--out", (dir / "w341.yaml").string()}),
        (dir / "trainer.log").string());
    const auto code = trainer.wait_for(seconds(60));
    ASSERT_TRUE(code.has_value()) << trainer.output();
    ASSERT_EQ(*code, 0) << trainer.output();
  }
  ASSERT_EQ(load_rnn_weights((dir / "w341.yaml").string()).layer_sizes, (std::vector<int>{3, 4, 1}));

  const CompensatedRun run = run_loop(dir, domain, compensator);
  expect_same_trace(dir, run, run_with_rnn(params, scenario(params), weights.weights, false));
  const std::string& out = run.compensator_output;
  EXPECT_NE(out.find("refused, keeping version 0: layer sizes differ"), std::string::npos) << out;
  EXPECT_NE(out.find("from 'de_trainer gen"), std::string::npos) << out;
  EXPECT_NE(out.find("0 weight set(s) taken"), std::string::npos) << out;
  EXPECT_EQ(out.find(" 0 refused"), std::string::npos) << out;
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

// The tutorial's compensator (compensators/spring_force_feedback, docs/writing-a-compensator.md),
// made from its folder alone, launched in a compensator's place in separate processes and composed:
// both traces equal the in-process loop with its law, byte for byte.
TEST(CompensatorDistributed, AFolderCompensatorComposedAndSeparateEqualsItsLawInProcess) {
  const fs::path dir = fresh_dir("folder");
  const SystemParams params = system_params();
  write_trace_csv((dir / "in_process.csv").string(),
                  run_with_law<SpringForceFeedback>(params, scenario(params), "spring_force_feedback"));
  const std::string expected = read_file(dir / "in_process.csv");
  ASSERT_GT(nonzero_count(trace_column(expected, "compensation_force_n")), 1000u);
  for (const bool composed : {false, true}) {
    const std::string mode = composed ? "composed" : "separate";
    test::ChildProcess launch(
        {bin("launcher"), source("launch/sim_compensator.yaml"), "--arg", "compensator=spring_force_feedback", "--arg",
         "compose=" + std::string(composed ? "true" : "false"), "--arg", "domain=" + test_domain(composed ? 112 : 111),
         "--arg", "out=" + (dir / mode).string(), "--arg", "keystore=none"},
        (dir / (mode + ".log")).string());
    const auto code = launch.wait_for(seconds(120));
    ASSERT_TRUE(code.has_value()) << launch.output();
    EXPECT_EQ(*code, 0) << launch.output();
    const std::string out = launch.output();
    EXPECT_NE(out.find("spring_force_feedback: 2000 ticks answered, 0 saturated, 0 rejected, 0 skipped"),
              std::string::npos)
        << out;
    EXPECT_EQ(out.find("container") != std::string::npos, composed) << out;
    EXPECT_TRUE(read_file(dir / mode / (kScenarioName + "_spring_force_feedback.csv")) == expected)
        << mode << " != in process (" << dir << ")";
  }
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace pmlsm

// The external reference over DDS: a controller on an external scenario follows
// `pmlsm setpoint` (lockstep, with the evaluator's trace of the raw command), never jumping
// (rate limit), back to zero when the source ends or dies, and a run whose source died
// mid-move ends with exit code 5; `pmlsm param` on the running controller, and a change there
// followed by state feedback at the same tick. Domains: offsets 74..77, 96, 99..101, 109, 110.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "child_process.hpp"
#include "integration_support.hpp"

namespace pmlsm::test {
namespace {

namespace fs = std::filesystem;
using std::chrono::seconds;

// configs/scenarios/external.yaml with its duration replaced (sim seconds; lockstep runs
// several times faster than real time, the setpoint source on wall time).
std::string external_scenario(const fs::path& dir, double duration_s) {
  const std::string text = read_file(source("configs/scenarios/external.yaml"));
  const std::string changed = std::regex_replace(text, std::regex("duration_s: \\{value: [^,}]+"),
                                                 "duration_s: {value: " + std::to_string(duration_s));
  EXPECT_NE(changed, text);
  const fs::path path = dir / "external.yaml";
  std::ofstream(path) << changed;
  return path.string();
}

std::vector<std::string> setpoint_args(const std::string& domain, std::vector<std::string> extra) {
  std::vector<std::string> a{bin("pmlsm"), "--domain", domain, "--profiles", source("configs/dds/profiles.xml"),
                             "setpoint"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

struct ExternalRun {
  std::string controller;
  std::vector<double> command;
  int controller_exit = -1;
};

/// Evaluator, estimator, controller and plant in lockstep on an external scenario; `source` is started
/// once the controller runs, and `during` gets it (to kill it, say).
template <typename During>
ExternalRun run_with_setpoints(const fs::path& dir, const std::string& domain, double duration_s,
                               const std::vector<std::string>& setpoint, During&& during) {
  const std::string scenario = external_scenario(dir, duration_s);
  ExternalRun run;
  ChildProcess evaluator(node_args("evaluator", domain, scenario, {"--out", dir.string(), "--label", "ext"}),
                         (dir / "evaluator.log").string());
  ChildProcess estimator(node_args("kalman_estimator", domain, scenario), (dir / "estimator.log").string());
  ChildProcess controller(node_args("controller", domain, scenario), (dir / "controller.log").string());
  ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "3"}), (dir / "plant.log").string());
  EXPECT_TRUE(plant.wait_for_output("lockstep clock", seconds(30))) << plant.output();
  ChildProcess source_process(setpoint_args(domain, setpoint), (dir / "setpoint.log").string());
  during(source_process);
  for (auto* p : {&plant, &controller, &estimator, &evaluator}) {
    const auto code = p->wait_for(seconds(120));
    EXPECT_TRUE(code.has_value()) << "still running:\n" << p->output();
    if (p == &controller && code) run.controller_exit = *code;
  }
  run.controller = controller.output();
  const std::string trace = read_file(dir / "external_ext.csv");
  EXPECT_FALSE(trace.empty()) << evaluator.output();
  if (!trace.empty()) run.command = trace_column(trace, "command_mps");
  return run;
}

void expect_no_jump(const std::vector<double>& command, double max_accel_mps2, double period_s) {
  double max_step = 0;
  for (std::size_t k = 1; k < command.size(); ++k) max_step = std::max(max_step, std::abs(command[k] - command[k - 1]));
  EXPECT_LE(max_step, max_accel_mps2 * period_s * (1 + 1e-6)) << "the command jumped";
}

TEST(ExternalReferenceDistributed, ControllerFollowsPmlsmSetpointThenZero) {
  const fs::path dir = fresh_dir("pmlsm_external", "follow");
  const std::string domain = test_domain(74);
  ExternalRun run = run_with_setpoints(dir, domain, 40.0, {"0.2", "--hold-s", "1.0", "--source", "itest"},
                                       [](ChildProcess& source_process) {
                                         const auto code = source_process.wait_for(seconds(60));
                                         ASSERT_TRUE(code.has_value()) << source_process.output();
                                         EXPECT_EQ(*code, 0) << source_process.output();
                                       });
  EXPECT_EQ(run.controller_exit, 0) << run.controller;
  EXPECT_NE(run.controller.find("following setpoints from 'itest'"), std::string::npos) << run.controller;
  EXPECT_NE(run.controller.find("0 rejected (0 invalid)"), std::string::npos) << run.controller;
  EXPECT_NE(run.controller.find("(0 mid-move)"), std::string::npos) << run.controller;
  ASSERT_FALSE(run.command.empty());
  // Reached the setpoint (held 1 s of wall time, some seconds of lockstep), came back to zero.
  EXPECT_DOUBLE_EQ(*std::max_element(run.command.begin(), run.command.end()), 0.2);
  // From rest: the first setpoint can reach the controller before the lockstep's first tick
  // (the source starts once the clock is announced), so tick 0 holds at most one tick's ramp.
  EXPECT_GE(run.command.front(), 0.0);
  EXPECT_LE(run.command.front(), 3.0 * 1e-3 * (1 + 1e-6));
  EXPECT_EQ(run.command.back(), 0.0);
  expect_no_jump(run.command, 3.0, 1e-3);  // external.yaml: accel_mps2 3.0
  fs::remove_all(dir);
}

TEST(ExternalReferenceDistributed, SourceKilledMidMoveRampsToZeroAndTheRunIsNotValid) {
  const fs::path dir = fresh_dir("pmlsm_external", "killed");
  const std::string domain = test_domain(75);
  ExternalRun run =
      run_with_setpoints(dir, domain, 40.0, {"0.2", "--source", "itest"}, [](ChildProcess& source_process) {
        // Holding until Ctrl-C; killed without its final zero, as a crashed source would be.
        EXPECT_TRUE(source_process.wait_for_output("until Ctrl-C", seconds(30))) << source_process.output();
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(1500);
        while (std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(50));
        source_process.signal(SIGKILL);
        source_process.wait_for(seconds(10));
      });
  EXPECT_EQ(run.controller_exit, 5) << run.controller;
  EXPECT_NE(run.controller.find("setpoint stale (none for 0.25 s): reference ramps to zero from 0.2 m/s"),
            std::string::npos)
      << run.controller;
  EXPECT_NE(run.controller.find("(1 mid-move)"), std::string::npos) << run.controller;
  ASSERT_FALSE(run.command.empty());
  EXPECT_DOUBLE_EQ(*std::max_element(run.command.begin(), run.command.end()), 0.2);
  EXPECT_EQ(run.command.back(), 0.0);
  expect_no_jump(run.command, 3.0, 1e-3);
  fs::remove_all(dir);
}

TEST(ExternalReferenceDistributed, PmlsmSetpointWithoutAControllerExits3AndRefusesNaN) {
  const fs::path dir = fresh_dir("pmlsm_external", "alone");
  const std::string domain = test_domain(76);
  ChildProcess alone(setpoint_args(domain, {"0.1", "--wait-s", "1"}), (dir / "alone.log").string());
  auto code = alone.wait_for(seconds(30));
  ASSERT_TRUE(code.has_value());
  EXPECT_EQ(*code, 3) << alone.output();
  EXPECT_NE(alone.output().find("no controller follows setpoints"), std::string::npos) << alone.output();
  ChildProcess nan(setpoint_args(domain, {"nan", "--wait-s", "1"}), (dir / "nan.log").string());
  code = nan.wait_for(seconds(30));
  ASSERT_TRUE(code.has_value());
  EXPECT_EQ(*code, 2) << nan.output();
  fs::remove_all(dir);
}

std::vector<std::string> param_args(const std::string& domain, std::vector<std::string> extra) {
  std::vector<std::string> a{bin("pmlsm"), "--domain", domain, "--profiles", source("configs/dds/profiles.xml"),
                             "param"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

/// `pmlsm param ARGS` on the domain, to its end: its exit code (-1: still running after 60 s) and output.
std::pair<int, std::string> run_param(const fs::path& dir, const std::string& domain, std::vector<std::string> args,
                                      const char* log) {
  ChildProcess p(param_args(domain, std::move(args)), (dir / log).string());
  const auto code = p.wait_for(seconds(60));
  EXPECT_TRUE(code.has_value()) << p.output();
  return {code.value_or(-1), p.output()};
}

// `pmlsm param` on a running controller (lockstep, an external scenario at rest): list, get and
// set its live parameters; a change is taken at a tick boundary, logged and versioned; a value out
// of range, one that is not a number, a key the node does not have are refused with the reason
// and the old value kept (exit 2); a node that is not there is reported (exit 3).
TEST(LiveParametersDistributed, PmlsmParamListsGetsAndSetsTheControllersParameters) {
  const fs::path dir = fresh_dir("pmlsm_external", "param");
  const std::string domain = test_domain(96);
  const std::string scenario = external_scenario(dir, 600.0);
  ChildProcess controller(node_args("controller", domain, scenario), (dir / "controller.log").string());
  ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "1"}), (dir / "plant.log").string());
  ASSERT_TRUE(plant.wait_for_output("lockstep clock", seconds(30))) << plant.output();
  const auto param = [&](std::vector<std::string> args, const char* log) { return run_param(dir, domain, args, log); };
  auto [code, text] = param({"list", "controller"}, "list.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find("velocity_loop.kp_n_s_per_m = 10000\n"), std::string::npos) << text;
  EXPECT_NE(text.find("filters.compensation.slot_4.second_damping = 0\n"), std::string::npos) << text;
  EXPECT_NE(text.find("(version 0)"), std::string::npos) << text;
  std::tie(code, text) = param({"set", "controller", "velocity_loop.kp_n_s_per_m", "12000"}, "set.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find("controller: velocity_loop.kp_n_s_per_m 10000 -> 12000 from tick "), std::string::npos) << text;
  EXPECT_NE(text.find("(version 1)"), std::string::npos) << text;
  std::tie(code, text) = param({"get", "controller", "velocity_loop.kp_n_s_per_m"}, "get.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_EQ(text, "12000\n");
  std::tie(code, text) = param({"set", "controller", "velocity_loop.kp_n_s_per_m", "2e6"}, "range.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("refused: velocity_loop.kp_n_s_per_m: must be in [0, 1000000]"), std::string::npos) << text;
  EXPECT_NE(text.find("stays 12000"), std::string::npos) << text;
  std::tie(code, text) = param({"set", "controller", "velocity_loop.ki_n_per_m", "much"}, "type.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("expected a number, got 'much'"), std::string::npos) << text;
  std::tie(code, text) = param({"set", "controller", "plant.mechanics.load_mass_kg", "5"}, "key.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("not a live parameter of this node"), std::string::npos) << text;
  std::tie(code, text) = param({"get", "estimator", "velocity_loop.kp_n_s_per_m", "--timeout-s", "1"}, "none.log");
  EXPECT_EQ(code, 3) << text;
  EXPECT_NE(text.find("node 'estimator' did not answer"), std::string::npos) << text;
  EXPECT_NE(controller.output().find("controller: tick "), std::string::npos) << controller.output();
  EXPECT_NE(controller.output().find("parameter velocity_loop.kp_n_s_per_m 10000 -> 12000 (version 1, by "),
            std::string::npos)
      << controller.output();
  for (ChildProcess* p : {&plant, &controller}) {
    p->signal(SIGINT);
    EXPECT_TRUE(p->wait_for(seconds(30)).has_value()) << p->output();
  }
  fs::remove_all(dir);
}

// `pmlsm param` on a running compensator (acceleration feedback in the lockstep chain, an external
// scenario at rest): its gain K_a listed, set at a tick boundary, logged and versioned; a value
// out of range and a key of another node's refused with the old value kept.
TEST(LiveParametersDistributed, PmlsmParamSetsACompensatorsGainAtATickBoundary) {
  const fs::path dir = fresh_dir("pmlsm_external", "param_compensator");
  const std::string domain = test_domain(99);
  const std::string scenario = external_scenario(dir, 600.0);
  ChildProcess estimator(node_args("kalman_estimator", domain, scenario), (dir / "estimator.log").string());
  ChildProcess compensator(node_args("accel_feedback", domain, scenario), (dir / "compensator.log").string());
  ChildProcess controller(node_args("controller", domain, scenario, {"--compensation", "topic"}),
                          (dir / "controller.log").string());
  ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "2"}), (dir / "plant.log").string());
  ASSERT_TRUE(plant.wait_for_output("lockstep clock", seconds(30))) << plant.output();
  const auto param = [&](std::vector<std::string> args, const char* log) { return run_param(dir, domain, args, log); };
  const std::string key = "compensator.acceleration_feedback.gain_kg";
  auto [code, text] = param({"list", "accel_feedback"}, "list.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find(key + " = 160\n"), std::string::npos) << text;
  std::tie(code, text) = param({"set", "accel_feedback", key, "120"}, "set.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find("accel_feedback: " + key + " 160 -> 120 from tick "), std::string::npos) << text;
  std::tie(code, text) = param({"get", "accel_feedback", key}, "get.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_EQ(text, "120\n");
  std::tie(code, text) = param({"set", "accel_feedback", key, "-5"}, "range.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("stays 120"), std::string::npos) << text;
  std::tie(code, text) =
      param({"set", "accel_feedback", "compensator.state_feedback.model_damping_ratio", "2"}, "key.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("not a live parameter of this node"), std::string::npos) << text;
  for (ChildProcess* p : {&plant, &controller, &compensator, &estimator}) {
    p->signal(SIGINT);
    EXPECT_TRUE(p->wait_for(seconds(30)).has_value()) << p->output();
  }
  EXPECT_NE(compensator.output().find("parameter " + key + " 160 -> 120 (version 1, by "), std::string::npos)
      << compensator.output();
  EXPECT_NE(compensator.output().find("K_a 120.0 kg"), std::string::npos) << compensator.output();
  fs::remove_all(dir);
}

// `pmlsm param` on the RNN compensator learning online in the lockstep chain: its online rule's
// learning rate set at a tick boundary, logged and versioned; a clamp that would stop the
// momentum term contracting (alpha k_c >= 1) refused with the old value kept.
TEST(LiveParametersDistributed, PmlsmParamSetsTheRnnsOnlineRule) {
  const fs::path dir = fresh_dir("pmlsm_external", "param_rnn");
  const std::string domain = test_domain(101);
  const std::string scenario = external_scenario(dir, 600.0);
  ChildProcess estimator(node_args("kalman_estimator", domain, scenario), (dir / "estimator.log").string());
  ChildProcess compensator(node_args("rnn_compensator", domain, scenario,
                                     {"--weights", source("configs/rnn_weights.yaml"), "--online-learning"}),
                           (dir / "compensator.log").string());
  ChildProcess controller(node_args("controller", domain, scenario, {"--compensation", "topic"}),
                          (dir / "controller.log").string());
  ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "2"}), (dir / "plant.log").string());
  ASSERT_TRUE(plant.wait_for_output("lockstep clock", seconds(30))) << plant.output();
  const auto param = [&](std::vector<std::string> args, const char* log) { return run_param(dir, domain, args, log); };
  const std::string key = "compensator.rnn.learning_rate";
  auto [code, text] = param({"list", "rnn_compensator"}, "list.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find(key + " = 0.001\n"), std::string::npos) << text;
  EXPECT_NE(text.find("compensator.rnn.du_deadband_per_s = 1\n"), std::string::npos) << text;
  std::tie(code, text) = param({"set", "rnn_compensator", key, "0.0005"}, "set.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find("rnn_compensator: " + key + " 0.001 -> 0.0005 from tick "), std::string::npos) << text;
  std::tie(code, text) = param({"set", "rnn_compensator", "compensator.rnn.kc_limit_mps", "2"}, "clamp.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("momentum * kc_limit_mps must be < 1"), std::string::npos) << text;
  EXPECT_NE(text.find("stays 1"), std::string::npos) << text;
  for (ChildProcess* p : {&plant, &controller, &compensator, &estimator}) {
    p->signal(SIGINT);
    EXPECT_TRUE(p->wait_for(seconds(30)).has_value()) << p->output();
  }
  EXPECT_NE(compensator.output().find("parameter " + key + " 0.001 -> 0.0005 (version 1, by "), std::string::npos)
      << compensator.output();
  fs::remove_all(dir);
}

// The tuner's result applied live: `pmlsm commission --design-filters --tune` writes a notch and
// tuned gains; `pmlsm param load` puts every live parameter that differs into the running
// controller in one request, taken at one tick boundary (the notch's kind with its values, which
// one change at a time would refuse). A dry run changes nothing; a second load finds nothing to
// change; a file that does not load is refused before anything is sent.
TEST(LiveParametersDistributed, PmlsmParamLoadsACommissionedFileIntoTheRunningController) {
  const fs::path dir = fresh_dir("pmlsm_external", "param_load");
  const std::string domain = test_domain(100);
  const std::string commissioned = (dir / "commissioned.yaml").string();
  ChildProcess commission(
      {bin("pmlsm"), "commission", "--simulate", "--no-plots", "-c", source("configs/system.yaml"), "--identification",
       source("configs/scenarios/identification.yaml"), "--set", "plant.encoder.mount_frequency_hz=250",
       "--design-filters", "--tune", "--no-verify", "-o", commissioned, "--report", (dir / "report").string()},
      (dir / "commission.log").string());
  const auto commissioned_code = commission.wait_for(seconds(120));
  ASSERT_TRUE(commissioned_code.has_value()) << commission.output();
  ASSERT_EQ(*commissioned_code, 0) << commission.output();
  EXPECT_NE(commission.output().find("pmlsm param load controller " + commissioned), std::string::npos)
      << commission.output();

  const std::string scenario = external_scenario(dir, 600.0);
  ChildProcess controller(node_args("controller", domain, scenario), (dir / "controller.log").string());
  ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "1"}), (dir / "plant.log").string());
  ASSERT_TRUE(plant.wait_for_output("lockstep clock", seconds(30))) << plant.output();
  const auto param = [&](std::vector<std::string> args, const char* log) { return run_param(dir, domain, args, log); };
  auto [code, text] = param({"load", "controller", commissioned, "--dry-run"}, "dry.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find("controller: filters.force_command.slot_1.kind none -> notch (not sent: --dry-run)"),
            std::string::npos)
      << text;
  std::tie(code, text) = param({"get", "controller", "filters.force_command.slot_1.kind"}, "before.log");
  EXPECT_EQ(text, "none\n");
  std::tie(code, text) = param({"load", "controller", commissioned}, "load.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find("controller: filters.force_command.slot_1.kind: none -> notch\n"), std::string::npos) << text;
  EXPECT_NE(text.find("controller: velocity_loop.kp_n_s_per_m: 10000 -> "), std::string::npos) << text;
  EXPECT_NE(text.find("controller: 6 parameters from " + commissioned + " from tick "), std::string::npos) << text;
  EXPECT_NE(text.find("(version 6)"), std::string::npos) << text;
  std::tie(code, text) = param({"get", "controller", "filters.force_command.slot_1.kind"}, "after.log");
  EXPECT_EQ(text, "notch\n");
  std::tie(code, text) = param({"load", "controller", commissioned}, "again.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find("are already as in"), std::string::npos) << text;
  const std::string broken = (dir / "broken.yaml").string();
  {
    std::ifstream in(commissioned);
    std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto at = yaml.find("force_limit_n: {value: ");
    ASSERT_NE(at, std::string::npos);
    yaml.replace(at, 23, "force_limit_n: {value: -");
    std::ofstream(broken) << yaml;
  }
  std::tie(code, text) = param({"load", "controller", broken}, "broken.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("force_limit_n"), std::string::npos) << text;
  EXPECT_NE(text.find("(nothing sent)"), std::string::npos) << text;
  for (ChildProcess* p : {&plant, &controller}) {
    p->signal(SIGINT);
    EXPECT_TRUE(p->wait_for(seconds(30)).has_value()) << p->output();
  }
  EXPECT_NE(controller.output().find("parameter filters.force_command.slot_1.kind none -> notch (version 3, by "),
            std::string::npos)
      << controller.output();
  EXPECT_NE(controller.output().find("together with 6)"), std::string::npos) << controller.output();
  fs::remove_all(dir);
}

/// The tick a `pmlsm param set` answer says a change acts from ("... from tick N (version V)"):
/// tick 0 too, when the request came before the first.
std::optional<std::uint64_t> from_tick(const std::string& text) {
  std::smatch m;
  if (!std::regex_search(text, m, std::regex("from tick ([0-9]+)"))) return std::nullopt;
  return std::stoull(m[1].str());
}

/// Estimator, state feedback, controller and plant in lockstep on an external scenario at rest,
/// as separate processes or composed in one container: the controller's Kp set live reaches state
/// feedback's model of the loop at the tick the controller takes it; a Kp that the model refuses
/// (it needs one above 0) is refused by the controller naming both, the old value kept.
void expect_kp_followed_at_the_same_tick(bool composed, const std::string& domain) {
  const fs::path dir = fresh_dir("pmlsm_external", composed ? "follow_composed" : "follow_separate");
  const std::string scenario = external_scenario(dir, 600.0);
  const std::vector<std::string> plant_extra{"--peers", "2"};
  const std::vector<std::string> controller_extra{"--compensation", "topic"};
  std::vector<std::unique_ptr<ChildProcess>> processes;
  if (composed) {
    processes.push_back(std::make_unique<ChildProcess>(
        container_args("chain", {component_args("kalman_estimator", "kalman_estimator", domain, scenario),
                                 component_args("state_feedback", "state_feedback", domain, scenario),
                                 component_args("controller", "controller", domain, scenario, controller_extra),
                                 component_args("plant_sim", "plant_sim", domain, scenario, plant_extra)}),
        (dir / "chain.log").string()));
  } else {
    processes.push_back(std::make_unique<ChildProcess>(node_args("kalman_estimator", domain, scenario),
                                                       (dir / "estimator.log").string()));
    processes.push_back(std::make_unique<ChildProcess>(node_args("state_feedback", domain, scenario),
                                                       (dir / "state_feedback.log").string()));
    processes.push_back(std::make_unique<ChildProcess>(node_args("controller", domain, scenario, controller_extra),
                                                       (dir / "controller.log").string()));
    processes.push_back(std::make_unique<ChildProcess>(node_args("plant_sim", domain, scenario, plant_extra),
                                                       (dir / "plant.log").string()));
  }
  ChildProcess& plant = *processes.back();
  ASSERT_TRUE(plant.wait_for_output("lockstep clock", seconds(30))) << plant.output();
  auto [code, text] = run_param(dir, domain, {"set", "controller", "velocity_loop.kp_n_s_per_m", "12000"}, "set.log");
  EXPECT_EQ(code, 0) << text;
  const std::optional<std::uint64_t> tick = from_tick(text);
  ASSERT_TRUE(tick.has_value()) << text;
  std::tie(code, text) = run_param(dir, domain, {"set", "controller", "velocity_loop.kp_n_s_per_m", "0"}, "zero.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("velocity_loop.kp_n_s_per_m = 0 refused by a value derived from it: "
                      "compensator.state_feedback.velocity_gain_n_s_per_m"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("stays 12000"), std::string::npos) << text;
  // A file loaded whole (SET_MANY: one request, its changes listed together) is followed too.
  const std::string system = read_file(source("configs/system.yaml"));
  const std::string loaded =
      std::regex_replace(system, std::regex("kp_n_s_per_m: \\{value: 10000.0"), "kp_n_s_per_m: {value: 13000.0");
  ASSERT_NE(loaded, system);
  std::ofstream(dir / "loaded.yaml") << loaded;
  std::tie(code, text) = run_param(dir, domain, {"load", "controller", (dir / "loaded.yaml").string()}, "load.log");
  EXPECT_EQ(code, 0) << text;
  const std::optional<std::uint64_t> load_tick = from_tick(text);
  ASSERT_TRUE(load_tick.has_value()) << text;
  std::string out;
  for (auto& p : processes) {
    p->signal(SIGINT);
    EXPECT_TRUE(p->wait_for(seconds(30)).has_value()) << p->output();
    out += p->output();
  }
  const std::string at = "tick " + std::to_string(*tick) + ": ";
  EXPECT_NE(out.find("controller: " + at + "parameter velocity_loop.kp_n_s_per_m 10000 -> 12000 (version 1"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("state_feedback: " + at +
                     "follows controller's parameter velocity_loop.kp_n_s_per_m 10000 -> 12000 (version 1)\n"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("state_feedback: tick " + std::to_string(*load_tick) +
                     ": follows controller's parameter velocity_loop.kp_n_s_per_m 12000 -> 13000 (version 2)\n"),
            std::string::npos)
      << out;
  EXPECT_EQ(out.find("not followed"), std::string::npos) << out;
  EXPECT_EQ(out.find("parameters not taken"), std::string::npos) << out;
  fs::remove_all(dir);
}

TEST(LiveParametersDistributed, AKpChangeReachesStateFeedbacksModelAtTheControllersTick) {
  expect_kp_followed_at_the_same_tick(false, test_domain(109));
}

TEST(LiveParametersDistributed, AKpChangeReachesStateFeedbacksModelAtTheControllersTickComposed) {
  expect_kp_followed_at_the_same_tick(true, test_domain(110));
}

}  // namespace
}  // namespace pmlsm::test

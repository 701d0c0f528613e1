// The control loop as separate processes on real DDS (loopback, shared memory).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "child_process.hpp"
#include "integration_support.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/config/config.hpp"
#include "trace_csv.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;

using test::bin;
using test::node_args;
using test::read_file;
using test::source;
using test::test_domain;

// Runs evaluator, estimator, controller and plant in lockstep and compares the
// evaluator's trace with the in-process loop's, byte for byte.
void expect_trace_equals_in_process(const std::string& name, const std::string& command_level) {
  const std::string scenario = source("configs/scenarios/" + name + ".yaml");
  const fs::path dir =
      fs::temp_directory_path() / ("pmlsm_dist_" + std::to_string(getpid()) + "_" + name + "_" + command_level);
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string domain = test_domain((name == "pulse" ? 0 : 1) + (command_level == "force" ? 0 : 2));

  test::ChildProcess evaluator(node_args("evaluator", domain, scenario, {"--out", dir.string()}),
                               (dir / "evaluator.log").string());
  test::ChildProcess estimator(node_args("kalman_estimator", domain, scenario), (dir / "estimator.log").string());
  test::ChildProcess controller(node_args("controller", domain, scenario, {"--command-level", command_level}),
                                (dir / "controller.log").string());
  test::ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "3", "--command-level", command_level}),
                           (dir / "plant.log").string());

  for (auto* p : {&plant, &controller, &estimator, &evaluator}) {
    const auto code = p->wait_for(std::chrono::seconds(60));
    ASSERT_TRUE(code.has_value()) << "still running:\n" << p->output();
    EXPECT_EQ(*code, 0) << p->output();
  }

  const SystemParams params = load_system_params(source("configs/system.yaml"));
  const Scenario sc = load_scenario(scenario, params.timing.control_period_s);
  write_trace_csv((dir / "in_process.csv").string(), run_scenario(params, sc));
  const std::string distributed = read_file(dir / (name + ".csv"));
  ASSERT_FALSE(distributed.empty()) << evaluator.output();
  EXPECT_TRUE(distributed == read_file(dir / "in_process.csv"))
      << "the distributed trace differs from the in-process one (" << dir << ")";
  EXPECT_NE(plant.output().find("late 0, rejected 0"), std::string::npos) << plant.output();
  fs::remove_all(dir);
}

class DistributedLockstep : public ::testing::TestWithParam<const char*> {};

TEST_P(DistributedLockstep, TraceEqualsTheInProcessLoop) { expect_trace_equals_in_process(GetParam(), "force"); }

INSTANTIATE_TEST_SUITE_P(Scenarios, DistributedLockstep, ::testing::Values("pulse", "free_vibration"));

// The voltage command level: the controller runs the current loop and
// exchanges CurrentFeedback / VoltageCommand with the plant 32 times a tick.
TEST(DistributedLockstepVoltage, TraceEqualsTheInProcessLoop) { expect_trace_equals_in_process("pulse", "voltage"); }

TEST(DistributedLockstepVoltage, RealtimeIsRejectedAsABadOption) {
  const fs::path log = fs::temp_directory_path() / ("pmlsm_voltage_rt_" + std::to_string(getpid()));
  test::ChildProcess p(node_args("plant_sim", "0", source("configs/scenarios/pulse.yaml"),
                                 {"--command-level", "voltage", "--clock", "realtime"}),
                       log.string());
  const auto code = p.wait_for(std::chrono::seconds(30));
  ASSERT_TRUE(code.has_value());
  EXPECT_EQ(*code, 2) << p.output();
  EXPECT_NE(p.output().find("lockstep only"), std::string::npos) << p.output();
  fs::remove(log);
}

TEST(DistributedFailures, LockstepPlantReportsALostControllerAndStops) {
  const std::string scenario = source("configs/scenarios/free_vibration.yaml");
  const fs::path dir = fs::temp_directory_path() / ("pmlsm_lost_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string domain = test_domain(4);
  test::ChildProcess controller(node_args("controller", domain, scenario), (dir / "controller.log").string());
  test::ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "1", "--peer-timeout-s", "1"}),
                           (dir / "plant.log").string());
  ASSERT_TRUE(plant.wait_for_output("lockstep clock", std::chrono::seconds(30))) << plant.output();
  controller.signal(SIGKILL);
  const auto code = plant.wait_for(std::chrono::seconds(30));
  ASSERT_TRUE(code.has_value());
  EXPECT_EQ(*code, 4) << plant.output();  // kPeerLost
  EXPECT_NE(plant.output().find("controller lost; safe state"), std::string::npos) << plant.output();
  fs::remove_all(dir);
}

TEST(DistributedFailures, RealtimeWatchdogFaultsTheDriveAndTheLostControllerEndsTheRun) {
  const std::string scenario = source("configs/scenarios/pulse.yaml");
  const fs::path dir = fs::temp_directory_path() / ("pmlsm_watchdog_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string domain = test_domain(5);
  test::ChildProcess controller(node_args("controller", domain, scenario, {"--clock", "realtime"}),
                                (dir / "controller.log").string());
  test::ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "1", "--clock", "realtime"}),
                           (dir / "plant.log").string());
  ASSERT_TRUE(plant.wait_for_output("watchdog armed", std::chrono::seconds(30))) << plant.output();
  controller.signal(SIGKILL);
  const auto code = plant.wait_for(std::chrono::seconds(30));
  ASSERT_TRUE(code.has_value());
  // The watchdog faults the drive (zero force at once); 50 ms later the controller is lost and
  // the simulation ends with code 4 instead of idling to the end of the scenario.
  EXPECT_EQ(*code, 4) << plant.output();
  const std::string out = plant.output();
  EXPECT_NE(out.find("unanswered for 3.0 ms"), std::string::npos) << out;
  EXPECT_NE(out.find("fault 0x8130, zero force"), std::string::npos) << out;
  EXPECT_NE(out.find("controller lost"), std::string::npos) << out;
  fs::remove_all(dir);
}

TEST(DistributedFailures, NodesRejectABadConfigWithExitCode2) {
  for (const char* exe : {"plant_sim", "controller", "kalman_estimator", "evaluator"}) {
    const fs::path log = fs::temp_directory_path() / ("pmlsm_badcfg_" + std::to_string(getpid()) + exe);
    test::ChildProcess p(
        node_args(exe, "0", source("configs/scenarios/pulse.yaml"), {"--set", "plant.mechanics.load_mass_kg=-4"}),
        log.string());
    const auto code = p.wait_for(std::chrono::seconds(30));
    ASSERT_TRUE(code.has_value()) << exe;
    EXPECT_EQ(*code, 2) << exe << ": " << p.output();
    EXPECT_NE(p.output().find("plant.mechanics.load_mass_kg"), std::string::npos) << p.output();
    fs::remove(log);
  }
}

TEST(DiscoveryServer, NodesFindEachOtherThroughTheServerAndNotWithoutIt) {
  // The pmlsm_discovery_client profile has no multicast discovery: the nodes
  // meet only through the server (Debian fastdds-tools).
  const std::string server_exe = "/usr/bin/fastdds";
  if (!fs::exists(server_exe)) GTEST_SKIP() << "fastdds-tools is not installed; not run";
  const std::string scenario = source("configs/scenarios/pulse.yaml");
  const fs::path dir = fs::temp_directory_path() / ("pmlsm_ds_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string domain = test_domain(6);
  const std::vector<std::string> client{"--participant-profile", "pmlsm_discovery_client", "--peer-timeout-s", "3"};
  auto with = [](std::vector<std::string> a, const std::vector<std::string>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
  };
  {
    // No server: the plant never finds its controller.
    test::ChildProcess controller(node_args("controller", domain, scenario, client), (dir / "c0.log").string());
    test::ChildProcess plant(node_args("plant_sim", domain, scenario, with(client, {"--peers", "1"})),
                             (dir / "p0.log").string());
    const auto code = plant.wait_for(std::chrono::seconds(30));
    ASSERT_TRUE(code.has_value());
    EXPECT_EQ(*code, 3) << plant.output();  // kPeerMissing
  }
  test::ChildProcess server({server_exe, "discovery", "-i", "0", "-l", "127.0.0.1", "-p", "11811"},
                            (dir / "server.log").string());
  ASSERT_TRUE(server.wait_for_output("Server is running", std::chrono::seconds(10))) << server.output();
  test::ChildProcess controller(node_args("controller", domain, scenario, client), (dir / "c1.log").string());
  test::ChildProcess plant(node_args("plant_sim", domain, scenario, with(client, {"--peers", "1"})),
                           (dir / "p1.log").string());
  for (auto* p : {&plant, &controller}) {
    const auto code = p->wait_for(std::chrono::seconds(60));
    ASSERT_TRUE(code.has_value()) << p->output();
    EXPECT_EQ(*code, 0) << p->output();
  }
  EXPECT_NE(plant.output().find("2000 ticks in"), std::string::npos) << plant.output();
  server.signal(SIGINT);
  server.wait_for(std::chrono::seconds(10));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace pmlsm

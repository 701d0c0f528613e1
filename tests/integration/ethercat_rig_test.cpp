// The EtherCAT rig: drive_bridge --bus ethercat (our master) and virtual_drive --bus ethercat (the
// simulated drive behind a virtual EtherCAT slave) exchanging EtherCAT over UDP on loopback, with
// the rest of the system on DDS. Each test has its own DDS domain (offsets 113..117) and UDP port
// (62xx: below DDS's port base and the ephemeral range).
#include <gtest/gtest.h>

#include <cmath>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "integration_support.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;

using test::bin;
using test::node_args;
using test::source;
using test::test_domain;

/// The true and estimated costs of the evaluator's row for `scenario` in a launcher's output.
std::optional<std::pair<double, double>> costs_of(const std::string& output, const std::string& scenario) {
  std::istringstream lines(output);
  for (std::string line; std::getline(lines, line);) {
    const std::string prefix = "[evaluator] " + scenario + " ";
    if (line.rfind(prefix, 0) != 0) continue;
    std::istringstream in(line.substr(prefix.size()));
    std::string label;
    double cost_true = NAN;
    double cost_est = NAN;
    if (in >> label >> cost_true >> cost_est) return std::make_pair(cost_true, cost_est);
  }
  return std::nullopt;
}

std::vector<std::string> rig_args(const std::string& launch, const std::string& domain, const std::string& scenario,
                                  const fs::path& out, std::vector<std::string> extra) {
  std::vector<std::string> a{bin("launcher"), source(launch),
                             "--arg",         "config=" + source("configs/system.yaml"),
                             "--arg",         "scenario=" + scenario,
                             "--arg",         "profiles=" + source("configs/dds/profiles.xml"),
                             "--arg",         "domain=" + domain,
                             "--arg",         "compensator=rnn",
                             "--arg",         "weights=" + source("configs/rnn_weights.yaml"),
                             "--arg",         "dictionary=" + source("configs/canopen/virtual_drive_od.yaml"),
                             "--arg",         "canopen_config=" + source("configs/canopen/drive.yaml"),
                             "--arg",         "out=" + out.string()};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

// The lockstep target: the EtherCAT rig's run is the CANopen rig's (the same quantisation
// of the simulated drive: per mille of the rated force, 1 um), so their costs agree.
TEST(EthercatRig, TheLockstepRunOverEthercatCostsWhatTheCanopenRigsDoes) {
  const fs::path dir = test::fresh_dir("pmlsm_ethercat_rig", "lockstep");
  const std::string scenario = source("configs/scenarios/free_vibration.yaml");
  test::ChildProcess ethercat(
      rig_args("launch/virtual_rig_ethercat.yaml", test_domain(113), scenario, dir / "ethercat",
               {"--arg", "ethercat_config=" + source("configs/ethercat/drive.yaml"), "--arg", "ethercat_port=6281"}),
      (dir / "ethercat.log").string());
  ASSERT_EQ(ethercat.wait_for(std::chrono::seconds(150)), std::optional<int>(0)) << ethercat.output();
  test::ChildProcess canopen(rig_args("launch/virtual_rig.yaml", test_domain(114), scenario, dir / "canopen",
                                      {"--arg", "can_group=239.74.171.21", "--arg", "can_port=6282"}),
                             (dir / "canopen.log").string());
  ASSERT_EQ(canopen.wait_for(std::chrono::seconds(150)), std::optional<int>(0)) << canopen.output();
  EXPECT_NE(ethercat.output().find("in OP on EtherCAT over UDP"), std::string::npos) << ethercat.output();
  EXPECT_NE(ethercat.output().find("all 6 nodes ended cleanly"), std::string::npos) << ethercat.output();
  EXPECT_NE(ethercat.output().find("0 working counter errors"), std::string::npos) << ethercat.output();
  const auto over_ethercat = costs_of(ethercat.output(), "free_vibration");
  const auto over_canopen = costs_of(canopen.output(), "free_vibration");
  ASSERT_TRUE(over_ethercat.has_value()) << ethercat.output();
  ASSERT_TRUE(over_canopen.has_value()) << canopen.output();
  EXPECT_NEAR(over_ethercat->first, over_canopen->first, 1e-3 * over_canopen->first)
      << "EtherCAT:\n"
      << ethercat.output() << "\nCANopen:\n"
      << canopen.output();
  EXPECT_NEAR(over_ethercat->second, over_canopen->second, 1e-3 * over_canopen->second);
  fs::remove_all(dir);
}

std::vector<std::string> ethercat_drive_args(const std::string& port) {
  return {"--bus",
          "ethercat",
          "--ethercat-config",
          source("configs/ethercat/drive.yaml"),
          "--ethercat-udp-port",
          port,
          "--dictionary",
          source("configs/canopen/virtual_drive_od.yaml")};
}
std::vector<std::string> ethercat_bridge_args(const std::string& port) {
  return {"--bus",          "ethercat",          "--ethercat-config", source("configs/ethercat/drive.yaml"),
          "--ethercat-udp", "127.0.0.1:" + port, "--peers",           "1"};
}

TEST(EthercatRig, ADeadDriveFaultsTheBridgeInsteadOfHangingIt) {
  const fs::path dir = test::fresh_dir("pmlsm_ethercat_rig", "dead_drive");
  const std::string scenario = source("configs/scenarios/free_vibration.yaml");
  const std::string domain = test_domain(115);
  test::ChildProcess drive(node_args("virtual_drive", domain, scenario, ethercat_drive_args("6283")),
                           (dir / "virtual_drive.log").string());
  test::ChildProcess controller(node_args("controller", domain, scenario), (dir / "controller.log").string());
  test::ChildProcess bridge(node_args("drive_bridge", domain, scenario, ethercat_bridge_args("6283")),
                            (dir / "bridge.log").string());
  ASSERT_TRUE(bridge.wait_for_output("operation enabled", std::chrono::seconds(30))) << bridge.output();
  drive.signal(SIGKILL);
  const auto code = bridge.wait_for(std::chrono::seconds(60));
  ASSERT_TRUE(code.has_value()) << "the bridge hung on a dead drive:\n" << bridge.output();
  EXPECT_EQ(*code, 5) << bridge.output();
  EXPECT_NE(bridge.output().find("0x8130"), std::string::npos) << bridge.output();
  EXPECT_NE(bridge.output().find("the slave does not answer"), std::string::npos) << bridge.output();
  controller.signal(SIGINT);
  controller.wait_for(std::chrono::seconds(30));
  fs::remove_all(dir);
}

TEST(EthercatRig, TheDrivesOwnFaultReachesTheBridgeWithItsCodeAndNeitherEndsOk) {
  const fs::path dir = test::fresh_dir("pmlsm_ethercat_rig", "drive_fault");
  const std::string scenario = source("configs/scenarios/pulse.yaml");
  const std::string domain = test_domain(116);
  std::vector<std::string> drive_args = ethercat_drive_args("6284");
  drive_args.insert(drive_args.end(), {"--inject-fault-at-tick", "500"});
  test::ChildProcess drive(node_args("virtual_drive", domain, scenario, drive_args),
                           (dir / "virtual_drive.log").string());
  test::ChildProcess controller(node_args("controller", domain, scenario), (dir / "controller.log").string());
  test::ChildProcess bridge(node_args("drive_bridge", domain, scenario, ethercat_bridge_args("6284")),
                            (dir / "bridge.log").string());
  const auto code = bridge.wait_for(std::chrono::seconds(60));
  ASSERT_TRUE(code.has_value()) << bridge.output();
  EXPECT_EQ(*code, 5) << bridge.output();
  EXPECT_NE(bridge.output().find("0x603F = 0x5000"), std::string::npos) << bridge.output();
  const auto drive_code = drive.wait_for(std::chrono::seconds(30));
  ASSERT_TRUE(drive_code.has_value()) << drive.output();
  EXPECT_EQ(*drive_code, 5) << drive.output();
  controller.signal(SIGINT);
  controller.wait_for(std::chrono::seconds(30));
  fs::remove_all(dir);
}

TEST(EthercatRig, ARunTheMasterEndsEarlyIsNoCleanRunForTheDriveEither) {
  const fs::path dir = test::fresh_dir("pmlsm_ethercat_rig", "early_end");
  const std::string scenario = source("configs/scenarios/free_vibration.yaml");
  const std::string domain = test_domain(117);
  test::ChildProcess drive(node_args("virtual_drive", domain, scenario, ethercat_drive_args("6285")),
                           (dir / "virtual_drive.log").string());
  test::ChildProcess controller(node_args("controller", domain, scenario), (dir / "controller.log").string());
  std::vector<std::string> bridge_args = ethercat_bridge_args("6285");
  bridge_args.insert(bridge_args.end(), {"--peer-timeout-s", "1"});
  test::ChildProcess bridge(node_args("drive_bridge", domain, scenario, bridge_args), (dir / "bridge.log").string());
  ASSERT_TRUE(bridge.wait_for_output("operation enabled", std::chrono::seconds(30))) << bridge.output();
  controller.signal(SIGKILL);  // the bridge ends the run without its controller, and releases the drive
  const auto code = bridge.wait_for(std::chrono::seconds(60));
  ASSERT_TRUE(code.has_value()) << bridge.output();
  EXPECT_NE(*code, 0) << bridge.output();
  const auto drive_code = drive.wait_for(std::chrono::seconds(30));
  ASSERT_TRUE(drive_code.has_value()) << drive.output();
  EXPECT_EQ(*drive_code, 4) << drive.output() << bridge.output();
  EXPECT_NE(drive.output().find("took the drive out of OP after"), std::string::npos) << bridge.output();
  controller.wait_for(std::chrono::seconds(10));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace pmlsm

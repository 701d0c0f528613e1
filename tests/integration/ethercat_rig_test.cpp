// The EtherCAT rig: drive_bridge --bus ethercat (our master) and virtual_drive --bus ethercat (the
// simulated drive behind a virtual EtherCAT slave) exchanging EtherCAT over UDP on loopback, with
// the rest of the system on DDS. Each test has its own DDS domain (offsets 113..119, 66, 67) and
// UDP port (62xx: below DDS's port base and the ephemeral range).
#include <gtest/gtest.h>

#include <cmath>
#include <csignal>
#include <cstdio>
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

/// The run's capture (the bridge's --ethercat-capture), as many frames as the bridge says, read by
/// our decoder and, where it is installed, by tshark: every frame EtherCAT, none malformed, and
/// every cyclic datagram (LWR outputs, LRD inputs) with the working counter the master expected of
/// its one slave, 1.
void expect_capture_of_the_run(const std::string& log, const std::string& capture, const fs::path& dir) {
  const std::string said = "EtherCAT capture: ";
  const std::size_t at = log.find(said);
  ASSERT_NE(at, std::string::npos) << log;
  const long long frames = std::stoll(log.substr(at + said.size()));
  EXPECT_GT(frames, 6 * 8000) << "the run's 8000 ticks: inputs, outputs and the clock's time, each there and back";
  test::ChildProcess pcap({bin("pmlsm"), "ethercat", "pcap", capture}, (dir / "pcap.log").string());
  ASSERT_EQ(pcap.wait_for(std::chrono::seconds(60)), std::optional<int>(0)) << pcap.output();
  EXPECT_NE(pcap.output().find(std::to_string(frames) + " frames: " + std::to_string(frames) + " EtherCAT"),
            std::string::npos)
      << pcap.output();
  EXPECT_NE(pcap.output().find("; 0 malformed"), std::string::npos) << pcap.output();
  if (std::system("tshark --version >/dev/null 2>&1") != 0) {
    std::printf("tshark is not installed: the capture is not read by it here\n");
    return;
  }
  const auto count = [&](const std::string& filter) {
    const std::string command = "tshark -n -r '" + capture + "' -Y '" + filter + "' 2>/dev/null | wc -l";
    FILE* pipe = ::popen(command.c_str(), "r");
    long long n = -1;
    if (pipe != nullptr) {
      if (std::fscanf(pipe, "%lld", &n) != 1) n = -1;
      ::pclose(pipe);
    }
    return n;
  };
  EXPECT_EQ(count("ecatf"), frames);
  EXPECT_EQ(count("_ws.malformed || _ws.expert.severity >= warning"), 0);
  // The way back of every cyclic datagram: counted once by the slave. Out, they carry 0.
  const long long cyclic_back = count("(ecat.cmd == 0x0a || ecat.cmd == 0x0b) && ecat.cnt == 1");
  EXPECT_GT(cyclic_back, 2 * 8000);
  EXPECT_EQ(count("(ecat.cmd == 0x0a || ecat.cmd == 0x0b) && ecat.cnt > 1"), 0);
  EXPECT_EQ(count("(ecat.cmd == 0x0a || ecat.cmd == 0x0b) && ecat.cnt == 0"), cyclic_back)
      << "each datagram seen going out (0) and coming back (1)";
}

// The lockstep target: the EtherCAT rig's run is the CANopen rig's (the same quantisation
// of the simulated drive: per mille of the rated force, 1 um), so their costs agree.
TEST(EthercatRig, TheLockstepRunOverEthercatCostsWhatTheCanopenRigsDoes) {
  const fs::path dir = test::fresh_dir("pmlsm_ethercat_rig", "lockstep");
  const std::string scenario = source("configs/scenarios/free_vibration.yaml");
  const std::string capture = (dir / "rig.pcapng").string();
  test::ChildProcess ethercat(rig_args("launch/virtual_rig_ethercat.yaml", test_domain(113), scenario, dir / "ethercat",
                                       {"--arg", "ethercat_config=" + source("configs/ethercat/drive.yaml"), "--arg",
                                        "ethercat_port=6281", "--arg", "ethercat_capture=" + capture}),
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
  expect_capture_of_the_run(ethercat.output(), capture, dir);
  if (!HasFailure()) fs::remove_all(dir);
}

// The drive on SYNC0 (drive.sync0): in realtime, composed, the virtual drive steps a period at each
// pulse of its distributed clock and the run ends cleanly; a lockstep run refuses the setting (exit
// 2, named) before anything moves.
TEST(EthercatRig, TheRealtimeRigOnSync0StepsAPeriodAPulseAndALockstepOneIsRefused) {
  const fs::path dir = test::fresh_dir("pmlsm_ethercat_rig", "sync0");
  const std::string scenario = source("configs/scenarios/pulse.yaml");
  test::ChildProcess lockstep(rig_args("launch/virtual_rig_ethercat.yaml", test_domain(118), scenario, dir / "lockstep",
                                       {"--arg", "ethercat_port=6286", "--arg", "sync0=true"}),
                              (dir / "lockstep.log").string());
  ASSERT_EQ(lockstep.wait_for(std::chrono::seconds(60)), std::optional<int>(2)) << lockstep.output();
  EXPECT_NE(lockstep.output().find("drive.sync0: SYNC0 runs on the drive's clock"), std::string::npos)
      << lockstep.output();
  test::ChildProcess realtime(
      rig_args("launch/virtual_rig_ethercat.yaml", test_domain(118), scenario, dir / "realtime",
               {"--arg", "ethercat_port=6286", "--arg", "sync0=true", "--arg", "clock=realtime"}),
      (dir / "realtime.log").string());
  ASSERT_EQ(realtime.wait_for(std::chrono::seconds(90)), std::optional<int>(0)) << realtime.output();
  const std::string out = realtime.output();
  EXPECT_NE(out.find("the drive on SYNC0 (DC mode): every 1 ms, 500 us into the cycle"), std::string::npos) << out;
  EXPECT_NE(out.find("0 working counter errors"), std::string::npos) << out;
  // The scenario's 2000 ticks, the walk and the lead before them: a pulse each millisecond.
  const std::string said = "virtual_drive: SYNC0: ";
  const std::size_t at = out.find(said);
  ASSERT_NE(at, std::string::npos) << out;
  EXPECT_GE(std::stoll(out.substr(at + said.size())), 2000) << out;
  EXPECT_NE(out.find("pulses of 1.000 ms"), std::string::npos) << out;
  EXPECT_NE(out.find("0 activations with the start time past"), std::string::npos) << out;
  if (!HasFailure()) fs::remove_all(dir);
}

// drive.mode (the launch file's drive_mode): in cyclic synchronous velocity the drive's own
// velocity loop (the system's PI) follows V_ref with the compensation as its torque offset, the
// paper's structure with the PI moved into the drive, so the lockstep pulse costs what the torque
// run's does to the quantisation's difference (the torque's per mille against the velocity's
// increment per second); in cyclic synchronous position the drive's position loop follows the
// reference's motion and the run ends cleanly, its cost finite.
TEST(EthercatRig, InVelocityModeTheDrivesOwnLoopCostsWhatTheTorqueRunDoesAndPositionModeRuns) {
  const fs::path dir = test::fresh_dir("pmlsm_ethercat_rig", "modes");
  const std::string scenario = source("configs/scenarios/pulse.yaml");
  std::optional<std::pair<double, double>> costs[3];
  const char* const modes[3] = {"cst", "csv", "csp"};
  for (int i = 0; i < 3; ++i) {
    test::ChildProcess run(rig_args("launch/virtual_rig_ethercat.yaml", test_domain(119), scenario, dir / modes[i],
                                    {"--arg", "ethercat_port=6287", "--arg", std::string("drive_mode=") + modes[i]}),
                           (dir / (std::string(modes[i]) + ".log")).string());
    ASSERT_EQ(run.wait_for(std::chrono::seconds(90)), std::optional<int>(0)) << run.output();
    const std::string out = run.output();
    EXPECT_NE(out.find("all 6 nodes ended cleanly"), std::string::npos) << out;
    EXPECT_NE(out.find("0 working counter errors"), std::string::npos) << out;
    costs[i] = costs_of(out, "pulse");
    ASSERT_TRUE(costs[i].has_value()) << out;
    EXPECT_TRUE(std::isfinite(costs[i]->first) && std::isfinite(costs[i]->second)) << out;
    if (i > 0) {
      EXPECT_NE(out.find(i == 1 ? "cyclic synchronous velocity" : "cyclic synchronous position"), std::string::npos)
          << out;
      EXPECT_NE(out.find("the compensation goes in as its torque offset 0x60B2"), std::string::npos) << out;
    }
  }
  EXPECT_NEAR(costs[1]->first, costs[0]->first, 0.05 * costs[0]->first) << "csv against cst";
  EXPECT_NEAR(costs[1]->second, costs[0]->second, 0.2 * costs[0]->second) << "csv against cst, estimated";
  if (!HasFailure()) fs::remove_all(dir);
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

// A system file that declares a load encoder the drive's inputs do not carry: the bridge stops at
// the boot (exit 2), names the object to map and leaves the slave in INIT, instead of a run whose
// sensor is failed 10 ms in. With 0x60E4:1 mapped the same rig boots and names the sensor.
TEST(EthercatRig, ALoadSensorTheDrivesInputsDoNotCarryStopsTheBoot) {
  const fs::path dir = test::fresh_dir("pmlsm_ethercat_rig", "load_sensor_unmapped");
  const std::string scenario = source("configs/scenarios/pulse.yaml");
  const std::string domain = test_domain(66);
  const std::vector<std::string> encoder{"--set", "sensors.load.kind=encoder"};
  const auto with = [](std::vector<std::string> a, const std::vector<std::string>& more) {
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  const std::vector<std::string> drive_args = with(ethercat_drive_args("6296"), encoder);
  const std::vector<std::string> bridge_args = with(ethercat_bridge_args("6296"), encoder);
  {
    test::ChildProcess drive(node_args("virtual_drive", domain, scenario, drive_args),
                             (dir / "unmapped_virtual_drive.log").string());
    test::ChildProcess controller(node_args("controller", domain, scenario, encoder),
                                  (dir / "unmapped_controller.log").string());
    test::ChildProcess bridge(node_args("drive_bridge", domain, scenario, bridge_args),
                              (dir / "unmapped_bridge.log").string());
    const auto code = bridge.wait_for(std::chrono::seconds(60));
    ASSERT_TRUE(code.has_value()) << bridge.output();
    EXPECT_EQ(*code, 2) << bridge.output();
    EXPECT_NE(bridge.output().find("sensors.load.kind encoder (the system file) but the drive's inputs (0x1C13's "
                                   "TxPDOs) carry no sensor on the load"),
              std::string::npos)
        << bridge.output();
    EXPECT_NE(bridge.output().find("map 0x60E4:1 in pdo.inputs"), std::string::npos) << bridge.output();
    EXPECT_NE(bridge.output().find("the drive's slave released to INIT"), std::string::npos) << bridge.output();
    EXPECT_EQ(bridge.output().find("operation enabled"), std::string::npos) << "nothing moved:\n" << bridge.output();
  }
  {
    test::ChildProcess drive(node_args("virtual_drive", domain, scenario, drive_args),
                             (dir / "mapped_virtual_drive.log").string());
    test::ChildProcess controller(node_args("controller", domain, scenario, encoder),
                                  (dir / "mapped_controller.log").string());
    test::ChildProcess bridge(
        node_args("drive_bridge", domain, scenario,
                  with(bridge_args, {"--ethercat-set",
                                     "pdo.inputs=[\"0x6041:0:16\", \"0x6077:0:16\", \"0x6074:0:16\", "
                                     "\"0x606C:0:32\", \"0x6064:0:32\", \"0x2001:0:32\", \"0x60E4:1:32\"]"})),
        (dir / "mapped_bridge.log").string());
    EXPECT_TRUE(bridge.wait_for_output("a sensor on the load in the drive's inputs: encoder (0x60E4:1)",
                                       std::chrono::seconds(60)))
        << bridge.output();
    EXPECT_TRUE(bridge.wait_for_output("operation enabled", std::chrono::seconds(30))) << bridge.output();
    bridge.signal(SIGINT);
    EXPECT_TRUE(bridge.wait_for(std::chrono::seconds(30)).has_value()) << bridge.output();
    controller.signal(SIGINT);
    controller.wait_for(std::chrono::seconds(30));
  }
  if (!HasFailure()) fs::remove_all(dir);
}

// A dual loop over a drive in csp would be two position loops in one axis (the drive's on its
// encoder, ours on the velocity offset): the bridge refuses it before the link opens (exit 2,
// named), whichever encoder ours closes on.
TEST(EthercatRig, ThePositionLoopOverADriveInPositionModeIsRefusedBeforeTheBoot) {
  const fs::path dir = test::fresh_dir("pmlsm_ethercat_rig", "csp_dual_loop");
  const std::string scenario = source("configs/scenarios/pulse.yaml");
  std::vector<std::string> args = ethercat_bridge_args("6297");
  for (const char* a : {"--ethercat-set", "drive.mode=csp", "--set", "position_loop.closes_on=motor"})
    args.emplace_back(a);
  test::ChildProcess bridge(node_args("drive_bridge", test_domain(67), scenario, args), (dir / "bridge.log").string());
  ASSERT_EQ(bridge.wait_for(std::chrono::seconds(60)), std::optional<int>(2)) << bridge.output();
  EXPECT_NE(bridge.output().find("position_loop.closes_on motor (the system file) with drive.mode csp"),
            std::string::npos)
      << bridge.output();
  EXPECT_EQ(bridge.output().find("in OP"), std::string::npos) << "nothing booted:\n" << bridge.output();
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace pmlsm

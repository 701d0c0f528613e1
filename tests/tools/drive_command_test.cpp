// `pmlsm drive` against a real drive node: plant_sim with --auto-enable false (it starts in
// switch on disabled and waits for an operator) and a controller, both realtime, on a domain of
// their own. The tool reads the state, is refused where CiA 402 refuses, walks the drive to
// operation enabled, quick-stops it, and never resets a fault by itself; with no drive it gives
// up at its timeout; bad subcommands are exit code 2.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>

#include "child_process.hpp"
#include "integration_support.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;
using test::bin;
using test::node_args;
using test::source;
using test::test_domain;

constexpr auto kToolTimeout = std::chrono::seconds(30);
constexpr auto kStartTimeout = std::chrono::seconds(30);

std::vector<std::string> pmlsm_args(const std::string& domain, std::vector<std::string> args) {
  std::vector<std::string> a{bin("pmlsm"), "--domain", domain, "--profiles", source("configs/dds/profiles.xml")};
  a.insert(a.end(), args.begin(), args.end());
  return a;
}

/// A finished `pmlsm` run: exit code (-1: did not end in time) and everything it printed.
struct ToolRun {
  int code = -1;
  std::string output;
};

/// Runs `pmlsm --domain D <args>` to its end; its log is dir/<log>.log.
ToolRun pmlsm(const std::string& domain, const fs::path& dir, const std::string& log, std::vector<std::string> args) {
  test::ChildProcess p(pmlsm_args(domain, std::move(args)), (dir / (log + ".log")).string());
  const auto code = p.wait_for(kToolTimeout);
  return ToolRun{code.value_or(-1), p.output()};
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

/// The free-vibration scenario made long (the file's 8 s would end before the steps do): the
/// test stops the nodes itself.
fs::path long_scenario(const fs::path& dir) {
  std::string text = test::read_file(source("configs/scenarios/free_vibration.yaml"));
  const std::regex duration(R"(duration_s: \{value: [0-9.]+)");
  EXPECT_TRUE(std::regex_search(text, duration)) << "free_vibration.yaml has no duration_s to lengthen";
  text = std::regex_replace(text, duration, "duration_s: {value: 300.0");
  const fs::path file = dir / "long_free_vibration.yaml";
  std::ofstream(file) << text;
  return file;
}

/// A realtime controller and an operator-enabled plant_sim, stopped with SIGINT at the end.
/// Both tolerate a loaded machine (two shared cores, other builds): neither gives the other up
/// within 30 s, and the plant stays up when it does; the drive's command watchdog trips after
/// `watchdog_ms` without an answer (a fault, which only an operator clears).
class DriveNodes {
 public:
  DriveNodes(const std::string& domain, const fs::path& dir, double watchdog_ms)
      : scenario_(long_scenario(dir).string()),
        controller_(node_args("controller", domain, scenario_, {"--clock", "realtime", "--plant-lost-ms", "30000"}),
                    (dir / "controller.log").string()),
        plant_(
            node_args("plant_sim", domain, scenario_,
                      {"--peers", "1", "--clock", "realtime", "--auto-enable", "false", "--watchdog-ms",
                       std::to_string(watchdog_ms), "--controller-lost-ms", "30000", "--on-controller-lost", "stay"}),
            (dir / "plant.log").string()) {}

  ~DriveNodes() {
    // SIGINT, as an operator would; the plant's exit code is not checked (after a quick stop
    // it is 5, force was off for some ticks, and a stop request ends it early anyway).
    for (auto* p : {&plant_, &controller_}) {
      p->signal(SIGCONT);  // in case a test left it stopped
      p->signal(SIGINT);
    }
    for (auto* p : {&plant_, &controller_}) {
      if (!p->wait_for(std::chrono::seconds(20))) ADD_FAILURE() << "did not stop on SIGINT:\n" << p->output();
    }
  }

  /// Waits until the plant runs its loop (it publishes DriveState from then on).
  bool started() { return plant_.wait_for_output("plant_sim: realtime clock", kStartTimeout); }

  test::ChildProcess& plant() { return plant_; }
  test::ChildProcess& controller() { return controller_; }

 private:
  std::string scenario_;
  test::ChildProcess controller_;
  test::ChildProcess plant_;
};

TEST(Drive, OperatorWalksThePowerStateMachine) {
  const fs::path dir = test::fresh_dir("pmlsm_drive", "walk");
  const std::string domain = test_domain(37);
  DriveNodes nodes(domain, dir, 2000.0);  // no fault in this test, however loaded the machine
  ASSERT_TRUE(nodes.started()) << nodes.plant().output() << nodes.controller().output();

  // Not enabled at start: switch on disabled, nothing refused yet, no fault.
  ToolRun status = pmlsm(domain, dir, "status0", {"drive", "status"});
  EXPECT_EQ(status.code, 0) << status.output;
  EXPECT_TRUE(contains(status.output, "drive:            plant_sim\n")) << status.output;
  EXPECT_TRUE(contains(status.output, "power state:      switch on disabled\n")) << status.output;
  EXPECT_TRUE(contains(status.output, "statusword:       0x0250\n")) << status.output;
  EXPECT_TRUE(contains(status.output, "error code:       none\n")) << status.output;
  EXPECT_TRUE(contains(status.output, "refused requests: 0\n")) << status.output;
  EXPECT_TRUE(std::regex_search(status.output, std::regex("run id:           0x[0-9a-f]{16}\n"))) << status.output;

  // Switch on from switch on disabled is not a CiA 402 transition: refused, with the reason.
  ToolRun refused = pmlsm(domain, dir, "switch_on_refused", {"drive", "switch-on", "--drive", "plant_sim"});
  EXPECT_EQ(refused.code, 1) << refused.output;
  EXPECT_TRUE(contains(refused.output,
                       "switch on: refused by plant_sim: switch on refused in switch on disabled: "
                       "not allowed in this state"))
      << refused.output;
  // Quick stop where the drive already is switched off is accepted with no change (repeating a
  // cyclic command is not an error), and is not counted as refused.
  ToolRun idle_stop = pmlsm(domain, dir, "quick_stop_idle", {"drive", "quick-stop"});
  EXPECT_EQ(idle_stop.code, 0) << idle_stop.output;
  EXPECT_TRUE(contains(idle_stop.output, "quick stop: quick stop in switch on disabled -> switch on disabled\n"))
      << idle_stop.output;
  status = pmlsm(domain, dir, "status1", {"drive", "status"});
  EXPECT_EQ(status.code, 0) << status.output;
  EXPECT_TRUE(contains(status.output, "power state:      switch on disabled\n")) << status.output;
  EXPECT_TRUE(contains(status.output, "refused requests: 1\n")) << status.output;

  // Enable: shutdown, switch on, enable operation, each answered before the next.
  ToolRun enable = pmlsm(domain, dir, "enable1", {"drive", "enable"});
  EXPECT_EQ(enable.code, 0) << enable.output;
  const auto shutdown_at = enable.output.find("shutdown: shutdown in switch on disabled -> ready to switch on\n");
  const auto switch_on_at = enable.output.find("switch on: switch on in ready to switch on -> switched on\n");
  const auto enable_at = enable.output.find("enable operation: enable operation in switched on -> operation enabled\n");
  EXPECT_NE(shutdown_at, std::string::npos) << enable.output;
  EXPECT_NE(switch_on_at, std::string::npos) << enable.output;
  EXPECT_NE(enable_at, std::string::npos) << enable.output;
  EXPECT_LT(shutdown_at, switch_on_at) << enable.output;
  EXPECT_LT(switch_on_at, enable_at) << enable.output;
  EXPECT_TRUE(contains(enable.output, "plant_sim: operation enabled (statusword 0x0237)\n")) << enable.output;
  status = pmlsm(domain, dir, "status2", {"drive", "status"});
  EXPECT_TRUE(contains(status.output, "power state:      operation enabled\n")) << status.output;

  // Quick stop from operation enabled: accepted; the simulated stop ends in switch on disabled.
  ToolRun stop = pmlsm(domain, dir, "quick_stop", {"drive", "quick-stop", "--drive", "plant_sim"});
  EXPECT_EQ(stop.code, 0) << stop.output;
  EXPECT_TRUE(contains(stop.output, "quick stop: quick stop in operation enabled -> quick stop active\n"))
      << stop.output;
  status = pmlsm(domain, dir, "status3", {"drive", "status"});
  EXPECT_EQ(status.code, 0) << status.output;
  EXPECT_TRUE(contains(status.output, "power state:      switch on disabled\n")) << status.output;
  EXPECT_TRUE(std::regex_search(status.output, std::regex("safe ticks:       [1-9][0-9]*\n"))) << status.output;
  EXPECT_TRUE(contains(status.output, "refused requests: 1\n")) << status.output;

  // And again.
  enable = pmlsm(domain, dir, "enable2", {"drive", "enable", "--drive", "plant_sim"});
  EXPECT_EQ(enable.code, 0) << enable.output;
  EXPECT_TRUE(contains(enable.output, "plant_sim: operation enabled (statusword 0x0237)\n")) << enable.output;

  // Disable voltage, then the single steps by hand.
  ToolRun disable = pmlsm(domain, dir, "disable", {"drive", "disable"});
  EXPECT_EQ(disable.code, 0) << disable.output;
  EXPECT_TRUE(contains(disable.output, "disable voltage: disable voltage in operation enabled -> switch on disabled\n"))
      << disable.output;
  ToolRun shutdown = pmlsm(domain, dir, "shutdown", {"drive", "shutdown"});
  EXPECT_EQ(shutdown.code, 0) << shutdown.output;
  EXPECT_TRUE(contains(shutdown.output, "plant_sim: ready to switch on (statusword 0x0231)\n")) << shutdown.output;
  ToolRun switch_on = pmlsm(domain, dir, "switch_on", {"drive", "switch-on"});
  EXPECT_EQ(switch_on.code, 0) << switch_on.output;
  EXPECT_TRUE(contains(switch_on.output, "plant_sim: switched on (statusword 0x0233)\n")) << switch_on.output;

  // A drive nobody runs: the named drive does not answer.
  ToolRun nobody = pmlsm(domain, dir, "nobody", {"drive", "status", "--drive", "nobody", "--timeout-s", "1"});
  EXPECT_EQ(nobody.code, 1) << nobody.output;
  EXPECT_TRUE(contains(nobody.output, "drive 'nobody' has not answered on domain " + domain + " within 1 s"))
      << nobody.output;

  // Every request reached the drive, each with its own id, from the requester named.
  const std::string plant_log = nodes.plant().output();
  std::set<std::string> ids;
  const std::regex line("plant_sim: drive control from [^ ]+ \\(request ([0-9]+)\\)");
  for (auto it = std::sregex_iterator(plant_log.begin(), plant_log.end(), line); it != std::sregex_iterator(); ++it) {
    EXPECT_NE((*it)[1].str(), "0") << plant_log;
    ids.insert((*it)[1].str());
  }
  EXPECT_EQ(ids.size(), 12u) << plant_log;                  // 2 + 3 + 1 + 3 + 1 + 1 + 1
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);  // the logs stay for a failure
}

TEST(Drive, EnableNeverResetsAFault) {
  const fs::path dir = test::fresh_dir("pmlsm_drive", "fault");
  const std::string domain = test_domain(38);
  // The plant stays up when the controller goes silent (a rig's setting), so its fault stays.
  DriveNodes nodes(domain, dir, 300.0);
  ASSERT_TRUE(nodes.started()) << nodes.plant().output() << nodes.controller().output();
  ToolRun enable = pmlsm(domain, dir, "enable", {"drive", "enable"});
  ASSERT_EQ(enable.code, 0) << enable.output;
  // The controller freezes: its feedback goes unanswered, the watchdog faults the drive.
  ASSERT_TRUE(nodes.plant().wait_for_output("watchdog armed", std::chrono::seconds(10))) << nodes.plant().output();
  nodes.controller().signal(SIGSTOP);
  ASSERT_TRUE(nodes.plant().wait_for_output("plant_sim: watchdog:", std::chrono::seconds(10)))
      << nodes.plant().output();

  ToolRun status = pmlsm(domain, dir, "status_fault", {"drive", "status"});
  EXPECT_EQ(status.code, 0) << status.output;
  EXPECT_TRUE(contains(status.output, "power state:      fault\n")) << status.output;
  EXPECT_TRUE(std::regex_search(status.output, std::regex("error code:       0x[0-9a-f]{4}\n"))) << status.output;
  EXPECT_TRUE(contains(status.output, "faults:           1\n")) << status.output;

  enable = pmlsm(domain, dir, "enable_fault", {"drive", "enable"});
  EXPECT_EQ(enable.code, 1) << enable.output;
  EXPECT_TRUE(contains(enable.output, "enable: drive plant_sim is in fault (error code 0x")) << enable.output;
  EXPECT_TRUE(contains(enable.output, "`pmlsm drive fault-reset` clears it")) << enable.output;
  EXPECT_FALSE(contains(enable.output, "fault reset:")) << enable.output;
  // The drive is still in fault: enable sent nothing.
  status = pmlsm(domain, dir, "status_still", {"drive", "status"});
  EXPECT_TRUE(contains(status.output, "power state:      fault\n")) << status.output;
  EXPECT_FALSE(contains(nodes.plant().output(), "fault reset")) << nodes.plant().output();

  ToolRun reset = pmlsm(domain, dir, "reset", {"drive", "fault-reset"});
  EXPECT_EQ(reset.code, 0) << reset.output;
  EXPECT_TRUE(contains(reset.output, "fault reset: fault reset in fault -> switch on disabled\n")) << reset.output;
  EXPECT_TRUE(contains(reset.output, "plant_sim: switch on disabled (statusword 0x0250)\n")) << reset.output;
  status = pmlsm(domain, dir, "status_reset", {"drive", "status"});
  EXPECT_TRUE(contains(status.output, "power state:      switch on disabled\n")) << status.output;
  EXPECT_TRUE(std::regex_search(status.output, std::regex("error code:       0x[0-9a-f]{4} \\(last fault, reset\\)\n")))
      << status.output;

  // Reset by the operator, the drive enables again.
  nodes.controller().signal(SIGCONT);
  enable = pmlsm(domain, dir, "enable_after_reset", {"drive", "enable"});
  EXPECT_EQ(enable.code, 0) << enable.output;
  EXPECT_TRUE(contains(enable.output, "plant_sim: operation enabled (statusword 0x0237)\n")) << enable.output;
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);  // the logs stay for a failure
}

TEST(Drive, NoDriveAndBadInput) {
  const fs::path dir = test::fresh_dir("pmlsm_drive", "none");
  const std::string domain = test_domain(39);  // nothing runs on it
  const auto start = std::chrono::steady_clock::now();
  ToolRun status = pmlsm(domain, dir, "status", {"drive", "status", "--timeout-s", "1"});
  const double took_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(status.code, 1) << status.output;
  EXPECT_TRUE(contains(status.output, "no drive answered on domain " + domain + " within 1 s")) << status.output;
  EXPECT_GE(took_s, 1.0);
  EXPECT_LT(took_s, 15.0);

  ToolRun enable = pmlsm(domain, dir, "enable", {"drive", "enable", "--timeout-s", "1"});
  EXPECT_EQ(enable.code, 1) << enable.output;
  EXPECT_TRUE(contains(enable.output, "no drive answered on domain " + domain)) << enable.output;

  ToolRun unknown = pmlsm(domain, dir, "unknown", {"drive", "warp-speed"});
  EXPECT_EQ(unknown.code, 2) << unknown.output;
  EXPECT_TRUE(contains(unknown.output, "subcommand")) << unknown.output;  // CLI11: "A subcommand is required"
  ToolRun none = pmlsm(domain, dir, "none", {"drive"});
  EXPECT_EQ(none.code, 2) << none.output;
  ToolRun bad_timeout = pmlsm(domain, dir, "bad_timeout", {"drive", "status", "--timeout-s", "-1"});
  EXPECT_EQ(bad_timeout.code, 2) << bad_timeout.output;
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);  // the logs stay for a failure
}

}  // namespace
}  // namespace pmlsm

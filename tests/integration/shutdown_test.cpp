// Bounded shutdown: a node or a container told to stop (SIGINT) is gone within a second whatever is
// attached, a reader that never acknowledges included. The reader here is a recorder stopped with
// SIGSTOP mid-run: its participant stays matched until its lease (20 s) runs out and acknowledges
// nothing meanwhile, so a node that waited for its acknowledgements at exit would wait that long.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "integration_support.hpp"

namespace {

namespace fs = std::filesystem;
namespace test = pmlsm::test;
using std::chrono::seconds;
using test::bin;
using test::node_args;
using test::source;
using test::test_domain;
using Clock = std::chrono::steady_clock;

/// What the tests allow from SIGINT to exit: the target is 1 s; a loaded CI host gets half again.
constexpr std::chrono::milliseconds kExitBound{1500};

/// A recorder of every topic, stopped (SIGSTOP) once it has matched the run's writers and samples
/// flow; resumed and ended by the caller.
class FrozenRecorder {
 public:
  FrozenRecorder(const std::string& domain, const fs::path& dir)
      : process_({bin("pmlsm"), "--domain", domain, "--profiles", source("configs/dds/profiles.xml"), "record", "-o",
                  (dir / "frozen.mcap").string()},
                 (dir / "recorder.log").string()) {}
  ~FrozenRecorder() {
    process_.signal(SIGCONT);
    process_.signal(SIGINT);
    process_.wait_for(seconds(20));
  }
  void freeze() { process_.signal(SIGSTOP); }
  test::ChildProcess& process() { return process_; }

 private:
  test::ChildProcess process_;
};

/// Sends SIGINT to `p` and returns how long it took to exit (its code into `code`).
std::chrono::milliseconds time_to_exit(test::ChildProcess& p, std::optional<int>& code) {
  const auto start = Clock::now();
  p.signal(SIGINT);
  code = p.wait_for(seconds(30));
  return std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - start);
}

TEST(Shutdown, SeparateNodesStopWithinASecondWhileAReaderNeverAcknowledges) {
  const fs::path dir = test::fresh_dir("pmlsm_shutdown", "separate");
  const std::string domain = test_domain(104);
  const std::string scenario = test::long_pulse(dir);
  FrozenRecorder recorder(domain, dir);
  test::ChildProcess controller(node_args("controller", domain, scenario), (dir / "controller.log").string());
  // The plant waits for the controller and the recorder's MotorFeedback readers: the recorder takes
  // part in the run before it is frozen.
  test::ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "2"}), (dir / "plant.log").string());
  ASSERT_TRUE(plant.wait_for_output("peers matched", seconds(60))) << plant.output();
  // Frozen while matched: every sample from here piles up unacknowledged at it while the lockstep
  // run goes on, and its lease (20 s, renewed every second until now) is far from running out when
  // the stop comes.
  recorder.freeze();
  std::optional<int> plant_code;
  const auto plant_ms = time_to_exit(plant, plant_code);
  std::optional<int> controller_code;
  const auto controller_ms = time_to_exit(controller, controller_code);
  ASSERT_TRUE(plant_code.has_value()) << plant.output();
  ASSERT_TRUE(controller_code.has_value()) << controller.output();
  EXPECT_LT(plant_ms.count(), kExitBound.count()) << "ms from SIGINT to exit\n" << plant.output();
  EXPECT_LT(controller_ms.count(), kExitBound.count()) << "ms from SIGINT to exit\n" << controller.output();
  // A stop asked for is not a failure of the node.
  EXPECT_EQ(*plant_code, 0) << plant.output();
  EXPECT_EQ(*controller_code, 0) << controller.output();
  fs::remove_all(dir);
}

TEST(Shutdown, ARealtimeContainerStopsWithinASecondWhileAReaderNeverAcknowledges) {
  const fs::path dir = test::fresh_dir("pmlsm_shutdown", "container");
  const std::string domain = test_domain(105);
  const std::string scenario = test::long_pulse(dir);
  FrozenRecorder recorder(domain, dir);
  test::ChildProcess container(
      test::container_args(
          "chain", {test::component_args("plant_sim", "plant_sim", domain, scenario,
                                         {"--clock", "realtime", "--watchdog-ms", "1000", "--peers", "2"}),
                    test::component_args("controller", "controller", domain, scenario, {"--clock", "realtime"})}),
      (dir / "container.log").string());
  ASSERT_TRUE(container.wait_for_output("peers matched", seconds(60))) << container.output();
  recorder.freeze();
  std::optional<int> code;
  const auto ms = time_to_exit(container, code);
  ASSERT_TRUE(code.has_value()) << container.output();
  EXPECT_LT(ms.count(), kExitBound.count()) << "ms from SIGINT to exit\n" << container.output();
  EXPECT_EQ(*code, 0) << container.output();
  // What the frozen reader did not get is counted, not waited for.
  EXPECT_NE(container.output().find("to readers outside (publisher thread):"), std::string::npos) << container.output();
  fs::remove_all(dir);
}

}  // namespace

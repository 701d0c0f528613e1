// Participants coming and going during a run: 200 cycles of four participants each (two churn
// processes, participant_churn) join and leave a composed realtime chain. Fast DDS 2.9.1 as Debian
// builds it can abort a process when a peer's lease check runs while peers leave (PDP.cpp,
// check_remote_participant_liveliness); the shipped profiles' 20 s lease keeps that check out of
// any life shorter than it (docs/hardening.md, "Participants that come and go").
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <optional>
#include <regex>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "integration_support.hpp"

namespace {

namespace fs = std::filesystem;
namespace test = pmlsm::test;
using std::chrono::seconds;
using test::bin;
using test::source;
using test::test_domain;

/// The lease the shipped participant profiles must announce at least: longer than a test's run
/// and than the churn's lives, so no peer's lease check runs before it has left.
constexpr int kMinimumLeaseS = 20;

bool aborted_in_discovery(const std::string& output) {
  return output.find("check_remote_participant_liveliness") != std::string::npos;
}

TEST(ParticipantChurn, TwoHundredCyclesOfParticipantsLeaveTheRunningChainUntouched) {
  const fs::path dir = test::fresh_dir("pmlsm_churn", "chain");
  const std::string domain = test_domain(107);
  const std::string scenario = test::long_pulse(dir);
  // The chain is the observer here, not under timing test: a watchdog no churn can trip on a
  // loaded 2-core host.
  test::ChildProcess chain(
      test::container_args(
          "chain", {test::component_args("plant_sim", "plant_sim", domain, scenario,
                                         {"--clock", "realtime", "--watchdog-ms", "1000", "--peers", "1"}),
                    test::component_args("controller", "controller", domain, scenario, {"--clock", "realtime"})}),
      (dir / "chain.log").string());
  ASSERT_TRUE(chain.wait_for_output("peers matched", seconds(60))) << chain.output();

  std::vector<std::unique_ptr<test::ChildProcess>> churners;
  for (int i = 0; i < 2; ++i) {
    churners.push_back(std::make_unique<test::ChildProcess>(
        std::vector<std::string>{bin("participant_churn"), "--domain", domain, "--profiles",
                                 source("configs/dds/profiles.xml"), "--cycles", "100", "--batch", "4", "--life-ms",
                                 "100"},
        (dir / ("churn" + std::to_string(i) + ".log")).string()));
  }
  for (auto& churner : churners) {
    const std::optional<int> code = churner->wait_for(seconds(150));
    ASSERT_TRUE(code.has_value()) << churner->output();
    EXPECT_FALSE(aborted_in_discovery(churner->output())) << churner->output();
    EXPECT_EQ(*code, 0) << churner->output();
    // The churn met the chain: most lives saw the plant's MotorFeedback writer (discovery takes a
    // few of a life's 100 ms; a loaded host may miss some).
    std::smatch m;
    const std::string out = churner->output();
    ASSERT_TRUE(std::regex_search(out, m, std::regex(R"((\d+) matched a MotorFeedback writer)"))) << out;
    EXPECT_GE(std::stoi(m[1]), 50) << out;
  }

  ASSERT_FALSE(chain.wait_for(std::chrono::milliseconds(0)).has_value()) << "the chain ended during the churn\n"
                                                                         << chain.output();
  chain.signal(SIGINT);
  const std::optional<int> code = chain.wait_for(seconds(30));
  ASSERT_TRUE(code.has_value()) << chain.output();
  EXPECT_FALSE(aborted_in_discovery(chain.output())) << chain.output();
  EXPECT_EQ(*code, 0) << chain.output();
  fs::remove_all(dir);
}

TEST(ParticipantChurn, EveryShippedParticipantProfileAnnouncesALeaseLongerThanARun) {
  const std::string profiles = test::read_file(source("configs/dds/profiles.xml"));
  const std::regex lease(R"(<leaseDuration><sec>(\d+)</sec>)");
  int leases = 0;
  for (auto it = std::sregex_iterator(profiles.begin(), profiles.end(), lease); it != std::sregex_iterator(); ++it) {
    ++leases;
    EXPECT_GE(std::stoi((*it)[1]), kMinimumLeaseS) << (*it)[0];
  }
  const std::regex participant("<participant profile_name=");
  const auto participants =
      std::distance(std::sregex_iterator(profiles.begin(), profiles.end(), participant), std::sregex_iterator());
  EXPECT_EQ(leases, participants) << "a participant profile without its own lease takes Fast DDS's default";
}

}  // namespace

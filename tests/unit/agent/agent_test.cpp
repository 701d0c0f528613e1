// pmlsm_agent: the launch agents' policy, driven directly with made-up times.
#include <gtest/gtest.h>

#include <stdexcept>

#include "pmlsm/agent/agent.hpp"
#include "pmlsm/util/exit_codes.hpp"

namespace pmlsm::agent {
namespace {

using std::chrono::milliseconds;
const TimePoint t0{};
using Kind = LaunchCoordinator::Action::Kind;
using Phase = LaunchCoordinator::Phase;

TEST(LeaseTracker, APeerIsAliveWithinItsLeaseAndReportedOnceWhenSilent) {
  LeaseTracker leases(milliseconds(1000));
  EXPECT_FALSE(leases.alive("rig", t0));
  leases.heard("rig", t0);
  leases.heard("ctrl", t0 + milliseconds(500));
  EXPECT_TRUE(leases.alive("rig", t0 + milliseconds(999)));
  EXPECT_FALSE(leases.alive("rig", t0 + milliseconds(1000)));
  EXPECT_EQ(leases.expired(t0 + milliseconds(1000)), std::vector<std::string>{"rig"});
  EXPECT_TRUE(leases.expired(t0 + milliseconds(1200)).empty());  // once
  EXPECT_EQ(leases.expired(t0 + milliseconds(1500)), std::vector<std::string>{"ctrl"});
  leases.heard("rig", t0 + milliseconds(2000));  // back: may be reported again
  EXPECT_EQ(leases.expired(t0 + milliseconds(3000)), std::vector<std::string>{"rig"});
  EXPECT_THROW(LeaseTracker(milliseconds(0)), std::invalid_argument);
}

TEST(ExecutablePolicy, OnlyTheAllowedPathsMayRunAndARefusalNamesNodeExecutableAndPlace) {
  const ExecutablePolicy policy({"/opt/pmlsm/bin/plant_sim", "/opt/pmlsm/bin/controller"});
  EXPECT_EQ(policy.refusal("plant", "plant_sim", "/opt/pmlsm/bin/plant_sim"), "");
  const std::string shell = policy.refusal("evil", "sh", "/usr/bin/sh");
  EXPECT_NE(shell.find("node 'evil'"), std::string::npos) << shell;
  EXPECT_NE(shell.find("/usr/bin/sh"), std::string::npos) << shell;
  EXPECT_NE(shell.find("/opt/pmlsm/bin"), std::string::npos) << shell;
  EXPECT_NE(policy.refusal("x", "nope", "").find("not found"), std::string::npos);
  EXPECT_THROW(ExecutablePolicy({}), std::invalid_argument);
  EXPECT_THROW(ExecutablePolicy({"bin/plant_sim"}), std::invalid_argument);
}

TEST(ExecutablePolicy, TheNodeProgramsAreNeitherAShellNorAnythingThatStartsPrograms) {
  const std::vector<std::string> programs = node_programs({"plant_sim", "controller"});
  EXPECT_EQ(programs, (std::vector<std::string>{"closed_loop", "container", "plant_sim", "controller"}));
  for (const char* starter : {"launcher", "launch_agent", "pmlsm"}) {  // `pmlsm launch` starts anything
    EXPECT_THROW(node_programs({"plant_sim", starter}), std::invalid_argument) << starter;
  }
}

TEST(AgentMachine, StartsOneLaunchRefusesOthersAndStopsOnRequest) {
  AgentMachine agent;
  EXPECT_EQ(agent.on_start(7, "ops@ctrl", milliseconds(2000), "", t0).kind, AgentAction::Kind::kStart);
  EXPECT_EQ(agent.state(), AgentMachine::State::kRunning);
  EXPECT_EQ(agent.on_start(7, "ops@ctrl", milliseconds(2000), "", t0).kind, AgentAction::Kind::kNone);  // repeated
  const auto busy = agent.on_start(8, "other@x", milliseconds(2000), "", t0);
  EXPECT_EQ(busy.kind, AgentAction::Kind::kRefuse);
  EXPECT_NE(busy.reason.find("busy"), std::string::npos);
  EXPECT_EQ(agent.on_stop(8).kind, AgentAction::Kind::kNone);  // not ours
  EXPECT_EQ(agent.on_stop(7).kind, AgentAction::Kind::kStop);
  EXPECT_EQ(agent.state(), AgentMachine::State::kStopping);
  EXPECT_EQ(agent.on_stop(7).kind, AgentAction::Kind::kNone);  // once
  agent.on_slice_ended();
  EXPECT_EQ(agent.state(), AgentMachine::State::kIdle);
  EXPECT_EQ(agent.on_start(8, "other@x", milliseconds(2000), "", t0).kind, AgentAction::Kind::kStart);
}

TEST(AgentMachine, ARefusedSliceStartsNothing) {
  AgentMachine agent;
  const auto a = agent.on_start(3, "ops", milliseconds(2000), "node 'evil': executable 'sh' ...", t0);
  EXPECT_EQ(a.kind, AgentAction::Kind::kRefuse);
  EXPECT_EQ(a.reason, "node 'evil': executable 'sh' ...");
  EXPECT_EQ(agent.state(), AgentMachine::State::kIdle);
  EXPECT_EQ(agent.on_start(0, "ops", milliseconds(2000), "", t0).kind, AgentAction::Kind::kRefuse);
}

TEST(AgentMachine, ASilentLauncherStopsTheSliceAfterItsLease) {
  AgentMachine agent;
  agent.on_start(5, "ops", milliseconds(1000), "", t0);
  agent.on_keepalive(5, t0 + milliseconds(800));
  EXPECT_EQ(agent.step(t0 + milliseconds(1700)).kind, AgentAction::Kind::kNone);
  agent.on_keepalive(6, t0 + milliseconds(1700));  // another launch's keepalive does not count
  const auto a = agent.step(t0 + milliseconds(1800));
  EXPECT_EQ(a.kind, AgentAction::Kind::kStop);
  EXPECT_NE(a.reason.find("silent for 1000 ms"), std::string::npos) << a.reason;
  EXPECT_EQ(agent.step(t0 + milliseconds(5000)).kind, AgentAction::Kind::kNone);
}

LaunchCoordinator two_hosts(TimePoint now, bool ctrl_ends = false) {
  return LaunchCoordinator({{"rig", false}, {"ctrl", ctrl_ends}}, milliseconds(5000), milliseconds(2000), now);
}

TEST(LaunchCoordinator, StartsWhenEveryHostHasAnAgentAndSucceedsWhenEverySliceEndsWithZero) {
  auto c = two_hosts(t0);
  c.on_announce("rig", t0 + milliseconds(100));
  EXPECT_EQ(c.step(t0 + milliseconds(150)).kind, Kind::kNone);
  EXPECT_EQ(c.missing_hosts(t0 + milliseconds(150)), std::vector<std::string>{"ctrl"});
  c.on_announce("ctrl", t0 + milliseconds(300));
  EXPECT_EQ(c.step(t0 + milliseconds(310)).kind, Kind::kStartAll);
  EXPECT_EQ(*c.all_agents_at(), t0 + milliseconds(310));
  EXPECT_EQ(c.phase(), Phase::kRunning);
  c.on_started("rig");
  c.on_ended("rig", kExitOk, "all 1 node ended cleanly");
  EXPECT_EQ(c.phase(), Phase::kRunning);
  EXPECT_EQ(c.unfinished_hosts(), std::vector<std::string>{"ctrl"});
  c.on_announce("ctrl", t0 + milliseconds(1500));
  c.on_ended("ctrl", kExitOk, "");
  EXPECT_EQ(c.phase(), Phase::kDone);
  EXPECT_EQ(c.exit_code(), kExitOk);
  EXPECT_TRUE(c.failures().empty());
}

TEST(LaunchCoordinator, AHostWithoutAnAgentIsNamedAfterTheDeadlineAndNothingStarts) {
  auto c = two_hosts(t0);
  c.on_announce("ctrl", t0 + milliseconds(100));
  for (int ms = 200; ms < 5000; ms += 500) {
    c.on_announce("ctrl", t0 + milliseconds(ms));
    EXPECT_EQ(c.step(t0 + milliseconds(ms)).kind, Kind::kNone);
  }
  EXPECT_EQ(c.step(t0 + milliseconds(5000)).kind, Kind::kNone);
  EXPECT_EQ(c.phase(), Phase::kDone);
  EXPECT_EQ(c.exit_code(), kExitPeerMissing);
  ASSERT_EQ(c.failures().size(), 1u);
  EXPECT_NE(c.failures()[0].find("rig: no agent"), std::string::npos) << c.failures()[0];
}

TEST(LaunchCoordinator, ALostAgentStopsTheOthersAndTheLaunchFailsWithPeerLost) {
  auto c = two_hosts(t0);
  c.on_announce("rig", t0);
  c.on_announce("ctrl", t0);
  ASSERT_EQ(c.step(t0).kind, Kind::kStartAll);
  c.on_announce("ctrl", t0 + milliseconds(1900));
  EXPECT_EQ(c.step(t0 + milliseconds(1999)).kind, Kind::kNone);
  const auto a = c.step(t0 + milliseconds(2000));  // rig silent for its lease
  EXPECT_EQ(a.kind, Kind::kStopAll);
  EXPECT_NE(a.reason.find("rig"), std::string::npos);
  EXPECT_EQ(c.phase(), Phase::kStopping);
  c.on_ended("ctrl", kExitPeerLost, "controller exited with code 4");
  EXPECT_EQ(c.phase(), Phase::kDone);
  EXPECT_EQ(c.exit_code(), kExitPeerLost);
  ASSERT_EQ(c.failures().size(), 2u);
  EXPECT_NE(c.failures()[0].find("rig: agent lost"), std::string::npos) << c.failures()[0];
  c.on_announce("rig", t0 + milliseconds(2500));  // a lost agent back: too late for this launch
  EXPECT_EQ(c.exit_code(), kExitPeerLost);
}

TEST(LaunchCoordinator, ARefusedSliceOrAFailedOneStopsTheRest) {
  auto c = two_hosts(t0);
  c.on_announce("rig", t0);
  c.on_announce("ctrl", t0);
  c.step(t0);
  const auto a = c.on_refused("ctrl", "node 'evil': executable 'sh' (/usr/bin/sh) is not one of ...");
  EXPECT_EQ(a.kind, Kind::kStopAll);
  c.on_ended("rig", kExitOk, "");  // stopped by SIGINT: clean
  EXPECT_EQ(c.phase(), Phase::kDone);
  EXPECT_EQ(c.exit_code(), kExitBadConfig);

  auto d = two_hosts(t0);
  d.on_announce("rig", t0);
  d.on_announce("ctrl", t0);
  d.step(t0);
  EXPECT_EQ(d.on_ended("rig", kExitSafeState, "plant exited with code 5").kind, Kind::kStopAll);
  d.on_ended("ctrl", kExitOk, "");
  EXPECT_EQ(d.exit_code(), kExitSafeState);
}

TEST(LaunchCoordinator, AnEndsLaunchSliceStopsTheOthersAndInterruptStopsAll) {
  auto c = two_hosts(t0, /*ctrl_ends=*/true);
  c.on_announce("rig", t0);
  c.on_announce("ctrl", t0);
  c.step(t0);
  EXPECT_EQ(c.on_ended("ctrl", kExitOk, "").kind, Kind::kStopAll);
  c.on_ended("rig", kExitOk, "");
  EXPECT_EQ(c.exit_code(), kExitOk);

  auto d = two_hosts(t0);
  d.on_announce("rig", t0);
  d.on_announce("ctrl", t0);
  d.step(t0);
  EXPECT_EQ(d.on_interrupt().kind, Kind::kStopAll);
  EXPECT_EQ(d.on_interrupt().kind, Kind::kNone);
  d.on_ended("rig", kExitOk, "");
  d.on_ended("ctrl", kExitOk, "");
  EXPECT_EQ(d.exit_code(), kExitOk);

  auto e = two_hosts(t0);  // interrupted while waiting for agents: nothing started, not a success
  e.on_interrupt();
  EXPECT_EQ(e.phase(), Phase::kDone);
  EXPECT_NE(e.exit_code(), kExitOk);
}

TEST(LaunchCoordinator, BadArgumentsAreRefused) {
  EXPECT_THROW(LaunchCoordinator({}, milliseconds(1), milliseconds(1), t0), std::invalid_argument);
  EXPECT_THROW(LaunchCoordinator({{"a", false}, {"a", false}}, milliseconds(1), milliseconds(1), t0),
               std::invalid_argument);
  EXPECT_THROW(LaunchCoordinator({{"a", false}}, milliseconds(0), milliseconds(1), t0), std::invalid_argument);
}

}  // namespace
}  // namespace pmlsm::agent

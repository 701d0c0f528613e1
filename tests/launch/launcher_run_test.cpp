// The launcher as a real process, with shell-script nodes: output relay, stop
// rules, failures at start, signal forwarding, exit codes, no leftover processes.
#include <gtest/gtest.h>

#include <csignal>
#include <map>
#include <regex>
#include <sstream>

#include "launch_test_support.hpp"
#include "pmlsm/util/exit_codes.hpp"

namespace {

using namespace launch_test;

::testing::AssertionResult contains(const std::string& text, const std::string& needle) {
  if (text.find(needle) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << needle << "' not found in:\n" << text;
}

class LauncherRun : public ::testing::Test {
 protected:
  // Writes node scripts (name -> text) and launch.yaml; returns the launch file path.
  std::string write_launch(const std::string& yaml, const std::map<std::string, std::string>& scripts) {
    for (const auto& [name, text] : scripts) dir_.write(name, text, true);
    return dir_.write("launch.yaml", yaml);
  }
  std::vector<std::string> args(std::vector<std::string> extra = {}) {
    std::vector<std::string> all{dir_.file("launch.yaml"), "--bin-dir", dir_.path().string()};
    all.insert(all.end(), extra.begin(), extra.end());
    return all;
  }
  // Every node that wrote a PID file is gone: reaped, not a zombie or orphan.
  void expect_gone(std::initializer_list<const char*> names) {
    for (const char* name : names) {
      const auto pid = dir_.pid_of(name);
      ASSERT_TRUE(pid.has_value()) << name << " never wrote its PID";
      EXPECT_FALSE(process_exists(*pid)) << name << " (pid " << *pid << ") is still there";
    }
  }

  ScratchDir dir_;  // first member: destroyed last, after the launcher
};

TEST_F(LauncherRun, PrefixesEachLineAndKeepsStdoutAndStderrApart) {
  write_launch("name: relay\nnodes:\n  - {name: talker, executable: talker.sh}\n",
               {{"talker.sh", "#!/bin/sh\necho one\necho warn >&2\necho two\nprintf tail\n"}});
  const RunResult r = run_launcher(dir_, args());
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, "[talker] one\n[talker] two\n[talker] tail\n");
  EXPECT_TRUE(contains(r.err, "[talker] warn\n"));
  EXPECT_TRUE(contains(r.err, "[launcher] talker exited with code 0 (ok)\n"));
  EXPECT_TRUE(contains(r.err, "[launcher] all 1 node ended cleanly"));
}

TEST_F(LauncherRun, LinesOfConcurrentNodesNeverMix) {
  // Each line goes out in two writes, so the launcher sees partial lines.
  const auto writer = [](const std::string& name) {
    return "#!/bin/sh\ni=0\nwhile [ $i -lt 300 ]; do\n"
           "  printf '%s-%04d-' " +
           name +
           " $i\n"
           "  printf '%0200d\\n' 0\n"
           "  i=$((i + 1))\ndone\n";
  };
  write_launch("name: chatter\nnodes:\n  - {name: a, executable: a.sh}\n  - {name: b, executable: b.sh}\n",
               {{"a.sh", writer("a")}, {"b.sh", writer("b")}});
  const RunResult r = run_launcher(dir_, args());
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 0) << r.err;
  const std::regex line_re("\\[(a|b)\\] (a|b)-([0-9]{4})-0{200}");
  std::map<std::string, int> next{{"a", 0}, {"b", 0}};
  std::istringstream lines(r.out);
  for (std::string line; std::getline(lines, line);) {
    std::smatch m;
    ASSERT_TRUE(std::regex_match(line, m, line_re)) << "mixed line: " << line;
    ASSERT_EQ(m[1], m[2]) << line;
    EXPECT_EQ(std::stoi(m[3]), next[m[1]]++) << line;
  }
  EXPECT_EQ(next["a"], 300);
  EXPECT_EQ(next["b"], 300);
}

TEST_F(LauncherRun, PassesArgsAndEnvironmentAfterSubstitution) {
  write_launch(
      "name: echo\n"
      "args: {word: default}\n"
      "nodes:\n"
      "  - name: echo\n"
      "    executable: ./tools/echo.sh\n"  // relative to the current folder: the scratch dir
      "    args: [\"$(arg word)\", \"two words\", \"x$(arg word)y\"]\n"
      "    env: {LAUNCH_TEST_VAR: \"with space\"}\n",
      {});
  std::filesystem::create_directory(dir_.path() / "tools");
  dir_.write("tools/echo.sh", "#!/bin/sh\necho \"env=$LAUNCH_TEST_VAR\"\nfor a in \"$@\"; do echo \"arg=$a\"; done\n",
             true);
  const RunResult r = run_launcher(dir_, args({"--arg", "word=hello"}));
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, "[echo] env=with space\n[echo] arg=hello\n[echo] arg=two words\n[echo] arg=xhelloy\n");
}

TEST_F(LauncherRun, EndsLaunchStopsTheOthers) {
  write_launch(
      "name: ends\nnodes:\n"
      "  - {name: worker, executable: worker.sh}\n"
      "  - {name: main, executable: main.sh, ends_launch: true}\n",
      {{"worker.sh", script::waits_for_sigint(dir_, "worker")},
       {"main.sh", script::exits_after(dir_, "main", "worker", 0)}});
  const RunResult r = run_launcher(dir_, args());
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.err, "[launcher] main exited with code 0"));
  EXPECT_TRUE(contains(r.err, "[launcher] main ends the launch"));
  EXPECT_TRUE(contains(r.out, "[worker] worker stopping on SIGINT"));
  EXPECT_TRUE(contains(r.err, "[launcher] worker exited with code 0"));
  expect_gone({"worker", "main"});
}

TEST_F(LauncherRun, NodeEndedByTheForwardedSigintCountsAsClean) {
  write_launch(
      "name: ends\nnodes:\n"
      "  - {name: worker, executable: worker.sh}\n"
      "  - {name: main, executable: main.sh, ends_launch: true}\n",
      {{"worker.sh", script::dies_on_sigint(dir_, "worker")},
       {"main.sh", script::exits_after(dir_, "main", "worker", 0)}});
  const RunResult r = run_launcher(dir_, args());
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.err, "[launcher] worker killed by signal 2 (SIGINT, sent by the launcher)\n"));
  EXPECT_TRUE(contains(r.err, "[launcher] all 2 nodes ended cleanly\n"));
  expect_gone({"worker", "main"});
}

TEST_F(LauncherRun, FailingEndsLaunchNodeFailsTheLaunch) {
  write_launch(
      "name: ends\nnodes:\n"
      "  - {name: worker, executable: worker.sh}\n"
      "  - {name: main, executable: main.sh, ends_launch: true}\n",
      {{"worker.sh", script::waits_for_sigint(dir_, "worker")},
       {"main.sh", script::exits_after(dir_, "main", "worker", 4)}});
  const RunResult r = run_launcher(dir_, args({"--start-grace-ms", "0"}));
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 4) << r.err;
  EXPECT_TRUE(contains(r.err, "[launcher] main exited with code 4 (a peer was lost)\n"));
  EXPECT_TRUE(contains(r.err, "[launcher] worker exited with code 0 (ok)\n"));
  EXPECT_TRUE(
      contains(r.err, "[launcher] launch failed with exit code 4: main exited with code 4 (a peer was lost)\n"));
  expect_gone({"worker", "main"});
}

TEST_F(LauncherRun, NodeIgnoringSigintIsKilledAfterTheStopTimeout) {
  write_launch(
      "name: stubborn\nnodes:\n"
      "  - {name: worker, executable: worker.sh}\n"
      "  - {name: main, executable: main.sh, ends_launch: true}\n",
      {{"worker.sh", script::ignores_sigint(dir_, "worker")},
       {"main.sh", script::exits_after(dir_, "main", "worker", 0)}});
  const RunResult r = run_launcher(dir_, args({"--stop-timeout-ms", "200"}));
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "[launcher] worker did not stop within 200 ms of SIGINT; sending SIGKILL"));
  EXPECT_TRUE(contains(r.err, "[launcher] worker killed by signal 9 (SIGKILL, sent by the launcher)"));
  EXPECT_TRUE(contains(r.err, "launch failed with exit code 1: worker killed by signal 9"));
  expect_gone({"worker", "main"});
}

TEST_F(LauncherRun, NodeDyingAtStartStopsTheOthersAndFails) {
  write_launch(
      "name: early\nnodes:\n"
      "  - {name: worker, executable: worker.sh}\n"
      "  - {name: bad, executable: bad.sh}\n",
      {{"worker.sh", script::waits_for_sigint(dir_, "worker")},
       {"bad.sh", script::exits_after(dir_, "bad", "worker", 3)}});
  // A generous grace: "bad" exits within milliseconds, however loaded the machine.
  const RunResult r = run_launcher(dir_, args({"--start-grace-ms", "20000"}));
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_TRUE(contains(r.err, "[launcher] node 'bad' died at start: exited with code 3 (a peer never appeared)\n"));
  EXPECT_TRUE(contains(r.err, "[launcher] worker exited with code 0"));
  EXPECT_TRUE(contains(r.err, "launch failed with exit code 3: bad exited with code 3 (a peer never appeared)\n"));
  expect_gone({"worker", "bad"});
}

TEST_F(LauncherRun, FailureAfterTheGraceIsReportedWithoutStoppingTheOthers) {
  write_launch(
      "name: late\nnodes:\n"
      "  - {name: worker, executable: worker.sh}\n"
      "  - {name: late, executable: late.sh}\n",
      {{"worker.sh", script::waits_for_sigint(dir_, "worker")},
       {"late.sh", script::exits_after(dir_, "late", "worker", 3)}});
  LauncherProcess launcher(dir_, args({"--start-grace-ms", "0"}));
  ASSERT_TRUE(wait_until([&] { return contains(launcher.err(), "late exited with code 3"); }, 10s)) << launcher.err();
  // Reaped before it was reported: no zombie.
  expect_gone({"late"});
  const auto worker = dir_.pid_of("worker");
  ASSERT_TRUE(worker.has_value());
  EXPECT_TRUE(process_exists(*worker));
  EXPECT_FALSE(contains(launcher.err(), "stopping"));

  launcher.signal(SIGINT);
  ASSERT_TRUE(launcher.wait_exit());
  EXPECT_EQ(launcher.code(), 3) << launcher.err();
  EXPECT_FALSE(contains(launcher.err(), "died at start"));
  EXPECT_TRUE(contains(launcher.err(), "[launcher] worker exited with code 0"));
  EXPECT_TRUE(
      contains(launcher.err(), "launch failed with exit code 3: late exited with code 3 (a peer never appeared)\n"));
  expect_gone({"worker"});
}

TEST_F(LauncherRun, MissingExecutableStartsNothing) {
  write_launch(
      "name: missing\nnodes:\n"
      "  - {name: worker, executable: worker.sh}\n"
      "  - {name: ghost, executable: no_such_node}\n",
      {{"worker.sh", script::waits_for_sigint(dir_, "worker")}});
  const RunResult r = run_launcher(dir_, args());
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(contains(
      r.err, "[launcher] node 'ghost': executable 'no_such_node' not found (looked in " + dir_.path().string() + ", "));
  EXPECT_TRUE(contains(r.err, "[launcher] missing: nothing started"));
  EXPECT_FALSE(contains(r.err, "worker started"));
  EXPECT_FALSE(dir_.exists("worker.pid"));
}

TEST_F(LauncherRun, ExecFailureInTheChildIsReportedAndStopsTheOthers) {
  write_launch(
      "name: broken\nnodes:\n"
      "  - {name: worker, executable: worker.sh}\n"
      "  - {name: broken, executable: broken}\n"
      "  - {name: after, executable: worker.sh}\n",
      {{"worker.sh", script::waits_for_sigint(dir_, "worker")},
       {"broken", "neither a script nor a program\n"}});  // executable bit set: exec says ENOEXEC
  const RunResult r = run_launcher(dir_, args());
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "[launcher] node 'broken' failed to start: cannot execute '" + dir_.file("broken") +
                                  "': Exec format error"));
  EXPECT_TRUE(contains(r.err, "launch failed with exit code 1: broken could not be executed; after not started\n"));
  EXPECT_FALSE(contains(r.err, "after started"));
  // The worker may have been stopped before its script got as far as its PID file.
  if (const auto pid = dir_.pid_of("worker")) {
    EXPECT_FALSE(process_exists(*pid));
  }
}

// The launcher's exit code is the first failing node's, so a script learns why.

TEST_F(LauncherRun, NodeEndingInTheSafeStateMakesTheLaunchExit5) {
  write_launch(
      "name: safe\nnodes:\n"
      "  - {name: evaluator, executable: evaluator.sh}\n"
      "  - {name: plant_sim, executable: plant.sh, ends_launch: true}\n",
      {{"evaluator.sh", script::waits_for_sigint(dir_, "evaluator")},
       {"plant.sh", script::exits_after(dir_, "plant_sim", "evaluator", 5)}});
  const RunResult r = run_launcher(dir_, args({"--start-grace-ms", "0"}));
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 5) << r.err;
  EXPECT_TRUE(contains(r.err,
                       "[launcher] plant_sim exited with code 5 (ended in the safe state or a "
                       "fault (run not valid))\n"));
  EXPECT_TRUE(contains(r.err,
                       "[launcher] launch failed with exit code 5: plant_sim exited with code 5 "
                       "(ended in the safe state or a fault (run not valid))\n"));
  EXPECT_FALSE(contains(r.err, "ended cleanly")) << r.err;
  expect_gone({"evaluator", "plant_sim"});
}

TEST_F(LauncherRun, NodeConfigErrorMakesTheLaunchExit2) {
  write_launch(
      "name: config\nnodes:\n"
      "  - {name: worker, executable: worker.sh}\n"
      "  - {name: controller, executable: controller.sh}\n",
      {{"worker.sh", script::waits_for_sigint(dir_, "worker")},
       {"controller.sh", script::exits_after(dir_, "controller", "worker", 2)}});
  const RunResult r = run_launcher(dir_, args({"--start-grace-ms", "20000"}));
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_TRUE(
      contains(r.err, "[launcher] node 'controller' died at start: exited with code 2 (bad config or input)\n"));
  EXPECT_TRUE(contains(r.err, "[launcher] worker exited with code 0 (ok)\n"));
  EXPECT_TRUE(contains(r.err, "launch failed with exit code 2: controller exited with code 2 (bad config or input)\n"));
  EXPECT_FALSE(contains(r.err, "ended cleanly"));
  expect_gone({"worker", "controller"});
}

// Two failures in a known order: `first` exits on its own; `second` fails only
// when the launcher stops it because `first` ended the launch. `second` comes
// first in the file, so neither file order nor the larger or smaller code can
// pass for "first in time".
class LauncherTwoFailures : public LauncherRun, public ::testing::WithParamInterface<std::pair<int, int>> {};

TEST_P(LauncherTwoFailures, ExitCodeIsTheFirstFailuresAndBothAreListed) {
  const auto [first_code, second_code] = GetParam();
  write_launch(
      "name: two\nnodes:\n"
      "  - {name: second, executable: second.sh}\n"
      "  - {name: first, executable: first.sh, ends_launch: true}\n",
      {{"second.sh", script::waits_for_sigint(dir_, "second", second_code)},
       {"first.sh", script::exits_after(dir_, "first", "second", first_code)}});
  const RunResult r = run_launcher(dir_, args({"--start-grace-ms", "0"}));
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, first_code) << r.err;
  const auto exit_text = [](const char* name, int code) {
    return std::string(name) + " exited with code " + std::to_string(code) + " (" + pmlsm::exit_code_meaning(code) +
           ")";
  };
  EXPECT_TRUE(contains(r.out, "[second] second stopping on SIGINT"));
  EXPECT_TRUE(contains(r.err, "[launcher] launch failed with exit code " + std::to_string(first_code) +
                                  " (from first, the first to fail): " + exit_text("first", first_code) + "; " +
                                  exit_text("second", second_code) + "\n"));
  EXPECT_FALSE(contains(r.err, "ended cleanly"));
  expect_gone({"first", "second"});
}

INSTANTIATE_TEST_SUITE_P(Codes, LauncherTwoFailures, ::testing::Values(std::pair{4, 5}, std::pair{5, 4}),
                         [](const auto& info) {
                           return "First" + std::to_string(info.param.first) + "Then" +
                                  std::to_string(info.param.second);
                         });

TEST_F(LauncherRun, NodeKilledByASignalTheLauncherDidNotSendExits1) {
  // SIGINT, the very signal the launcher stops with: it counts only when the launcher sent it.
  write_launch("name: selfkill\nnodes:\n  - {name: victim, executable: victim.sh}\n",
               {{"victim.sh", "#!/bin/sh\nkill -INT $$\nsleep 30\n"}});
  const RunResult r = run_launcher(dir_, args({"--start-grace-ms", "0"}));
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "[launcher] victim killed by signal 2 (SIGINT)\n"));
  EXPECT_TRUE(contains(r.err, "launch failed with exit code 1: victim killed by signal 2 (SIGINT)\n"));
  EXPECT_FALSE(contains(r.err, "ended cleanly"));
}

TEST_F(LauncherRun, AllNodesExitingZeroEndCleanly) {
  write_launch(
      "name: fine\nnodes:\n"
      "  - {name: a, executable: ok.sh}\n"
      "  - {name: b, executable: ok.sh}\n"
      "  - {name: c, executable: ok.sh}\n",
      {{"ok.sh", "#!/bin/sh\nexit 0\n"}});
  const RunResult r = run_launcher(dir_, args());
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 0) << r.err;
  for (const char* name : {"a", "b", "c"})
    EXPECT_TRUE(contains(r.err, std::string("[launcher] ") + name + " exited with code 0 (ok)\n"));
  EXPECT_TRUE(contains(r.err, "[launcher] all 3 nodes ended cleanly\n"));
  EXPECT_FALSE(contains(r.err, "launch failed"));
}

class LauncherStopSignal : public LauncherRun, public ::testing::WithParamInterface<int> {};

TEST_P(LauncherStopSignal, IsForwardedAsSigintAndEndsCleanly) {
  write_launch(
      "name: forward\nnodes:\n"
      "  - {name: one, executable: one.sh}\n"
      "  - {name: two, executable: two.sh}\n",
      {{"one.sh", script::waits_for_sigint(dir_, "one")}, {"two.sh", script::waits_for_sigint(dir_, "two")}});
  LauncherProcess launcher(dir_, args());
  ASSERT_TRUE(wait_until([&] { return dir_.exists("one.pid") && dir_.exists("two.pid"); }, 10s)) << launcher.err();
  launcher.signal(GetParam());
  ASSERT_TRUE(launcher.wait_exit());
  EXPECT_EQ(launcher.code(), 0) << launcher.err();
  EXPECT_TRUE(contains(launcher.out(), "[one] one stopping on SIGINT"));
  EXPECT_TRUE(contains(launcher.out(), "[two] two stopping on SIGINT"));
  EXPECT_TRUE(contains(launcher.err(), "[launcher] one exited with code 0"));
  EXPECT_TRUE(contains(launcher.err(), "[launcher] two exited with code 0"));
  expect_gone({"one", "two"});
}

INSTANTIATE_TEST_SUITE_P(Signals, LauncherStopSignal, ::testing::Values(SIGINT, SIGTERM, SIGHUP), [](const auto& info) {
  return std::string(info.param == SIGINT ? "SIGINT" : info.param == SIGTERM ? "SIGTERM" : "SIGHUP");
});

TEST_F(LauncherRun, SigintStopsALauncherStartedWithSigintIgnored) {
  write_launch("name: background\nnodes:\n  - {name: worker, executable: worker.sh}\n",
               {{"worker.sh", script::waits_for_sigint(dir_, "worker")}});
  LauncherProcess launcher(dir_, args(), {SIGINT});
  ASSERT_TRUE(wait_until([&] { return dir_.exists("worker.pid"); }, 10s)) << launcher.err();
  launcher.signal(SIGINT);
  ASSERT_TRUE(launcher.wait_exit());
  EXPECT_EQ(launcher.code(), 0) << launcher.err();
  // The node gets a default SIGINT disposition, whatever the launcher inherited.
  EXPECT_TRUE(contains(launcher.out(), "[worker] worker stopping on SIGINT"));
  expect_gone({"worker"});
}

TEST_F(LauncherRun, ExitStatusesSurviveAnInheritedIgnoredSigchld) {
  write_launch("name: reaper\nnodes:\n  - {name: quitter, executable: quit.sh}\n",
               {{"quit.sh", "#!/bin/sh\nexit 5\n"}});
  LauncherProcess launcher(dir_, args({"--start-grace-ms", "0"}), {SIGCHLD});
  ASSERT_TRUE(launcher.wait_exit()) << launcher.err();
  EXPECT_EQ(launcher.code(), 5) << launcher.err();
  EXPECT_TRUE(contains(launcher.err(), "[launcher] quitter exited with code 5"));
}

TEST_F(LauncherRun, IgnoredSighupIsLeftIgnoredAsUnderNohup) {
  write_launch("name: nohup\nnodes:\n  - {name: worker, executable: worker.sh}\n",
               {{"worker.sh", script::waits_for_sigint(dir_, "worker")}});
  LauncherProcess launcher(dir_, args(), {SIGHUP});
  ASSERT_TRUE(wait_until([&] { return dir_.exists("worker.pid"); }, 10s)) << launcher.err();
  launcher.signal(SIGHUP);
  launcher.signal(SIGINT);  // had SIGHUP counted, it would be reported first
  ASSERT_TRUE(launcher.wait_exit());
  EXPECT_EQ(launcher.code(), 0) << launcher.err();
  EXPECT_FALSE(contains(launcher.err(), "got SIGHUP"));
  EXPECT_TRUE(contains(launcher.err(), "[launcher] got SIGINT\n"));
  expect_gone({"worker"});
}

TEST_F(LauncherRun, SecondSigintKillsAtOnce) {
  write_launch("name: impatient\nnodes:\n  - {name: worker, executable: worker.sh}\n",
               {{"worker.sh", script::ignores_sigint(dir_, "worker")}});
  LauncherProcess launcher(dir_, args({"--stop-timeout-ms", "60000"}));
  ASSERT_TRUE(wait_until([&] { return dir_.exists("worker.pid"); }, 10s)) << launcher.err();
  launcher.signal(SIGINT);
  ASSERT_TRUE(wait_until([&] { return contains(launcher.err(), "stopping 1 node"); }, 10s));
  launcher.signal(SIGINT);
  ASSERT_TRUE(launcher.wait_exit());  // long before the 60 s stop timeout
  EXPECT_EQ(launcher.code(), 1) << launcher.err();
  EXPECT_TRUE(contains(launcher.err(), "[launcher] got SIGINT again; sending SIGKILL"));
  EXPECT_TRUE(contains(launcher.err(), "[launcher] worker killed by signal 9"));
  expect_gone({"worker"});
}

TEST_F(LauncherRun, HostOptionStartsOnlyThatSlice) {
  write_launch(
      "name: split\nhosts: [rig, ctrl]\nnodes:\n"
      "  - {name: plant, executable: say.sh, args: [plant]}\n"
      "  - {name: control, executable: say.sh, args: [control], host: ctrl}\n",
      {{"say.sh", "#!/bin/sh\necho \"$1 ran\"\n"}});
  const RunResult r = run_launcher(dir_, args({"--host", "ctrl"}));
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, "[control] control ran\n");
  EXPECT_TRUE(contains(r.err, "starting 1 node (host ctrl)"));
}

TEST_F(LauncherRun, DryRunPrintsTheResolvedCommandsAndStartsNothing) {
  write_launch(
      "name: dry\nhosts: [rig, ctrl]\nargs: {word: default}\nnodes:\n"
      "  - {name: worker, executable: worker.sh, args: [\"$(arg word)\", \"two words\"],"
      " env: {A_VAR: \"x y\"}, ends_launch: true}\n"
      "  - {name: other, executable: worker.sh, host: ctrl}\n",
      {{"worker.sh", script::waits_for_sigint(dir_, "worker")}});
  const RunResult r = run_launcher(dir_, args({"--dry-run", "--host", "rig", "--arg", "word=hi"}));
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, "# dry (" + dir_.file("launch.yaml") +
                       "), host rig: 1 node\n"
                       "worker (host rig, ends the launch)\n"
                       "  env: A_VAR='x y'\n"
                       "  cmd: " +
                       dir_.file("worker.sh") + " hi 'two words'\n");
  EXPECT_FALSE(dir_.exists("worker.pid"));
}

TEST_F(LauncherRun, DryRunWithMissingExecutableFails) {
  write_launch("name: dry\nnodes:\n  - {name: ghost, executable: no_such_node}\n", {});
  const RunResult r = run_launcher(dir_, args({"--dry-run"}));
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 1);
  EXPECT_TRUE(contains(r.out, "cmd: <executable 'no_such_node' not found (looked in "));
}

TEST_F(LauncherRun, BadLaunchFileExitsWith2NamingFileKeyAndValue) {
  write_launch("name: bad\nhosts: [rig]\nnodes:\n  - {name: a, executable: a.sh, host: ctrl}\n", {});
  const RunResult r = run_launcher(dir_, args());
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(contains(r.err, dir_.file("launch.yaml") + ":4:"));
  EXPECT_TRUE(contains(r.err, "nodes[0].host: 'ctrl' is not among hosts [rig]"));
}

TEST_F(LauncherRun, MissingLaunchFileExitsWith2) {
  const RunResult r = run_launcher(dir_, {dir_.file("nowhere.yaml")});
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(contains(r.err, dir_.file("nowhere.yaml") + ": cannot open launch file"));
}

TEST_F(LauncherRun, UnknownHostExitsWith2ListingTheKnownOnes) {
  write_launch("name: h\nhosts: [rig, ctrl]\nnodes:\n  - {name: a, executable: a.sh}\n", {});
  const RunResult r = run_launcher(dir_, args({"--host", "lab"}));
  ASSERT_TRUE(r.finished);
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(contains(r.err, "--host 'lab': unknown host (known: rig, ctrl)"));
}

TEST_F(LauncherRun, BadOptionsExitWith2) {
  write_launch("name: o\nargs: {word: w}\nnodes:\n  - {name: a, executable: a.sh}\n", {});
  for (const auto& extra : std::vector<std::vector<std::string>>{{"--stop-timeout-ms", "soon"},
                                                                 {"--start-grace-ms", "-5"},
                                                                 {"--arg", "word"},
                                                                 {"--arg", "nosuch=1"},
                                                                 {"--bin-dir", dir_.file("no_such_dir")},
                                                                 {"--no-such-option"}}) {
    const RunResult r = run_launcher(dir_, args(extra));
    ASSERT_TRUE(r.finished);
    EXPECT_EQ(r.code, 2) << extra[0] << "\n" << r.err;
    EXPECT_FALSE(r.err.empty()) << extra[0];
  }
  const RunResult none = run_launcher(dir_, {});
  EXPECT_EQ(none.code, 2);
  const RunResult help = run_launcher(dir_, {"--help"});
  EXPECT_EQ(help.code, 0);
  EXPECT_TRUE(contains(help.out, "--stop-timeout-ms"));
}

}  // namespace

// The control loop split over two hosts: two network namespaces made by the
// test, joined by a veth pair, each with its own /dev/shm, and the UDP-only
// participant profile, so every sample really crosses UDP. The plant runs in
// one, controller, estimator and evaluator in the other; the lockstep trace
// must equal the single-host one. Where namespaces cannot be made (not root,
// no iproute2) the test says so and skips.
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
using test::read_file;
using test::source;

int sh(const std::string& command) { return std::system((command + " >/dev/null 2>&1").c_str()); }

// Two namespaces "<prefix>_rig" and "<prefix>_ctrl" on 10.231.<n>.0/24, removed on destruction.
class TwoHosts {
 public:
  explicit TwoHosts(const std::string& prefix) : rig_(prefix + "_rig"), ctrl_(prefix + "_ctrl") {
    const std::string subnet = "10.231." + std::to_string(getpid() % 250);
    const std::string veth_rig = "vr" + std::to_string(getpid()), veth_ctrl = "vc" + std::to_string(getpid());
    ok_ = sh("ip netns add " + rig_) == 0 && sh("ip netns add " + ctrl_) == 0 &&
          sh("ip link add " + veth_rig + " type veth peer name " + veth_ctrl) == 0 &&
          sh("ip link set " + veth_rig + " netns " + rig_) == 0 &&
          sh("ip link set " + veth_ctrl + " netns " + ctrl_) == 0 && setup(rig_, veth_rig, subnet + ".1") &&
          setup(ctrl_, veth_ctrl, subnet + ".2");
  }
  ~TwoHosts() {
    sh("ip netns del " + rig_);
    sh("ip netns del " + ctrl_);
  }
  bool ok() const { return ok_; }
  const std::string& rig() const { return rig_; }
  const std::string& ctrl() const { return ctrl_; }

 private:
  static bool setup(const std::string& ns, const std::string& veth, const std::string& address) {
    const std::string in = "ip netns exec " + ns + " ";
    return sh(in + "ip link set lo up") == 0 && sh(in + "ip addr add " + address + "/24 dev " + veth) == 0 &&
           sh(in + "ip link set " + veth + " up multicast on") == 0 &&
           sh(in + "ip route add 224.0.0.0/4 dev " + veth) == 0;  // discovery is multicast
  }
  std::string rig_, ctrl_;
  bool ok_ = false;
};

// A node inside a namespace, with a private tmpfs on /dev/shm so no shared
// memory can be shared with the other host.
std::vector<std::string> in_host(const std::string& ns, const std::string& exe, const std::string& domain,
                                 const std::string& scenario, const std::vector<std::string>& extra) {
  std::string command = "mount -t tmpfs tmpfs /dev/shm && exec " + bin(exe) + " --domain " + domain + " --config " +
                        source("configs/system.yaml") + " --scenario " + scenario + " --profiles " +
                        source("configs/dds/profiles.xml") +
                        " --participant-profile pmlsm_udp_only --peer-timeout-s 30";
  for (const auto& e : extra) command += " " + e;
  return {"/usr/sbin/ip", "netns",   "exec", ns,     "/usr/bin/unshare", "--mount", "--propagation",
          "private",      "/bin/sh", "-c",   command};
}

TEST(TwoHosts, LockstepTraceOverUdpEqualsTheSingleHostOne) {
  if (geteuid() != 0) GTEST_SKIP() << "network namespaces need root; not run";
  TwoHosts hosts("pmlsm" + std::to_string(getpid()));
  if (!hosts.ok()) GTEST_SKIP() << "this machine does not allow network namespaces and veth pairs; not run";

  const std::string scenario = source("configs/scenarios/pulse.yaml");
  const fs::path dir = fs::temp_directory_path() / ("pmlsm_two_hosts_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string domain = "7";  // the namespaces are private: no other test can meet it

  test::ChildProcess evaluator(in_host(hosts.ctrl(), "evaluator", domain, scenario, {"--out", dir.string()}),
                               (dir / "evaluator.log").string());
  test::ChildProcess estimator(in_host(hosts.ctrl(), "kalman_estimator", domain, scenario, {}),
                               (dir / "estimator.log").string());
  test::ChildProcess controller(in_host(hosts.ctrl(), "controller", domain, scenario, {}),
                                (dir / "controller.log").string());
  test::ChildProcess plant(in_host(hosts.rig(), "plant_sim", domain, scenario, {"--peers", "3"}),
                           (dir / "plant.log").string());
  for (auto* p : {&plant, &controller, &estimator, &evaluator}) {
    const auto code = p->wait_for(std::chrono::seconds(120));
    ASSERT_TRUE(code.has_value()) << "still running:\n" << p->output();
    EXPECT_EQ(*code, 0) << p->output();
  }
  const SystemParams params = load_system_params(source("configs/system.yaml"));
  write_trace_csv((dir / "single_host.csv").string(),
                  run_scenario(params, load_scenario(scenario, params.timing.control_period_s)));
  const std::string distributed = read_file(dir / "pulse.csv");
  ASSERT_FALSE(distributed.empty()) << evaluator.output();
  EXPECT_TRUE(distributed == read_file(dir / "single_host.csv")) << "traces differ (" << dir << ")";
  std::printf("[ two hosts  ] %s", plant.output().c_str());
  fs::remove_all(dir);
}

/// The launcher inside a namespace, its own /dev/shm, the shipped files by absolute path.
std::vector<std::string> launcher_in_host(const std::string& ns, const std::string& host,
                                          const std::vector<std::string>& args) {
  std::string command = "mount -t tmpfs tmpfs /dev/shm && exec " + bin("launcher") + " " +
                        source("launch/rig_split.yaml") + " --host " + host;
  for (const auto& a : args) command += " " + a;
  return {"/usr/sbin/ip", "netns",   "exec", ns,     "/usr/bin/unshare", "--mount", "--propagation",
          "private",      "/bin/sh", "-c",   command};
}

/// The number after `key` in `text` (-1 when absent).
long long number_after(const std::string& text, const std::string& key) {
  const auto at = text.find(key);
  if (at == std::string::npos) return -1;
  return std::atoll(text.c_str() + at + key.size());
}

/// A short pulse scenario in `dir`.
std::string three_second_pulse(const fs::path& dir) {
  std::string scenario = read_file(source("configs/scenarios/pulse.yaml"));
  const auto at = scenario.find("duration_s:");
  scenario.replace(at, scenario.find('\n', at) - at, "duration_s: 3.0");
  std::ofstream(dir / "three_s.yaml") << scenario;
  return (dir / "three_s.yaml").string();
}

/// Both hosts' slices of launch/rig_split.yaml (RNN compensator, 3 s realtime) with `extra` args;
/// their exit codes and outputs.
struct SplitRun {
  int rig_code = -1, ctrl_code = -1;
  std::string rig, ctrl;
};
SplitRun run_split(const TwoHosts& hosts, const fs::path& dir, const std::string& scenario,
                   const std::vector<std::string>& extra) {
  // A watchdog and loss windows on the rig that the loaded CI host cannot trip by holding the rig's
  // process (controller and drive share its chain thread; held 50 ms, each finds the other silent):
  // what is checked is that nothing from the other host is waited for (bench/rig_split_bench.sh
  // holds the 3 ms watchdog and the 50 ms windows).
  std::vector<std::string> args = {"--arg domain=8",
                                   "--arg profile=pmlsm_udp_only",
                                   "--arg config=" + source("configs/system.yaml"),
                                   "--arg scenario=" + scenario,
                                   "--arg profiles=" + source("configs/dds/profiles.xml"),
                                   "--arg weights=" + source("configs/rnn_weights.yaml"),
                                   "--arg out=" + dir.string(),
                                   "--arg compensator=rnn",
                                   "--arg watchdog_ms=1000",
                                   "--arg rig_peer_lost_ms=1000"};
  args.insert(args.end(), extra.begin(), extra.end());
  test::ChildProcess ctrl(launcher_in_host(hosts.ctrl(), "ctrl", args), (dir / "ctrl.log").string());
  test::ChildProcess rig(launcher_in_host(hosts.rig(), "rig", args), (dir / "rig.log").string());
  SplitRun run;
  const auto rig_code = rig.wait_for(std::chrono::seconds(120));
  const auto ctrl_code = ctrl.wait_for(std::chrono::seconds(120));
  run.rig_code = rig_code.value_or(-1);
  run.ctrl_code = ctrl_code.value_or(-1);
  run.rig = rig.output();
  run.ctrl = ctrl.output();
  return run;
}

/// The controller's compensation after the start (the first one on time): the share of ticks on time.
double on_time_after_start(const std::string& rig_out, long long ticks) {
  const long long without = number_after(rig_out, "compensation rnn (");
  const long long at_start = number_after(rig_out, "ticks without; at the start ");
  if (without < 0 || at_start < 0 || at_start >= ticks) return -1.0;
  return 1.0 - static_cast<double>(without - at_start) / static_cast<double>(ticks - at_start);
}

/// The drive's median chain latency (its feedback to the controller's command), us; -1 if not printed.
double chain_latency_p50_us(const std::string& rig_out) {
  const auto at = rig_out.find("chain latency feedback -> command over ");
  if (at == std::string::npos) return -1.0;
  const auto p50 = rig_out.find("p50 ", at);
  return p50 == std::string::npos ? -1.0 : std::atof(rig_out.c_str() + p50 + 4);
}

/// What the rig's slice shows whatever the load on the host: it ran its ticks without a watchdog
/// trip, the controller answered each feedback from its own process (a median answer far below the
/// 250 us publisher period and a UDP round trip to ctrl: a chain that waited for the other host
/// could not answer in 100 us; 12-21 us here, loaded or not) and used compensation from ctrl
/// (on time for some ticks). How many ticks it was on time depends on how much of the two cores
/// ctrl's processes got; it is printed, and bench/rig_split_bench.sh holds its targets.
void expect_rig_held(const SplitRun& run, const char* what) {
  EXPECT_EQ(run.rig.find("watchdog: tick"), std::string::npos) << run.rig;
  EXPECT_NE(run.rig.find("3000 ticks in"), std::string::npos) << run.rig;
  const double p50_us = chain_latency_p50_us(run.rig);
  EXPECT_GE(p50_us, 0.0) << run.rig;
  EXPECT_LT(p50_us, 100.0) << run.rig;
  const double on_time = on_time_after_start(run.rig, 3000);
  EXPECT_GT(on_time, 0.0) << run.rig;
  std::printf(
      "[ rig split  ] %s: chain latency p50 %.1f us, compensation on time in %.1f %% of the ticks after the first\n",
      what, p50_us, on_time * 100.0);
}

// launch/rig_split.yaml across two hosts in realtime: the drive and the controller composed on the
// rig, estimator, RNN compensator and evaluator on ctrl, every sample between them over UDP.
// Reliable inputs on a clean link: the chain holds (no watchdog trip, answered from its own
// process), the run is valid on both hosts and the compensation from the other host is used. Best-effort inputs
// (the file's default) with 2 % of the packets dropped at random (nftables, where the machine
// has it): the rig still holds and uses the compensation, while the evaluator on ctrl
// names the ticks that were never estimated and ends 4: a lossy run never looks clean.
TEST(TwoHosts, TheRigSplitHoldsInRealtimeWithTheCompensatorOnTheOtherHost) {
  if (geteuid() != 0) GTEST_SKIP() << "network namespaces need root; not run";
  TwoHosts hosts("pmlsmsplit" + std::to_string(getpid()));
  if (!hosts.ok()) GTEST_SKIP() << "this machine does not allow network namespaces and veth pairs; not run";
  const fs::path dir = fs::temp_directory_path() / ("pmlsm_rig_split_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string scenario = three_second_pulse(dir);

  const SplitRun clean = run_split(hosts, dir, scenario, {"--arg realtime_inputs=reliable"});
  EXPECT_EQ(clean.rig_code, 0) << clean.rig;
  // The evaluator on ctrl scores the run, unless one of its readers matched the rig's writer after
  // the first ticks went out: the rig's container hands DDS only what it writes once a reader
  // outside is matched, and the drive does not wait for the evaluator's ForceCommand reader. It
  // then names the first ticks missing and ends 4 (seen in 1 of 10 runs here).
  if (clean.ctrl_code != 0) {
    EXPECT_EQ(clean.ctrl_code, 4) << clean.ctrl;
    EXPECT_NE(clean.ctrl.find("ticks, the first 0"), std::string::npos) << clean.ctrl;
  }
  expect_rig_held(clean, "clean link, reliable inputs");
  if (clean.ctrl_code == 0) {
    EXPECT_NE(clean.ctrl.find("rig_split"), std::string::npos) << clean.ctrl;  // the evaluator's row
  }

  if (sh("command -v nft") != 0) {
    std::printf(
        "[ rig split  ] nft not found: the lossy link is not tried (scripts/install_deps.sh installs nftables)\n");
    fs::remove_all(dir);
    return;
  }
  for (const std::string& ns : {hosts.rig(), hosts.ctrl()}) {
    const std::string nft = "ip netns exec " + ns + " nft ";
    if (sh(nft + "add table inet pmlsm_test") != 0 ||
        sh(nft + "'add chain inet pmlsm_test input { type filter hook input priority 0; policy accept; }'") != 0 ||
        sh(nft + "add rule inet pmlsm_test input iifname != lo numgen random mod 100 '<' 2 drop") != 0) {
      std::printf("[ rig split  ] this kernel refuses nftables rules in a namespace: the lossy link is not tried\n");
      fs::remove_all(dir);
      return;
    }
  }
  const SplitRun lossy = run_split(hosts, dir, scenario, {});
  EXPECT_EQ(lossy.rig_code, 0) << lossy.rig;
  expect_rig_held(lossy, "2 % of the packets dropped, best-effort inputs");
  for (const char* node :
       {"[launcher] kalman_estimator exited with code 0", "[launcher] rnn_compensator exited with code 0"}) {
    EXPECT_NE(lossy.ctrl.find(node), std::string::npos) << lossy.ctrl;
  }
  if (lossy.ctrl_code != 0) {
    EXPECT_EQ(lossy.ctrl_code, 4) << lossy.ctrl;
    EXPECT_NE(lossy.ctrl.find("EstimatedState missing for"), std::string::npos) << lossy.ctrl;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace pmlsm

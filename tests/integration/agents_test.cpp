// Launch agents across hosts: three network namespaces made by the test (a launcher host and
// two agent hosts, "rig" and "ctrl") on a bridge in a fourth, each host with its own /dev/shm
// and the UDP-only profile, so requests, output and samples really cross UDP. Where namespaces
// cannot be made (not root, no iproute2) those tests say so and skip. The refusals that need no
// second host run on loopback.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "child_process.hpp"
#include "integration_support.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "trace_csv.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;
using std::chrono::seconds;
using test::bin;
using test::read_file;
using test::source;

int sh(const std::string& command) { return std::system((command + " >/dev/null 2>&1").c_str()); }

// Namespaces "<prefix>_<host>" joined by veth pairs to a bridge in "<prefix>_sw", on
// 10.232.<n>.0/24; removed on destruction.
class Hosts {
 public:
  Hosts(const std::string& prefix, const std::vector<std::string>& names) : prefix_(prefix) {
    const std::string subnet = "10.232." + std::to_string(getpid() % 250);
    const std::string sw = prefix + "_sw";
    namespaces_.push_back(sw);
    ok_ = sh("ip netns add " + sw) == 0 && sh("ip -n " + sw + " link add br0 type bridge mcast_snooping 0") == 0 &&
          sh("ip -n " + sw + " link set br0 up") == 0;
    for (std::size_t i = 0; ok_ && i < names.size(); ++i) {
      const std::string ns = prefix + "_" + names[i];
      const std::string veth = "va" + std::to_string(getpid()) + "_" + std::to_string(i);
      const std::string port = "vb" + std::to_string(getpid()) + "_" + std::to_string(i);
      const std::string in = "ip netns exec " + ns + " ";
      namespaces_.push_back(ns);
      ok_ = sh("ip netns add " + ns) == 0 && sh("ip link add " + veth + " type veth peer name " + port) == 0 &&
            sh("ip link set " + veth + " netns " + ns) == 0 && sh("ip link set " + port + " netns " + sw) == 0 &&
            sh("ip -n " + sw + " link set " + port + " master br0 up") == 0 && sh(in + "ip link set lo up") == 0 &&
            sh(in + "ip addr add " + subnet + "." + std::to_string(i + 1) + "/24 dev " + veth) == 0 &&
            sh(in + "ip link set " + veth + " up multicast on") == 0 &&
            sh(in + "ip route add 224.0.0.0/4 dev " + veth) == 0;  // discovery is multicast
    }
  }
  ~Hosts() {
    for (const auto& ns : namespaces_) sh("ip netns del " + ns);
  }
  bool ok() const { return ok_; }
  // `command` run in host `name`'s namespace with a private tmpfs on /dev/shm.
  std::vector<std::string> in(const std::string& name, const std::string& command) const {
    return {"/usr/sbin/ip",
            "netns",
            "exec",
            prefix_ + "_" + name,
            "/usr/bin/unshare",
            "--mount",
            "--propagation",
            "private",
            "/bin/sh",
            "-c",
            "mount -t tmpfs tmpfs /dev/shm && exec " + command};
  }

 private:
  std::string prefix_;
  std::vector<std::string> namespaces_;
  bool ok_ = false;
};

std::string dds_args(const std::string& domain) {
  return " --domain " + domain + " --profiles " + source("configs/dds/profiles.xml") +
         " --participant-profile pmlsm_udp_only";
}

std::string agent_command(const std::string& host, const std::string& domain, const std::string& security) {
  return bin("launch_agent") + " --host " + host + dds_args(domain) + " --work-dir " + source("") + " " + security;
}

// two_hosts.yaml through the agents, over UDP, writing its trace to `out`.
std::string launcher_command(const std::string& domain, const fs::path& out, const std::string& extra = "") {
  return bin("launcher") + " " + source("launch/two_hosts.yaml") + " --agents" + dds_args(domain) +
         " --keystore none --arg profile=pmlsm_udp_only --arg domain=" + domain + " --arg out=" + out.string() +
         " --arg keystore=none " + extra;
}

#define REQUIRE_HOSTS(hosts)                                                    \
  if (geteuid() != 0) GTEST_SKIP() << "network namespaces need root; not run";  \
  if (!(hosts).ok())                                                            \
  GTEST_SKIP() << "this machine does not allow network namespaces, veth pairs " \
                  "and a bridge; not run"

TEST(AgentHosts, LockstepRunThroughTwoAgentsEqualsTheSingleHostTrace) {
  const Hosts hosts("pa" + std::to_string(getpid()), {"launch", "rig", "ctrl"});
  REQUIRE_HOSTS(hosts);
  const fs::path dir = test::fresh_dir("pmlsm_agents", "lockstep");
  const std::string domain = test::test_domain(80);
  test::ChildProcess rig(hosts.in("rig", agent_command("rig", domain, "--insecure")), (dir / "rig.log").string());
  test::ChildProcess ctrl(hosts.in("ctrl", agent_command("ctrl", domain, "--insecure")), (dir / "ctrl.log").string());
  ASSERT_TRUE(rig.wait_for_output("launch_agent: host rig", seconds(20))) << rig.output();
  ASSERT_TRUE(ctrl.wait_for_output("launch_agent: host ctrl", seconds(20))) << ctrl.output();

  const auto t0 = std::chrono::steady_clock::now();
  test::ChildProcess launcher(hosts.in("launch", launcher_command(domain, dir)), (dir / "launcher.log").string());
  // plant_sim prints this once its 3 peers (controller, estimator, evaluator on ctrl) matched.
  ASSERT_TRUE(launcher.wait_for_output("peers matched", seconds(60))) << launcher.output();
  const double matched_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto code = launcher.wait_for(seconds(120));
  ASSERT_TRUE(code.has_value()) << launcher.output();
  EXPECT_EQ(*code, 0) << launcher.output();
  const std::string log = launcher.output();
  EXPECT_NE(log.find("[rig/plant_sim]"), std::string::npos) << log;
  EXPECT_NE(log.find("[ctrl/evaluator] pulse"), std::string::npos) << log;

  const SystemParams params = load_system_params(source("configs/system.yaml"));
  const std::string scenario = source("configs/scenarios/pulse.yaml");
  write_trace_csv((dir / "single_host.csv").string(),
                  run_scenario(params, load_scenario(scenario, params.timing.control_period_s)));
  const std::string distributed = read_file(dir / "pulse.csv");
  ASSERT_FALSE(distributed.empty()) << log;
  EXPECT_TRUE(distributed == read_file(dir / "single_host.csv")) << "traces differ (" << dir << ")";
  std::printf("[ agents     ] all nodes on 2 agent hosts matched %.2f s after the launch command (target 3 s)\n",
              matched_s);
  rig.signal(SIGINT);
  ctrl.signal(SIGINT);
  EXPECT_EQ(rig.wait_for(seconds(10)), 0) << rig.output();
  EXPECT_EQ(ctrl.wait_for(seconds(10)), 0) << ctrl.output();
  fs::remove_all(dir);
}

TEST(AgentHosts, AKilledAgentIsReportedAndTheOtherHostIsStopped) {
  const Hosts hosts("pk" + std::to_string(getpid()), {"launch", "rig", "ctrl"});
  REQUIRE_HOSTS(hosts);
  const fs::path dir = test::fresh_dir("pmlsm_agents", "killed");
  const std::string domain = test::test_domain(81);
  test::ChildProcess rig(hosts.in("rig", agent_command("rig", domain, "--insecure")), (dir / "rig.log").string());
  test::ChildProcess ctrl(hosts.in("ctrl", agent_command("ctrl", domain, "--insecure")), (dir / "ctrl.log").string());
  ASSERT_TRUE(rig.wait_for_output("launch_agent: host rig", seconds(20))) << rig.output();
  ASSERT_TRUE(ctrl.wait_for_output("launch_agent: host ctrl", seconds(20))) << ctrl.output();
  // Realtime and a plant that stays up without its controller: only the launcher can end the rig's slice.
  test::ChildProcess launcher(
      hosts.in("launch", launcher_command(domain, dir, "--arg clock=realtime --arg on_controller_lost=stay")),
      (dir / "launcher.log").string());
  ASSERT_TRUE(launcher.wait_for_output("peers matched", seconds(60))) << launcher.output();
  const auto killed = std::chrono::steady_clock::now();
  ctrl.signal(SIGKILL);
  const auto code = launcher.wait_for(seconds(30));
  ASSERT_TRUE(code.has_value()) << launcher.output();
  const double noticed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count();
  const std::string log = launcher.output();
  EXPECT_EQ(*code, 4) << log;  // a peer was lost
  EXPECT_NE(log.find("ctrl: agent lost"), std::string::npos) << log;
  EXPECT_NE(log.find("host rig: slice ended"), std::string::npos) << log;
  EXPECT_LT(noticed_s, 15.0) << log;
  std::printf("[ agents     ] killed agent: launch over %.2f s after the kill (lease 2 s, stop 5 s)\n", noticed_s);
  rig.signal(SIGINT);
  EXPECT_EQ(rig.wait_for(seconds(10)), 0) << rig.output();
  fs::remove_all(dir);
}

TEST(AgentHosts, AnUnauthenticatedLauncherFindsNoSecuredAgentAndNothingStarts) {
  const Hosts hosts("pu" + std::to_string(getpid()), {"launch", "rig"});
  REQUIRE_HOSTS(hosts);
  const fs::path dir = test::fresh_dir("pmlsm_agents", "unauthenticated");
  const fs::path keystore = dir / "keystore";
  ASSERT_EQ(sh(bin("pmlsm") + " security create " + keystore.string() + " --policy " +
               source("configs/security/policy.yaml")),
            0);
  const std::string domain = test::test_domain(82);
  test::ChildProcess rig(hosts.in("rig", agent_command("rig", domain, "--keystore " + keystore.string())),
                         (dir / "rig.log").string());
  ASSERT_TRUE(rig.wait_for_output("launch_agent: host rig, identity launch_agent", seconds(20))) << rig.output();
  const fs::path slice = dir / "one.yaml";
  std::ofstream(slice) << "name: one\nhosts: [rig]\nnodes:\n  - name: loop\n    executable: closed_loop\n"
                          "    args: [-s, configs/scenarios/pulse.yaml]\n";
  const std::string base = bin("launcher") + " " + slice.string() + " --agents" + dds_args(domain) + " ";
  test::ChildProcess open(hosts.in("launch", base + "--agent-wait-ms 6000 --keystore none"),
                          (dir / "open.log").string());
  const auto open_code = open.wait_for(seconds(30));
  ASSERT_TRUE(open_code.has_value()) << open.output();
  EXPECT_EQ(*open_code, 3) << open.output();  // a peer never appeared
  EXPECT_NE(open.output().find("rig: no agent announced this host"), std::string::npos) << open.output();
  EXPECT_EQ(rig.output().find("started for"), std::string::npos) << rig.output();

  // The launcher's identity may; with it the same slice runs (PKI-DH handshakes take seconds on a loaded machine).
  test::ChildProcess secure(hosts.in("launch", base + "--agent-wait-ms 30000 --keystore " + keystore.string()),
                            (dir / "secure.log").string());
  const auto secure_code = secure.wait_for(seconds(60));
  ASSERT_TRUE(secure_code.has_value()) << secure.output();
  EXPECT_EQ(*secure_code, 0) << secure.output() << rig.output();
  rig.signal(SIGINT);
  EXPECT_EQ(rig.wait_for(seconds(10)), 0) << rig.output();
  fs::remove_all(dir);
}

// On loopback: a host without an agent, an executable outside the allowed set, an agent without keystore.
TEST(Agents, AHostWithoutAnAgentIsNamedAndNothingStarts) {
  const fs::path dir = test::fresh_dir("pmlsm_agents", "no_agent");
  const std::string domain = test::test_domain(83);
  test::ChildProcess rig({bin("launch_agent"), "--host", "rig", "--domain", domain, "--profiles",
                          source("configs/dds/profiles.xml"), "--insecure", "--keystore", "none"},
                         (dir / "rig.log").string());
  ASSERT_TRUE(rig.wait_for_output("launch_agent: host rig", seconds(20))) << rig.output();
  test::ChildProcess launcher({bin("launcher"), source("launch/two_hosts.yaml"), "--agents", "--domain", domain,
                               "--profiles", source("configs/dds/profiles.xml"), "--keystore", "none",
                               "--agent-wait-ms", "3000", "--arg", "domain=" + domain},
                              (dir / "launcher.log").string());
  const auto code = launcher.wait_for(seconds(30));
  ASSERT_TRUE(code.has_value()) << launcher.output();
  EXPECT_EQ(*code, 3) << launcher.output();
  EXPECT_NE(launcher.output().find("ctrl: no agent announced this host within 3000 ms; nothing started"),
            std::string::npos)
      << launcher.output();
  EXPECT_EQ(rig.output().find("started for"), std::string::npos) << rig.output();
  rig.signal(SIGINT);
  EXPECT_EQ(rig.wait_for(seconds(10)), 0) << rig.output();
  fs::remove_all(dir);
}

TEST(Agents, AnExecutableOutsideTheAllowedSetIsRefusedAndReported) {
  const fs::path dir = test::fresh_dir("pmlsm_agents", "refused");
  const std::string domain = test::test_domain(84);
  test::ChildProcess rig({bin("launch_agent"), "--host", "rig", "--domain", domain, "--profiles",
                          source("configs/dds/profiles.xml"), "--insecure", "--keystore", "none"},
                         (dir / "rig.log").string());
  ASSERT_TRUE(rig.wait_for_output("launch_agent: host rig", seconds(20))) << rig.output();
  const fs::path marker = dir / "touched";
  for (const std::string executable : {"/bin/sh", "launcher"}) {
    const fs::path file = dir / "evil.yaml";
    std::ofstream(file) << "name: evil\nhosts: [rig]\nnodes:\n  - name: loop\n    executable: closed_loop\n"
                           "    args: [-s, configs/scenarios/pulse.yaml]\n  - name: evil\n    executable: "
                        << executable << "\n    args: [-c, 'touch " << marker.string() << "']\n";
    test::ChildProcess launcher({bin("launcher"), file.string(), "--agents", "--domain", domain, "--profiles",
                                 source("configs/dds/profiles.xml"), "--keystore", "none"},
                                (dir / "launcher.log").string());
    const auto code = launcher.wait_for(seconds(30));
    ASSERT_TRUE(code.has_value()) << launcher.output();
    EXPECT_EQ(*code, 2) << launcher.output();
    EXPECT_NE(launcher.output().find("refused: node 'evil': executable '" + executable + "'"), std::string::npos)
        << launcher.output();
    EXPECT_FALSE(fs::exists(marker));
  }
  EXPECT_EQ(rig.output().find("started for"), std::string::npos) << rig.output();
  rig.signal(SIGINT);
  EXPECT_EQ(rig.wait_for(seconds(10)), 0) << rig.output();
  fs::remove_all(dir);
}

TEST(Agents, AnAgentWithoutKeystoreRefusesToStartUnlessInsecure) {
  const fs::path dir = test::fresh_dir("pmlsm_agents", "no_keystore");
  test::ChildProcess agent({bin("launch_agent"), "--domain", test::test_domain(85), "--keystore", "none"},
                           (dir / "agent.log").string());
  const auto code = agent.wait_for(seconds(10));
  ASSERT_TRUE(code.has_value());
  EXPECT_EQ(*code, 2);
  EXPECT_NE(agent.output().find("refusing to start without a keystore"), std::string::npos) << agent.output();
  EXPECT_NE(agent.output().find("--insecure"), std::string::npos) << agent.output();
  fs::remove_all(dir);
}

}  // namespace
}  // namespace pmlsm

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

}  // namespace
}  // namespace pmlsm

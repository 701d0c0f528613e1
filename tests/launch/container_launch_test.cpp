// Containers in launch files (`containers:`) and the container's command line: which nodes
// share a process, what the launcher runs for them, and every malformed entry refused with
// its place in the file. No process is started.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "container_spec.hpp"
#include "launch_test_support.hpp"
#include "launch_file.hpp"

namespace {

using namespace pmlsm::launch;
using pmlsm::container::ComponentSpec;
using pmlsm::container::ContainerSpecError;
using pmlsm::container::split_container_command_line;

const char* const kComposable = R"yaml(name: sim
args:
  compose: "true"
  clock: lockstep
nodes:
  - name: evaluator
    executable: evaluator
    ends_launch: true
    args: [--clock, $(arg clock)]
  - name: recorder
    executable: pmlsm
    args: [record]
  - name: controller
    executable: controller
    args: [--clock, $(arg clock)]
  - name: plant_sim
    executable: plant_sim
    args: [--clock, $(arg clock), --peers, "2"]
containers:
  - name: chain
    if: $(arg compose)
    components: [plant_sim, controller, evaluator]
    args: [--rt-priority, "0"]
)yaml";

using launch_test::error_of;

TEST(ContainerLaunch, AContainerReplacesItsComponentsByOneNodeAtTheFirstOnesPlace) {
  const LaunchDescription d = parse_launch(kComposable, "launch.yaml");
  ASSERT_EQ(d.nodes.size(), 2u);
  const NodeSpec& chain = d.nodes[0];
  EXPECT_EQ(chain.name, "chain");
  EXPECT_EQ(chain.executable, "container");
  EXPECT_TRUE(chain.ends_launch);  // the evaluator ends the launch, so its container does
  EXPECT_EQ(chain.components, (std::vector<std::string>{"plant_sim", "controller", "evaluator"}));
  EXPECT_EQ(d.nodes[1].name, "recorder");  // outside: its own process
  // The container's own options, then each component's command line in the order of `nodes`.
  const std::vector<std::string> expected = {
      "--name",      "chain",     "--rt-priority", "0",          "--component", "evaluator", "evaluator",
      "--clock",     "lockstep",  "--component",   "controller", "controller",  "--clock",   "lockstep",
      "--component", "plant_sim", "plant_sim",     "--clock",    "lockstep",    "--peers",   "2"};
  EXPECT_EQ(chain.args, expected);
  // What the container reads back from that command line.
  const auto line = split_container_command_line(std::vector<std::string>(chain.args.begin(), chain.args.end()),
                                                 {"plant_sim", "controller", "evaluator"});
  EXPECT_EQ(line.own_args, (std::vector<std::string>{"--name", "chain", "--rt-priority", "0"}));
  ASSERT_EQ(line.components.size(), 3u);
  EXPECT_EQ(line.components[2].name, "plant_sim");
  EXPECT_EQ(line.components[2].args, (std::vector<std::string>{"--clock", "lockstep", "--peers", "2"}));
}

TEST(ContainerLaunch, ComposeFalseKeepsOneProcessPerNode) {
  const LaunchDescription d = parse_launch(kComposable, "launch.yaml", {{"compose", "false"}});
  ASSERT_EQ(d.nodes.size(), 4u);
  for (const auto& n : d.nodes) EXPECT_TRUE(n.components.empty()) << n.name;
  EXPECT_NE(std::find(d.left_out.begin(), d.left_out.end(), "chain"), d.left_out.end());
}

TEST(ContainerLaunch, AComponentLeftOutByItsOwnIfIsSkipped) {
  std::string text = kComposable;
  text.replace(text.find("  - name: controller\n"), 21, "  - name: controller\n    if: \"false\"\n");
  const LaunchDescription d = parse_launch(text, "launch.yaml");
  EXPECT_EQ(d.nodes[0].components, (std::vector<std::string>{"plant_sim", "evaluator"}));
}

TEST(ContainerLaunch, MalformedContainersAreRefusedWithTheirPlace) {
  const std::string base = kComposable;
  const auto with_components = [&](const std::string& list) {
    std::string t = base;
    t.replace(t.find("[plant_sim, controller, evaluator]"), 34, list);
    return t;
  };
  EXPECT_NE(
      error_of(with_components("[plant_sim, nowhere]")).find("containers[0].components[1]: 'nowhere' is not a node"),
      std::string::npos);
  EXPECT_NE(error_of(with_components("[]")).find("must list at least one node"), std::string::npos);
  // Checked when the container is left out too.
  EXPECT_NE(error_of(with_components("[plant_sim, nowhere]"), {{"compose", "false"}}).find("'nowhere' is not a node"),
            std::string::npos);
  // A node in two containers.
  std::string twice = base + "  - name: other\n    components: [controller]\n";
  EXPECT_NE(error_of(twice).find("'controller' is already in a container"), std::string::npos);
  // A container named like a node, or like another container.
  std::string clash = base;
  clash.replace(clash.find("  - name: chain"), 15, "  - name: recorder");
  EXPECT_NE(error_of(clash).find("'recorder' is already the name of a node"), std::string::npos);
  std::string dup = base + "  - name: chain\n    components: [recorder]\n";
  EXPECT_NE(error_of(dup).find("'chain' is already the name of a container"), std::string::npos);
  // Unknown keys, as everywhere in a launch file.
  std::string unknown = base;
  unknown.replace(unknown.find("    if: $(arg compose)"), 22, "    threads: \"2\"");
  EXPECT_NE(error_of(unknown).find("containers[0].threads: unknown key"), std::string::npos);
  // A component with its own environment: a container is one process.
  std::string env = base;
  env.replace(env.find("    args: [--clock, $(arg clock), --peers"), 0, "    env: {A: b}\n");
  EXPECT_NE(error_of(env).find("'plant_sim' sets env"), std::string::npos);
}

TEST(ContainerLaunch, ComponentsOnTwoHostsNeedTheContainersOwnHost) {
  const std::string two_hosts = R"yaml(name: rig
hosts: [ctrl, rig]
nodes:
  - name: controller
    executable: controller
    host: ctrl
  - name: drive_bridge
    executable: drive_bridge
    host: rig
containers:
  - name: rig_chain
    components: [drive_bridge, controller]
)yaml";
  EXPECT_NE(error_of(two_hosts).find("'controller' is on host ctrl, the container on rig"), std::string::npos);
  const LaunchDescription d = parse_launch(two_hosts + "    host: rig\n", "launch.yaml");
  ASSERT_EQ(d.nodes.size(), 1u);
  EXPECT_EQ(d.nodes[0].host, "rig");  // the controller moves to the rig with its container
  EXPECT_NE(error_of(two_hosts + "    host: lab\n").find("'lab' is not among hosts"), std::string::npos);
}

TEST(ContainerCommandLine, RefusesNoComponentUnknownTypesAndNamesUsedTwice) {
  const std::vector<std::string> known = {"plant_sim", "controller"};
  const auto error = [&](const std::vector<std::string>& args) -> std::string {
    try {
      split_container_command_line(args, known);
    } catch (const ContainerSpecError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(error({"--name", "x"}).find("no component"), std::string::npos);
  EXPECT_NE(error({"--component", "a", "turbine"})
                .find("component 'a': unknown type 'turbine' (a container runs: "
                      "plant_sim, controller)"),
            std::string::npos);
  EXPECT_NE(error({"--component", "a", "plant_sim", "--component", "a", "controller"})
                .find("component name 'a' is used twice (plant_sim and controller)"),
            std::string::npos);
  EXPECT_NE(error({"--component", "a"}).find("needs a NAME and a TYPE"), std::string::npos);
  EXPECT_NE(error({"--component", "a b", "plant_sim"}).find("must be [A-Za-z0-9_-]+"), std::string::npos);
  const auto round_trip = pmlsm::container::container_command_line(
      {"--name", "c"},
      {ComponentSpec{"p", "plant_sim", {"--clock", "realtime"}}, ComponentSpec{"c", "controller", {}}});
  const auto line = split_container_command_line(round_trip, known);
  ASSERT_EQ(line.components.size(), 2u);
  EXPECT_EQ(line.components[0].args, (std::vector<std::string>{"--clock", "realtime"}));
  EXPECT_TRUE(line.components[1].args.empty());
}

}  // namespace

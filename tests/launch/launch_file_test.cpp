// Launch-file parsing and validation, arg substitution, host slicing,
// executable lookup and the line relay, without starting processes.
#include "launch_file.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>

#include "launch_test_support.hpp"
#include "supervisor.hpp"

namespace {

using namespace pmlsm::launch;

const char* const kExample = R"yaml(name: pulse_lockstep
hosts: [rig, ctrl]
nodes:
  - name: plant
    executable: plant_sim
    host: rig
    args: ["--clock", "lockstep", "--scenario", "$(arg scenario)"]
    env: {FASTDDS_DEFAULT_PROFILES_FILE: configs/dds/profiles.xml}
    ends_launch: true
  - name: controller
    executable: ./bin/controller
    host: ctrl
args:
  scenario: configs/scenarios/pulse.yaml
)yaml";

LaunchDescription parse(const std::string& text, const ArgOverrides& overrides = {}) {
  return parse_launch(text, "launch.yaml", overrides);
}

using launch_test::error_of;

TEST(LaunchFile, ParsesEveryField) {
  const LaunchDescription d = parse(kExample);
  EXPECT_EQ(d.source, "launch.yaml");
  EXPECT_EQ(d.name, "pulse_lockstep");
  EXPECT_EQ(d.hosts, (std::vector<std::string>{"rig", "ctrl"}));
  ASSERT_EQ(d.nodes.size(), 2u);
  const NodeSpec& plant = d.nodes[0];
  EXPECT_EQ(plant.name, "plant");
  EXPECT_EQ(plant.executable, "plant_sim");
  EXPECT_EQ(plant.host, "rig");
  EXPECT_EQ(plant.args,
            (std::vector<std::string>{"--clock", "lockstep", "--scenario", "configs/scenarios/pulse.yaml"}));
  ASSERT_EQ(plant.env.size(), 1u);
  EXPECT_EQ(plant.env[0].first, "FASTDDS_DEFAULT_PROFILES_FILE");
  EXPECT_EQ(plant.env[0].second, "configs/dds/profiles.xml");
  EXPECT_TRUE(plant.ends_launch);
  EXPECT_EQ(d.nodes[1].name, "controller");
  EXPECT_EQ(d.nodes[1].executable, "./bin/controller");
  EXPECT_EQ(d.nodes[1].host, "ctrl");
  EXPECT_EQ(d.args.at("scenario"), "configs/scenarios/pulse.yaml");
}

TEST(LaunchFile, DefaultsToOneLocalHostAndEmptyOptionals) {
  const LaunchDescription d = parse("name: n\nnodes:\n  - {name: a, executable: a}\n");
  EXPECT_EQ(d.hosts, (std::vector<std::string>{"local"}));
  ASSERT_EQ(d.nodes.size(), 1u);
  EXPECT_EQ(d.nodes[0].host, "local");
  EXPECT_TRUE(d.nodes[0].args.empty());
  EXPECT_TRUE(d.nodes[0].env.empty());
  EXPECT_FALSE(d.nodes[0].ends_launch);
  EXPECT_TRUE(d.args.empty());
}

TEST(LaunchFile, NodeHostDefaultsToTheFirstHost) {
  const LaunchDescription d = parse("name: n\nhosts: [ctrl, rig]\nnodes:\n  - {name: a, executable: a}\n");
  EXPECT_EQ(d.nodes[0].host, "ctrl");
}

TEST(LaunchFile, NumbersAndBooleansInArgsAreKeptAsWritten) {
  const LaunchDescription d = parse(
      "name: n\nnodes:\n  - {name: a, executable: a, args: [--rate, 1000, 0.5e-3, true], "
      "env: {N: 4}, ends_launch: false}\n");
  EXPECT_EQ(d.nodes[0].args, (std::vector<std::string>{"--rate", "1000", "0.5e-3", "true"}));
  EXPECT_EQ(d.nodes[0].env[0].second, "4");
  EXPECT_FALSE(d.nodes[0].ends_launch);
}

TEST(LaunchFile, EnvKeepsFileOrder) {
  const LaunchDescription d = parse("name: n\nnodes:\n  - {name: a, executable: a, env: {Z: 1, A: 2}}\n");
  ASSERT_EQ(d.nodes[0].env.size(), 2u);
  EXPECT_EQ(d.nodes[0].env[0].first, "Z");
  EXPECT_EQ(d.nodes[0].env[1].first, "A");
}

TEST(LaunchFile, LoadsFromAFileAndNamesItInErrors) {
  const launch_test::ScratchDir dir;
  const std::string good = dir.write("good.yaml", kExample);
  EXPECT_EQ(load_launch_file(good).name, "pulse_lockstep");
  const std::string bad = dir.write("bad.yaml", "name: n\nnodes: []\n");
  try {
    load_launch_file(bad);
    FAIL() << "expected a LaunchFileError";
  } catch (const LaunchFileError& e) {
    EXPECT_NE(std::string(e.what()).find(bad + ":2:"), std::string::npos) << e.what();
  }
  try {
    load_launch_file(dir.file("absent.yaml"));
    FAIL() << "expected a LaunchFileError";
  } catch (const LaunchFileError& e) {
    EXPECT_NE(std::string(e.what()).find(dir.file("absent.yaml") + ": cannot open launch file"), std::string::npos)
        << e.what();
  }
}

// ---- validation: every rule gives a LaunchFileError naming file, key path and value

struct BadFile {
  const char* label;
  const char* yaml;
  std::vector<const char*> mentions;  // besides the file name
};

void PrintTo(const BadFile& f, std::ostream* os) { *os << f.label; }

class LaunchFileRejects : public ::testing::TestWithParam<BadFile> {};

TEST_P(LaunchFileRejects, WithAClearMessage) {
  const std::string message = error_of(GetParam().yaml);
  ASSERT_FALSE(message.empty()) << "accepted:\n" << GetParam().yaml;
  EXPECT_EQ(message.rfind("launch.yaml", 0), 0u) << message;
  for (const char* needle : GetParam().mentions) {
    EXPECT_NE(message.find(needle), std::string::npos) << "'" << needle << "' not in: " << message;
  }
}

const std::vector<BadFile> kBadFiles = {
    {"InvalidYaml", "name: n\nnodes: [\n", {"invalid YAML"}},
    {"EmptyDocument", "", {"top level must be a map", "null"}},
    {"TopLevelList", "- a\n- b\n", {"top level must be a map", "a list"}},
    {"MissingName", "nodes:\n  - {name: a, executable: a}\n", {"missing required key 'name'"}},
    {"EmptyName", "name: ''\nnodes:\n  - {name: a, executable: a}\n", {"name: must not be empty"}},
    {"NameNotString", "name: [x]\nnodes:\n  - {name: a, executable: a}\n", {"name: must be a string, got a list"}},
    {"MissingNodes", "name: n\n", {"missing required key 'nodes'"}},
    {"EmptyNodes", "name: n\nnodes: []\n", {"launch.yaml:2:", "nodes: must list at least one node"}},
    {"NodesNotList", "name: n\nnodes: {a: 1}\n", {"nodes: must be a list of nodes, got a map"}},
    {"UnknownTopKey",
     "name: n\nnodez: []\nnodes:\n  - {name: a, executable: a}\n",
     {"launch.yaml:2:1", "nodez: unknown key", "allowed: name, hosts, nodes, args"}},
    {"DuplicateTopKey",
     "name: n\nname: m\nnodes:\n  - {name: a, executable: a}\n",
     {"launch.yaml:2:", "name: duplicate key"}},
    {"NodeNotMap", "name: n\nnodes:\n  - plant_sim\n", {"nodes[0]: must be a map", "'plant_sim'"}},
    {"NodeMissingName", "name: n\nnodes:\n  - {executable: a}\n", {"nodes[0]: missing required key 'name'"}},
    {"NodeMissingExecutable", "name: n\nnodes:\n  - {name: a}\n", {"nodes[0]: missing required key 'executable'"}},
    {"UnknownNodeKey",
     "name: n\nnodes:\n  - {name: a, executable: a}\n  - {name: b, exectuable: b}\n",
     {"launch.yaml:4:", "nodes[1].exectuable: unknown key", "executable"}},
    {"DuplicateNodeKey",
     "name: n\nnodes:\n  - name: a\n    executable: a\n    name: b\n",
     {"launch.yaml:5:", "nodes[0].name: duplicate key"}},
    {"DuplicateNodeNames",
     "name: n\nnodes:\n  - {name: a, executable: a}\n  - {name: a, executable: b}\n",
     {"launch.yaml:4:", "nodes[1].name: 'a' is already the name of nodes[0]"}},
    {"BadNodeName",
     "name: n\nnodes:\n  - {name: plant sim, executable: a}\n",
     {"nodes[0].name: 'plant sim' is not a node name"}},
    {"ReservedNodeName",
     "name: n\nnodes:\n  - {name: launcher, executable: a}\n",
     {"nodes[0].name: 'launcher' is reserved"}},
    {"EmptyExecutable", "name: n\nnodes:\n  - {name: a, executable: ''}\n", {"nodes[0].executable: must not be empty"}},
    {"NullExecutable",
     "name: n\nnodes:\n  - {name: a, executable: }\n",
     {"nodes[0].executable: must be a string, got null"}},
    {"HostNotListed",
     "name: n\nhosts: [rig, ctrl]\nnodes:\n  - {name: a, executable: a, host: lab}\n",
     {"launch.yaml:4:", "nodes[0].host: 'lab' is not among hosts [rig, ctrl]"}},
    {"HostNotListedWithDefaultHosts",
     "name: n\nnodes:\n  - {name: a, executable: a, host: rig}\n",
     {"nodes[0].host: 'rig' is not among hosts [local]"}},
    {"HostsNotList",
     "name: n\nhosts: rig\nnodes:\n  - {name: a, executable: a}\n",
     {"hosts: must be a list of host names, got 'rig'"}},
    {"HostsEmpty", "name: n\nhosts: []\nnodes:\n  - {name: a, executable: a}\n", {"hosts: must not be empty"}},
    {"HostsDuplicate",
     "name: n\nhosts: [rig, rig]\nnodes:\n  - {name: a, executable: a}\n",
     {"hosts[1]: 'rig' is listed twice"}},
    {"BadHostName",
     "name: n\nhosts: ['rig 1']\nnodes:\n  - {name: a, executable: a}\n",
     {"hosts[0]: 'rig 1' is not a host name"}},
    {"NodeArgsNotList",
     "name: n\nnodes:\n  - {name: a, executable: a, args: --fast}\n",
     {"nodes[0].args: must be a list of strings, got '--fast'"}},
    {"NodeArgNotString",
     "name: n\nnodes:\n  - {name: a, executable: a, args: [--x, [1, 2]]}\n",
     {"nodes[0].args[1]: must be a string, got a list"}},
    {"EnvNotMap",
     "name: n\nnodes:\n  - {name: a, executable: a, env: [A=1]}\n",
     {"nodes[0].env: must be a map", "got a list"}},
    {"EnvValueNull",
     "name: n\nnodes:\n  - {name: a, executable: a, env: {A: }}\n",
     {"nodes[0].env.A: must be a string, got null"}},
    {"EnvBadName",
     "name: n\nnodes:\n  - {name: a, executable: a, env: {1A: x}}\n",
     {"nodes[0].env.1A: '1A' is not an environment variable name"}},
    {"EnvDuplicate",
     "name: n\nnodes:\n  - {name: a, executable: a, env: {A: x, A: y}}\n",
     {"nodes[0].env.A: duplicate key"}},
    {"EndsLaunchNotBool",
     "name: n\nnodes:\n  - {name: a, executable: a, ends_launch: yes}\n",
     {"nodes[0].ends_launch: must be true or false, got 'yes'"}},
    {"EndsLaunchList",
     "name: n\nnodes:\n  - {name: a, executable: a, ends_launch: [true]}\n",
     {"nodes[0].ends_launch: must be true or false, got a list"}},
    {"ArgsNotMap", "name: n\nargs: [a]\nnodes:\n  - {name: a, executable: a}\n", {"args: must be a map", "got a list"}},
    {"ArgValueNotString",
     "name: n\nargs: {a: {b: c}}\nnodes:\n  - {name: a, executable: a}\n",
     {"args.a: must be a string, got a map"}},
    {"BadArgName",
     "name: n\nargs: {a-b: c}\nnodes:\n  - {name: a, executable: a}\n",
     {"args.a-b: 'a-b' is not an arg name"}},
    {"UnknownArgInArgs",
     "name: n\nargs: {word: w}\nnodes:\n  - {name: a, executable: a, args: [x, \"$(arg wrd)\"]}\n",
     {"launch.yaml:4:40", "nodes[0].args[1]", "'$(arg wrd)'", "unknown arg 'wrd'", "declared: word"}},
    {"UnknownArgWithoutArgs",
     "name: n\nnodes:\n  - {name: a, executable: \"$(arg exe)\"}\n",
     {"nodes[0].executable", "unknown arg 'exe'", "declared: none"}},
    {"UnknownArgInEnv",
     "name: n\nnodes:\n  - {name: a, executable: a, env: {X: \"$(arg x)\"}}\n",
     {"nodes[0].env.X", "unknown arg 'x'"}},
    {"UnterminatedSubstitution",
     "name: n\nargs: {a: b}\nnodes:\n  - {name: a, executable: a, args: [\"$(arg a\"]}\n",
     {"nodes[0].args[0]", "'$(' without a closing ')'"}},
    {"UnknownSubstitution",
     "name: n\nnodes:\n  - {name: a, executable: a, args: [\"$(env HOME)\"]}\n",
     {"nodes[0].args[0]", "unknown substitution '$(env HOME)'", "only $(arg NAME)"}},
    {"ExecutableEmptyAfterSubstitution",
     "name: n\nargs: {exe: ''}\nnodes:\n  - {name: a, executable: \"$(arg exe)\"}\n",
     {"nodes[0].executable: is empty after substitution"}},
};

INSTANTIATE_TEST_SUITE_P(Rules, LaunchFileRejects, ::testing::ValuesIn(kBadFiles),
                         [](const auto& info) { return std::string(info.param.label); });

// ---- arg substitution

TEST(ArgSubstitution, UsesDefaultsAndOverrides) {
  const char* yaml =
      "name: n\nargs: {scenario: pulse, rate: '1000'}\n"
      "nodes:\n  - {name: a, executable: a, args: [\"--s=$(arg scenario)/$(arg rate)\"]}\n";
  EXPECT_EQ(parse(yaml).nodes[0].args[0], "--s=pulse/1000");
  EXPECT_EQ(parse(yaml, {{"scenario", "free"}}).nodes[0].args[0], "--s=free/1000");
  EXPECT_EQ(parse(yaml, {{"scenario", "free"}}).args.at("scenario"), "free");
}

TEST(ArgSubstitution, AppliesToExecutableArgsAndEnvButNotToNames) {
  const LaunchDescription d = parse(
      "name: $(arg x)\nargs: {x: v}\nnodes:\n"
      "  - {name: a, executable: \"bin/$(arg x)\", args: [\"$(arg x)\"], env: {E: \"$(arg x)$(arg x)\"}}\n");
  EXPECT_EQ(d.name, "$(arg x)");
  EXPECT_EQ(d.nodes[0].executable, "bin/v");
  EXPECT_EQ(d.nodes[0].args[0], "v");
  EXPECT_EQ(d.nodes[0].env[0].second, "vv");
}

TEST(ArgSubstitution, ValuesAreNotSubstitutedAgain) {
  EXPECT_EQ(substitute_args("<$(arg a)>", {{"a", "$(arg b)"}}, "here"), "<$(arg b)>");
}

TEST(ArgSubstitution, TextWithoutSubstitutionsIsUnchanged) {
  EXPECT_EQ(substitute_args("$HOME (x) $ (", {}, "here"), "$HOME (x) $ (");
  EXPECT_EQ(substitute_args("", {}, "here"), "");
}

TEST(ArgSubstitution, ToleratesSpacesInsideTheParentheses) {
  EXPECT_EQ(substitute_args("$( arg  a )", {{"a", "1"}}, "here"), "1");
}

TEST(ArgSubstitution, ErrorsStartWithWhere) {
  try {
    substitute_args("$(arg nope)", {{"a", "1"}}, "f.yaml:3:4: nodes[0].args[0]");
    FAIL() << "expected a LaunchFileError";
  } catch (const LaunchFileError& e) {
    EXPECT_EQ(std::string(e.what()), "f.yaml:3:4: nodes[0].args[0]: '$(arg nope)': unknown arg 'nope' (declared: a)");
  }
}

TEST(ArgSubstitution, OverrideOfAnUndeclaredArgIsAnError) {
  const std::string message =
      error_of("name: n\nargs: {scenario: s}\nnodes:\n  - {name: a, executable: a}\n", {{"scenaro", "x"}});
  EXPECT_NE(message.find("launch.yaml: --arg scenaro=x: no arg 'scenaro' is declared (declared: scenario)"),
            std::string::npos)
      << message;
}

TEST(ArgSubstitution, ParsesOverrideText) {
  EXPECT_EQ(parse_arg_override("a=b"), (std::pair<std::string, std::string>{"a", "b"}));
  EXPECT_EQ(parse_arg_override("a=b=c"), (std::pair<std::string, std::string>{"a", "b=c"}));
  EXPECT_EQ(parse_arg_override("a="), (std::pair<std::string, std::string>{"a", ""}));
  EXPECT_THROW(parse_arg_override("a"), LaunchFileError);
  EXPECT_THROW(parse_arg_override("=b"), LaunchFileError);
}

// ---- host slicing

const char* const kThreeHosts = R"yaml(name: n
hosts: [rig, ctrl, spare]
nodes:
  - {name: plant, executable: p}
  - {name: controller, executable: c, host: ctrl}
  - {name: bridge, executable: b, host: rig}
  - {name: kalman, executable: k, host: ctrl}
)yaml";

std::vector<std::string> names(const std::vector<NodeSpec>& nodes) {
  std::vector<std::string> out;
  for (const auto& n : nodes) out.push_back(n.name);
  return out;
}

TEST(HostSlicing, WithoutAHostEveryNodeInFileOrder) {
  EXPECT_EQ(names(select_nodes(parse(kThreeHosts), std::nullopt)),
            (std::vector<std::string>{"plant", "controller", "bridge", "kalman"}));
}

TEST(HostSlicing, AHostGetsItsNodesInFileOrder) {
  const LaunchDescription d = parse(kThreeHosts);
  EXPECT_EQ(names(select_nodes(d, "rig")), (std::vector<std::string>{"plant", "bridge"}));
  EXPECT_EQ(names(select_nodes(d, "ctrl")), (std::vector<std::string>{"controller", "kalman"}));
  EXPECT_TRUE(select_nodes(d, "spare").empty());
}

TEST(HostSlicing, UnknownHostListsTheKnownOnes) {
  try {
    select_nodes(parse(kThreeHosts), std::string("lab"));
    FAIL() << "expected a LaunchFileError";
  } catch (const LaunchFileError& e) {
    EXPECT_EQ(std::string(e.what()), "launch.yaml: --host 'lab': unknown host (known: rig, ctrl, spare)");
  }
}

// ---- executable lookup

class ExecutableLookup : public ::testing::Test {
 protected:
  ExecutableLookup() {
    for (const char* d : {"bin", "path1", "path2"}) std::filesystem::create_directory(dir_.path() / d);
  }
  std::string dir(const char* name) const { return dir_.file(name); }
  launch_test::ScratchDir dir_;
};

TEST_F(ExecutableLookup, BinDirComesBeforePath) {
  dir_.write("bin/node", "#!/bin/sh\n", true);
  dir_.write("path1/node", "#!/bin/sh\n", true);
  EXPECT_EQ(resolve_executable("node", dir("bin"), dir("path1")), dir("bin") + "/node");
}

TEST_F(ExecutableLookup, PathEntriesInOrderSkippingWhatCannotRun) {
  dir_.write("path1/node", "#!/bin/sh\n", false);                      // not executable
  std::filesystem::create_directory(dir_.path() / "path2" / "other");  // a folder
  dir_.write("path2/node", "#!/bin/sh\n", true);
  EXPECT_EQ(resolve_executable("node", dir("bin"), dir("path1") + ":" + dir("path2")), dir("path2") + "/node");
  EXPECT_THROW(resolve_executable("other", dir("bin"), dir("path2")), ExecutableNotFound);
}

TEST_F(ExecutableLookup, NotFoundSaysWhereItLooked) {
  try {
    resolve_executable("plant_sim", dir("bin"), dir("path1") + ":" + dir("path1") + ":" + dir("path2"));
    FAIL() << "expected ExecutableNotFound";
  } catch (const ExecutableNotFound& e) {
    EXPECT_EQ(std::string(e.what()), "executable 'plant_sim' not found (looked in " + dir("bin") + ", " + dir("path1") +
                                         ", " + dir("path2") + ")");
  }
}

TEST_F(ExecutableLookup, NameWithSlashIsUsedAsGiven) {
  dir_.write("bin/node", "#!/bin/sh\n", true);
  EXPECT_EQ(resolve_executable(dir("bin") + "/node", "", ""), dir("bin") + "/node");
  try {
    resolve_executable("./no/such/node", dir("path1"), dir("path1"));
    FAIL() << "expected ExecutableNotFound";
  } catch (const ExecutableNotFound& e) {
    EXPECT_NE(std::string(e.what()).find("executable './no/such/node' not found (relative to "), std::string::npos)
        << e.what();
  }
  dir_.write("bin/plain", "text\n", false);
  try {
    resolve_executable(dir("bin") + "/plain", "", "");
    FAIL() << "expected ExecutableNotFound";
  } catch (const ExecutableNotFound& e) {
    EXPECT_NE(std::string(e.what()).find("is not an executable file"), std::string::npos) << e.what();
  }
}

TEST(ShellQuote, QuotesOnlyWhenNeeded) {
  EXPECT_EQ(shell_quote("configs/scenarios/pulse.yaml"), "configs/scenarios/pulse.yaml");
  EXPECT_EQ(shell_quote("--rate=1000"), "--rate=1000");
  EXPECT_EQ(shell_quote(""), "''");
  EXPECT_EQ(shell_quote("two words"), "'two words'");
  EXPECT_EQ(shell_quote("it's"), "'it'\\''s'");
  EXPECT_EQ(shell_quote("$HOME"), "'$HOME'");
}

// ---- line relay

struct Collected {
  std::vector<std::string> lines;
  LineRelay::Sink sink() {
    return [this](const std::string& s) { lines.push_back(s); };
  }
};

TEST(LineRelay, JoinsPartialChunksIntoWholeLines) {
  Collected c;
  LineRelay relay("[n] ", c.sink());
  relay.feed("hel", 3);
  EXPECT_TRUE(c.lines.empty());
  relay.feed("lo\nwor", 6);
  relay.feed("ld\n\nlast", 8);
  EXPECT_EQ(c.lines, (std::vector<std::string>{"[n] hello\n", "[n] world\n", "[n] \n"}));
  relay.finish();
  EXPECT_EQ(c.lines.back(), "[n] last\n");
  relay.finish();
  EXPECT_EQ(c.lines.size(), 4u);
}

TEST(LineRelay, SplitsOverlongLines) {
  Collected c;
  LineRelay relay("> ", c.sink(), 4);
  relay.feed("abcdefghij\nxy", 13);
  EXPECT_EQ(c.lines, (std::vector<std::string>{"> abcd\n", "> efgh\n", "> ij\n"}));
  relay.feed("zabcdefg", 8);  // an unfinished line reaching the limit goes out too
  EXPECT_EQ(c.lines, (std::vector<std::string>{"> abcd\n", "> efgh\n", "> ij\n", "> xyza\n", "> bcde\n"}));
  relay.finish();
  EXPECT_EQ(c.lines.back(), "> fg\n");
  relay.feed("abcd\n", 5);  // exactly the limit: one piece, no empty extra line
  EXPECT_EQ(c.lines.back(), "> abcd\n");
  EXPECT_EQ(c.lines.size(), 7u);
}

// ---- the repository's own launch files stay valid

TEST(LaunchFile, IfLeavesOutTheNodesWhoseConditionIsFalse) {
  const char* const text = R"yaml(name: rig
args: {drive: sim}
nodes:
  - {name: plant, executable: plant_sim, if: "$(arg drive) == sim"}
  - {name: bridge, executable: drive_bridge, if: "$(arg drive) != sim"}
  - {name: controller, executable: controller, if: "true"}
  - {name: spare, executable: controller, if: "false"}
)yaml";
  const LaunchDescription sim = parse(text);
  ASSERT_EQ(sim.nodes.size(), 2u);
  EXPECT_EQ(sim.nodes[0].name, "plant");
  EXPECT_EQ(sim.nodes[1].name, "controller");
  EXPECT_EQ(sim.left_out, (std::vector<std::string>{"bridge", "spare"}));
  const LaunchDescription rig = parse(text, {{"drive", "virtual"}});
  ASSERT_EQ(rig.nodes.size(), 2u);
  EXPECT_EQ(rig.nodes[0].name, "bridge");
  EXPECT_EQ(rig.left_out, (std::vector<std::string>{"plant", "spare"}));
}

TEST(LaunchFile, ConditionsJoinComparisonsWithAndBeforeOr) {
  using pmlsm::launch::evaluate_condition;
  // What the sim and rig files say for their container: composed when asked, or by default in realtime.
  const char* const composed = "$C == true || $C == auto && $K == realtime";
  const auto with = [&](const std::string& c, const std::string& k) {
    std::string text = composed;
    for (auto at = text.find("$C"); at != std::string::npos; at = text.find("$C")) text.replace(at, 2, c);
    for (auto at = text.find("$K"); at != std::string::npos; at = text.find("$K")) text.replace(at, 2, k);
    return evaluate_condition(text, "x");
  };
  EXPECT_TRUE(with("true", "lockstep"));
  EXPECT_TRUE(with("true", "realtime"));
  EXPECT_TRUE(with("auto", "realtime"));
  EXPECT_FALSE(with("auto", "lockstep"));
  EXPECT_FALSE(with("false", "realtime"));
  EXPECT_FALSE(with("false", "lockstep"));
  EXPECT_TRUE(evaluate_condition("a == a && b != c", "x"));
  EXPECT_FALSE(evaluate_condition("a == a && b == c", "x"));
  EXPECT_TRUE(evaluate_condition("false || true", "x"));
  // Every part is checked, also one that cannot change the outcome.
  EXPECT_THROW(evaluate_condition("true || yes", "x"), pmlsm::launch::LaunchFileError);
  EXPECT_THROW(evaluate_condition("false && a =", "x"), pmlsm::launch::LaunchFileError);
}

TEST(LaunchFile, AConditionThatIsNoneOfTheFormsIsAnErrorNamingIt) {
  const std::string base = "name: x\nnodes:\n  - {name: a, executable: b, if: \"";
  for (const char* bad : {"yes", "", "a = b", "== b", "a ==", "a == b == c", "a == b ||", "&& a == b"}) {
    const std::string e = error_of(base + bad + "\"}\n");
    EXPECT_NE(e.find("nodes[0].if"), std::string::npos) << bad << ": " << e;
    EXPECT_NE(e.find("a condition is true, false, A == B or A != B"), std::string::npos) << bad << ": " << e;
  }
  const std::string none = error_of("name: x\nnodes:\n  - {name: a, executable: b, if: \"false\"}\n");
  EXPECT_NE(none.find("every node is left out"), std::string::npos) << none;
  // Names stay unique over every node, left out or not.
  EXPECT_NE(error_of("name: x\nnodes:\n  - {name: a, executable: b, if: \"false\"}\n  - {name: a, executable: b}\n")
                .find("already the name"),
            std::string::npos);
}

// common_args: what every node of a file shares, written once, before each node's own args; a node
// that does not take them says `common_args: false`.
TEST(LaunchFile, CommonArgsComeBeforeEachNodesOwn) {
  const LaunchDescription d = parse(R"yaml(name: x
args: {domain: "7"}
common_args: [--domain, $(arg domain)]
nodes:
  - {name: a, executable: a, args: [--peers, 3]}
  - {name: b, executable: b}
  - {name: c, executable: c, common_args: false, args: [--own]}
)yaml");
  ASSERT_EQ(d.nodes.size(), 3u);
  EXPECT_EQ(d.nodes[0].args, (std::vector<std::string>{"--domain", "7", "--peers", "3"}));
  EXPECT_EQ(d.nodes[1].args, (std::vector<std::string>{"--domain", "7"}));
  EXPECT_EQ(d.nodes[2].args, (std::vector<std::string>{"--own"}));
  EXPECT_NE(error_of("name: x\ncommon_args: --domain\nnodes:\n  - {name: a, executable: a}\n")
                .find("common_args: must be a list of strings"),
            std::string::npos);
  EXPECT_NE(error_of("name: x\nnodes:\n  - {name: a, executable: a, common_args: maybe}\n").find("common_args"),
            std::string::npos);
}

// A path default that starts with $(dirname) is the launch file's folder, wherever the launcher
// runs; an override is taken as given (the user's, from the current folder); $(dirname) anywhere
// else is refused.
TEST(LaunchFile, DirnameInAnArgsDefaultIsTheFilesFolder) {
  const std::string text =
      "name: x\nargs: {config: $(dirname)/../configs/system.yaml}\n"
      "nodes:\n  - {name: a, executable: a, args: [--config, $(arg config)]}\n";
  const LaunchDescription d = parse_launch(text, "/opt/rig/launch/x.yaml");
  EXPECT_EQ(d.nodes[0].args, (std::vector<std::string>{"--config", "/opt/rig/configs/system.yaml"}));
  const LaunchDescription relative = parse_launch(text, "launch/x.yaml");
  EXPECT_EQ(relative.args.at("config"),
            (std::filesystem::current_path() / "configs" / "system.yaml").lexically_normal().string());
  EXPECT_EQ(parse_launch(text, "/opt/rig/launch/x.yaml", {{"config", "mine.yaml"}}).args.at("config"), "mine.yaml");
  EXPECT_NE(error_of("name: x\nnodes:\n  - {name: a, executable: a, args: [$(dirname)/a]}\n")
                .find("unknown substitution '$(dirname)'"),
            std::string::npos);
}

TEST(RepositoryLaunchFiles, AllParse) {
  const std::filesystem::path folder = std::filesystem::path(PMLSM_SOURCE_DIR) / "launch";
  int checked = 0;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    const auto ext = entry.path().extension();
    if (ext != ".yaml" && ext != ".yml") continue;
    EXPECT_NO_THROW(load_launch_file(entry.path().string())) << entry.path();
    // Every file a default names (from the file's folder) is there.
    for (const auto& [name, value] : load_launch_file(entry.path().string()).args) {
      if (value.rfind('/', 0) == 0) {
        EXPECT_TRUE(std::filesystem::exists(value)) << entry.path() << ": " << name;
      }
    }
    ++checked;
  }
  if (checked == 0) GTEST_SKIP() << "no launch files in " << folder;
}

}  // namespace

namespace {

// What a launcher sends an agent reads back to the same nodes: quotes, spaces, colons, '#',
// numbers that must stay strings, env and ends_launch.
TEST(SliceYaml, ReadsBackToTheSameNodes) {
  NodeSpec a;
  a.name = "plant";
  a.executable = "plant_sim";
  a.host = "rig";
  a.args = {"--set", "plant.x: 1 # not a comment", "3", "it's \"quoted\"", "", "true"};
  a.env = {{"FASTDDS_DEFAULT_PROFILES_FILE", "configs/dds/profiles.xml"}, {"EMPTY", ""}};
  a.ends_launch = true;
  NodeSpec b;
  b.name = "controller";
  b.executable = "/opt/pmlsm/bin/controller";
  b.host = "rig";
  const auto launch = parse_launch(slice_yaml("pulse", "rig", {a, b}), "slice");
  EXPECT_EQ(launch.name, "pulse");
  EXPECT_EQ(launch.hosts, std::vector<std::string>{"rig"});
  ASSERT_EQ(launch.nodes.size(), 2u);
  EXPECT_EQ(launch.nodes[0].name, a.name);
  EXPECT_EQ(launch.nodes[0].executable, a.executable);
  EXPECT_EQ(launch.nodes[0].host, "rig");
  EXPECT_EQ(launch.nodes[0].args, a.args);
  EXPECT_EQ(launch.nodes[0].env, a.env);
  EXPECT_TRUE(launch.nodes[0].ends_launch);
  EXPECT_EQ(launch.nodes[1].executable, b.executable);
  EXPECT_TRUE(launch.nodes[1].args.empty());
  EXPECT_FALSE(launch.nodes[1].ends_launch);
}

}  // namespace

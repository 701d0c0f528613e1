// The pmlsm tool against real nodes on real DDS (loopback): recording a lockstep run loses
// nothing and third-party readers decode it; a recording stands in for the plant; a recorder
// killed by SIGKILL leaves a readable file; the ros2 profile read by ROS 2's decoders; topic
// list/echo/hz/delay on a running loop; bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <csignal>

#include <unistd.h>
#include <map>
#include <optional>
#include <sstream>
#include <tuple>

#include "child_process.hpp"
#include "integration_support.hpp"
#include "pmlsm/util/exit_codes.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/dds/catalog.hpp"
#include "pmlsm/introspect/cdr_schema.hpp"
#include "pmlsm/mcap/mcap.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;
using test::bin;
using test::node_args;
using test::source;
using test::test_domain;

constexpr auto kRunTimeout = std::chrono::seconds(60);

std::vector<std::string> pmlsm_args(const std::string& domain, std::vector<std::string> args) {
  std::vector<std::string> a{bin("pmlsm"), "--domain", domain, "--profiles", source("configs/dds/profiles.xml")};
  a.insert(a.end(), args.begin(), args.end());
  return a;
}

std::vector<std::string> node_js(std::vector<std::string> args) {
  std::vector<std::string> a{PMLSM_NODE, source("tests/node/read_mcap.mjs")};
  a.insert(a.end(), args.begin(), args.end());
  return a;
}

int run_to_end(test::ChildProcess& p) {
  const auto code = p.wait_for(kRunTimeout);
  EXPECT_TRUE(code.has_value()) << "still running:\n" << p.output();
  return code.value_or(-1);
}

/// Every message of a file, decoded, per topic, in file order.
struct FileContents {
  std::map<std::string, std::vector<introspect::Decoded>> by_topic;
  mcap::ReadReport report;
};

FileContents read_all(const fs::path& file) {
  FileContents out;
  std::map<std::uint16_t, mcap::Schema> schemas;
  std::map<std::uint16_t, std::pair<std::string, introspect::MessageSchema>> channels;
  mcap::ReadCallbacks callbacks;
  callbacks.on_schema = [&](const mcap::Schema& s) { schemas[s.id] = s; };
  callbacks.on_channel = [&](const mcap::Channel& c) {
    const auto& s = schemas.at(c.schema_id);
    // A ros2msg schema (the ros2 profile) is decoded by this build's IDL of the topic's type.
    const auto* entry = dds::find_topic(c.topic);
    channels.emplace(c.id,
                     std::make_pair(c.topic, s.encoding == "ros2msg" && entry != nullptr
                                                 ? introspect::MessageSchema::parse(entry->schema_idl, entry->type_name)
                                                 : introspect::MessageSchema::parse(s.data, s.name)));
  };
  callbacks.on_message = [&](const mcap::Message& m) {
    const auto& [topic, schema] = channels.at(m.channel_id);
    out.by_topic[topic].push_back(schema.decode(m.data, m.size));
  };
  out.report = mcap::read(file.string(), callbacks);
  return out;
}

double field(const introspect::Decoded& d, const std::string& path) {
  const auto* f = d.find(path);
  return f != nullptr ? f->as_double().value_or(-1.0) : -1.0;
}

/// Records a lockstep run (the pulse unless named) of plant, controller and estimator into dir/run.mcap.
/// @return the recorder's output.
std::string record_lockstep_run(const std::string& domain, const fs::path& dir,
                                std::vector<std::string> extra_record_args = {},
                                std::vector<std::string> extra_plant_args = {}, int plant_exit = 0,
                                const std::string& scenario_name = "pulse") {
  const std::string scenario = source("configs/scenarios/" + scenario_name + ".yaml");
  std::vector<std::string> record{"record", "-o",           (dir / "run.mcap").string(), "--stop-after-idle-s",
                                  "2",      "--no-progress"};
  record.insert(record.end(), extra_record_args.begin(), extra_record_args.end());
  test::ChildProcess recorder(pmlsm_args(domain, record), (dir / "record.log").string());
  EXPECT_TRUE(recorder.wait_for_output("topics on domain", std::chrono::seconds(20))) << recorder.output();
  test::ChildProcess estimator(node_args("kalman_estimator", domain, scenario), (dir / "estimator.log").string());
  test::ChildProcess controller(node_args("controller", domain, scenario), (dir / "controller.log").string());
  // Three MotorFeedback readers: controller, estimator and the recorder, all matched before tick 0.
  std::vector<std::string> plant_args{"--peers", "3"};
  plant_args.insert(plant_args.end(), extra_plant_args.begin(), extra_plant_args.end());
  test::ChildProcess plant(node_args("plant_sim", domain, scenario, plant_args), (dir / "plant.log").string());
  EXPECT_EQ(run_to_end(plant), plant_exit) << plant.output();
  for (auto* p : {&controller, &estimator}) EXPECT_EQ(run_to_end(*p), 0) << p->output();
  EXPECT_EQ(run_to_end(recorder), 0) << recorder.output();
  return recorder.output();
}

/// Nothing lost on any stream of a recorder's summary. The drive's state is latched (KEEP_LAST 1):
/// a state the drive leaves within the same burst (enabling walks three in a row) is superseded
/// before a reader takes it, and the recorder counts that gap; it is no loss of the stream.
void expect_no_stream_lost(const std::string& log) {
  std::istringstream rows(log);
  std::size_t streams = 0;
  for (std::string row; std::getline(rows, row);) {
    if (row.rfind("/pmlsm/", 0) != 0) continue;
    std::istringstream fields(row);
    std::string topic;
    unsigned long long messages = 0, lost = 0;
    ASSERT_TRUE(static_cast<bool>(fields >> topic >> messages >> lost)) << row;
    ++streams;
    if (topic != "/pmlsm/drive_state") {
      EXPECT_EQ(lost, 0u) << row << "\n" << log;
    }
  }
  EXPECT_GE(streams, 6u) << log;
}

TEST(Record, LockstepRunWholeAndDecodedByThirdPartyReaders) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "record");
  const std::string log = record_lockstep_run(test_domain(30), dir);
  expect_no_stream_lost(log);

  const FileContents file = read_all(dir / "run.mcap");
  EXPECT_TRUE(file.report.complete());
  // The pulse scenario: 2 s at 1 kHz. Each control topic holds every tick, in order.
  for (const char* topic : {"/pmlsm/motor_feedback", "/pmlsm/force_command", "/pmlsm/estimated_state",
                            "/pmlsm/plant_truth", "/pmlsm/velocity_reference"}) {
    const auto found = file.by_topic.find(topic);
    ASSERT_NE(found, file.by_topic.end()) << topic << "\n" << log;
    const auto& samples = found->second;
    EXPECT_EQ(samples.size(), 2000u) << topic;
    for (std::size_t k = 0; k < samples.size(); ++k) {
      ASSERT_TRUE(samples[k].ok()) << topic << " " << k << ": " << samples[k].error;
      ASSERT_EQ(field(samples[k], "stamp.tick"), static_cast<double>(k)) << topic;
    }
  }

  // Third-party readers (Node.js: @mcap/core, @foxglove/omgidl-serialization) decode every message.
  test::ChildProcess reader(node_js({(dir / "run.mcap").string(), "--expect-topic", "/pmlsm/motor_feedback",
                                     "--expect-topic", "/pmlsm/estimated_state", "--min-messages", "10000"}),
                            (dir / "node.log").string());
  EXPECT_EQ(run_to_end(reader), 0) << reader.output();

  test::ChildProcess plot(
      pmlsm_args(test_domain(30), {"plot", (dir / "run.mcap").string(), "-o", (dir / "plots").string()}),
      (dir / "plot.log").string());
  EXPECT_EQ(run_to_end(plot), 0) << plot.output();
  for (const char* png : {"velocities.png", "forces.png", "phase_plane.png"}) {
    EXPECT_GT(fs::exists(dir / "plots" / png) ? fs::file_size(dir / "plots" / png) : 0u, 10000u) << png;
  }
  EXPECT_EQ(plot.output().find("force off"), std::string::npos) << plot.output();  // the drive was on throughout
  fs::remove_all(dir);
}

// The ros2 profile (`--profile ros2`): the same messages with ROS 2's .msg definitions, as rosbag2
// writes them. Foxglove's ROS 2 parser and CDR reader decode every message, each definition is
// the generated ROS 2 package's (build/ros2/pmlsm_msgs), and our own tools read it as the other.
TEST(Record, TheRos2ProfileIsReadByRos2ToolsAndByOurs) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "record_ros2");
  const std::string log = record_lockstep_run(test_domain(92), dir, {"--profile", "ros2"});
  EXPECT_NE(log.find("ros2 profile"), std::string::npos) << log;
  expect_no_stream_lost(log);
  const FileContents file = read_all(dir / "run.mcap");
  EXPECT_TRUE(file.report.complete());
  ASSERT_EQ(file.by_topic.count("/pmlsm/motor_feedback"), 1u);
  EXPECT_EQ(file.by_topic.at("/pmlsm/motor_feedback").size(), 2000u);

  test::ChildProcess reader(node_js({(dir / "run.mcap").string(), "--expect-topic", "/pmlsm/motor_feedback",
                                     "--expect-topic", "/pmlsm/estimated_state", "--min-messages", "10000"}),
                            (dir / "node.log").string());
  EXPECT_EQ(run_to_end(reader), 0) << reader.output();
  test::ChildProcess package(
      {PMLSM_NODE, source("tests/node/check_ros2_package.mjs"), PMLSM_ROS2_PACKAGE_DIR, (dir / "run.mcap").string()},
      (dir / "package.log").string());
  EXPECT_EQ(run_to_end(package), 0) << package.output();

  test::ChildProcess plot(
      pmlsm_args(test_domain(92), {"plot", (dir / "run.mcap").string(), "-o", (dir / "plots").string()}),
      (dir / "plot.log").string());
  EXPECT_EQ(run_to_end(plot), 0) << plot.output();
  EXPECT_GT(fs::exists(dir / "plots" / "velocities.png") ? fs::file_size(dir / "plots" / "velocities.png") : 0u,
            10000u);
  if (!HasFailure()) fs::remove_all(dir);
}

// A recording whose channel of one of our topics does not carry that topic's type (another type's
// definition, an unknown schema encoding) is refused with the channel named: nothing is played.
TEST(Play, ChannelsNotCarryingTheirTopicsTypeAreRefusedAndNothingIsPlayed) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "play_refused");
  const auto& catalog = dds::catalog();
  const auto* feedback = dds::find_topic("/pmlsm/motor_feedback");
  const auto* command = dds::find_topic("/pmlsm/force_command");
  ASSERT_NE(feedback, nullptr);
  ASSERT_NE(command, nullptr);
  ASSERT_FALSE(catalog.empty());
  struct Case {
    const char* what;
    dds::RecordedSchema schema;
    const char* expected;
  };
  const dds::RecordedSchema other = dds::recorded_schema(*command, dds::RecordingProfile::kRos2);
  dds::RecordedSchema edited = dds::recorded_schema(*feedback, dds::RecordingProfile::kRos2);
  edited.data.replace(edited.data.find("float64 position_m"), 18, "float32 position_m");
  for (const Case& c : {Case{"another type's definition", other, "but the topic carries pmlsm_msgs/msg/MotorFeedback"},
                        Case{"an edited definition", edited, "differs from this build's"},
                        Case{"an unknown encoding", {"pmlsm_msgs/MotorFeedback", "protobuf", "x"}, "'protobuf'"}}) {
    SCOPED_TRACE(c.what);
    const fs::path file = dir / "bad.mcap";
    {
      mcap::Writer writer(file.string(), mcap::WriterOptions{});
      const auto schema = writer.add_schema(c.schema.name, c.schema.encoding, c.schema.data);
      const auto channel = writer.add_channel(schema, "/pmlsm/motor_feedback", "cdr");
      const std::uint8_t sample[8] = {0, 1, 0, 0, 0, 0, 0, 0};
      writer.write(channel, 0, 1, 1, sample, sizeof sample);
      writer.close();
    }
    test::ChildProcess player(
        pmlsm_args(test_domain(93), {"play", file.string(), "--wait-matched-s", "0", "--no-progress"}),
        (dir / "play.log").string());
    EXPECT_EQ(run_to_end(player), 2) << player.output();
    EXPECT_NE(player.output().find(" /pmlsm/motor_feedback: "), std::string::npos) << player.output();
    EXPECT_NE(player.output().find("  channel "), std::string::npos) << player.output();
    EXPECT_NE(player.output().find(c.expected), std::string::npos) << player.output();
    EXPECT_EQ(player.output().find("published"), std::string::npos) << player.output();
  }
  if (!HasFailure()) fs::remove_all(dir);
}

// A run at zero force (a drive never enabled) is plain in the plots: the applied force is drawn
// with the commands, the force-off ticks are a red band, the titles and the tool say how many.
TEST(Plot, ARunAtZeroForceIsMarked) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "zero_force");
  record_lockstep_run(test_domain(61), dir, {}, {"--auto-enable", "false"}, 5);
  test::ChildProcess plot(
      pmlsm_args(test_domain(61), {"plot", (dir / "run.mcap").string(), "-o", (dir / "plots").string()}),
      (dir / "plot.log").string());
  EXPECT_EQ(run_to_end(plot), 0) << plot.output();
  EXPECT_NE(plot.output().find("drive force off for 2000 of 2000 ticks from tick 0"), std::string::npos)
      << plot.output();
  const std::string script = test::read_file(dir / "plots" / "plots.gp");
  EXPECT_NE(script.find("DRIVE FORCE OFF for 2000 of 2000 ticks"), std::string::npos) << script;
  EXPECT_NE(script.find("filledcurves"), std::string::npos) << script;
  EXPECT_NE(script.find("F applied by the drive"), std::string::npos) << script;
  // The applied force is the drive's zero, not the controller's command.
  std::ifstream data(dir / "plots" / "motor_feedback.dat");
  double t = 0, v = 0, applied = 1, status = 0, power = 0;
  int rows = 0;
  while (data >> t >> v >> applied >> status >> power) {
    EXPECT_EQ(applied, 0.0) << t;
    EXPECT_NE(power, 4.0) << t;  // never operation enabled
    ++rows;
  }
  EXPECT_EQ(rows, 2000);
  for (const char* png : {"velocities.png", "forces.png"}) {
    EXPECT_GT(fs::exists(dir / "plots" / png) ? fs::file_size(dir / "plots" / png) : 0u, 10000u) << png;
  }
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

TEST(Play, RecordingStandsInForThePlant) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "play");
  record_lockstep_run(test_domain(31), dir);

  // A fresh estimator on another domain, fed only the recorded MotorFeedback.
  const std::string domain = test_domain(32);
  const std::string scenario = source("configs/scenarios/pulse.yaml");
  test::ChildProcess recorder(
      pmlsm_args(domain, {"record", "/pmlsm/estimated_state", "-o", (dir / "replayed.mcap").string(),
                          "--stop-after-idle-s", "2", "--no-progress"}),
      (dir / "record2.log").string());
  ASSERT_TRUE(recorder.wait_for_output("topics on domain", std::chrono::seconds(20))) << recorder.output();
  test::ChildProcess estimator(node_args("kalman_estimator", domain, scenario), (dir / "estimator2.log").string());
  test::ChildProcess player(pmlsm_args(domain, {"play", (dir / "run.mcap").string(), "--topics",
                                                "/pmlsm/motor_feedback", "--rate", "4", "--no-progress"}),
                            (dir / "play.log").string());
  EXPECT_EQ(run_to_end(player), 0) << player.output();
  EXPECT_EQ(run_to_end(estimator), 0) << estimator.output();
  EXPECT_EQ(run_to_end(recorder), 0) << recorder.output();

  const auto original = read_all(dir / "run.mcap").by_topic["/pmlsm/estimated_state"];
  const auto replayed = read_all(dir / "replayed.mcap").by_topic["/pmlsm/estimated_state"];
  ASSERT_EQ(original.size(), 2000u);
  ASSERT_EQ(replayed.size(), original.size()) << recorder.output();
  for (std::size_t k = 0; k < original.size(); ++k) {
    ASSERT_EQ(original[k].fields.size(), replayed[k].fields.size());
    for (std::size_t i = 0; i < original[k].fields.size(); ++i) {
      const auto& a = original[k].fields[i];
      if (a.path == "stamp.source_time_ns") continue;  // the wall clock at publication
      ASSERT_EQ(a.to_string(), replayed[k].fields[i].to_string()) << "tick " << k << " " << a.path;
    }
  }
  fs::remove_all(dir);
}

TEST(Record, KilledRecorderLeavesReadableFile) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "killed");
  const std::string domain = test_domain(33);
  const std::string scenario = source("configs/scenarios/free_vibration.yaml");
  const fs::path file = dir / "run.mcap";
  test::ChildProcess recorder(pmlsm_args(domain, {"record", "-o", file.string(), "--chunk-size-kib", "16",
                                                  "--flush-interval-s", "0.1", "--no-progress"}),
                              (dir / "record.log").string());
  ASSERT_TRUE(recorder.wait_for_output("topics on domain", std::chrono::seconds(20))) << recorder.output();
  test::ChildProcess controller(node_args("controller", domain, scenario), (dir / "controller.log").string());
  test::ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "2"}), (dir / "plant.log").string());
  // Kill it once the file holds a few hundred samples of feedback, read as the test reads it below.
  // Not by the file's size: the schemas of every topic come first (about 48 kB), and on a loaded
  // host the chunks flushed every 0.1 s hold few samples each, so 100 kB held as few as 100.
  constexpr std::size_t kFeedbackBeforeKill = 300;
  std::size_t feedback_on_disk = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (std::chrono::steady_clock::now() < deadline && feedback_on_disk < kFeedbackBeforeKill) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (fs::exists(file)) feedback_on_disk = read_all(file).by_topic["/pmlsm/motor_feedback"].size();
  }
  recorder.signal(SIGKILL);
  ASSERT_GE(feedback_on_disk, kFeedbackBeforeKill) << recorder.output();
  recorder.wait_for(std::chrono::seconds(10));
  for (auto* p : {&plant, &controller}) EXPECT_EQ(run_to_end(*p), 0) << p->output();

  FileContents contents = read_all(file);
  EXPECT_FALSE(contents.report.has_footer);
  EXPECT_FALSE(contents.report.problems.empty());
  ASSERT_GE(contents.by_topic["/pmlsm/motor_feedback"].size(), feedback_on_disk);
  for (const auto& d : contents.by_topic["/pmlsm/motor_feedback"]) EXPECT_TRUE(d.ok()) << d.error;

  test::ChildProcess plot(pmlsm_args(domain, {"plot", file.string(), "-o", (dir / "plots").string()}),
                          (dir / "plot.log").string());
  EXPECT_EQ(run_to_end(plot), 0) << plot.output();
  EXPECT_NE(plot.output().find("not whole"), std::string::npos) << plot.output();
  EXPECT_TRUE(fs::exists(dir / "plots" / "velocities.png"));

  test::ChildProcess player(
      pmlsm_args(test_domain(34), {"play", file.string(), "--rate", "50", "--wait-matched-s", "0", "--no-progress"}),
      (dir / "play.log").string());
  EXPECT_EQ(run_to_end(player), 0) << player.output();
  EXPECT_NE(player.output().find("not whole"), std::string::npos) << player.output();

  test::ChildProcess reader(node_js({file.string(), "--allow-truncated", "--min-messages", "100"}),
                            (dir / "node.log").string());
  EXPECT_EQ(run_to_end(reader), 0) << reader.output();
  fs::remove_all(dir);
}

TEST(Tool, BadInputIsAClearErrorWithExitCode2) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "bad");
  const std::string domain = test_domain(35);
  test::ChildProcess unknown(pmlsm_args(domain, {"record", "/pmlsm/nope", "-o", (dir / "x.mcap").string()}),
                             (dir / "unknown.log").string());
  EXPECT_EQ(run_to_end(unknown), 2);
  EXPECT_NE(unknown.output().find("unknown topic '/pmlsm/nope'"), std::string::npos) << unknown.output();
  EXPECT_NE(unknown.output().find("/pmlsm/motor_feedback"), std::string::npos) << unknown.output();

  test::ChildProcess echo(pmlsm_args(domain, {"topic", "echo", "/pmlsm/nope"}), (dir / "echo.log").string());
  EXPECT_EQ(run_to_end(echo), 2);

  test::ChildProcess missing(pmlsm_args(domain, {"play", (dir / "missing.mcap").string()}),
                             (dir / "missing.log").string());
  EXPECT_EQ(run_to_end(missing), 2) << missing.output();

  {
    std::ofstream garbage(dir / "garbage.mcap", std::ios::binary);
    for (int i = 0; i < 5000; ++i) garbage.put(static_cast<char>((i * 7919) & 0xff));
  }
  test::ChildProcess plot(pmlsm_args(domain, {"plot", (dir / "garbage.mcap").string(), "-o", (dir / "p").string()}),
                          (dir / "plot.log").string());
  EXPECT_EQ(run_to_end(plot), 2) << plot.output();
  EXPECT_NE(plot.output().find("nothing to plot"), std::string::npos) << plot.output();

  test::ChildProcess play(pmlsm_args(domain, {"play", (dir / "garbage.mcap").string()}), (dir / "play.log").string());
  EXPECT_EQ(run_to_end(play), 2) << play.output();

  test::ChildProcess compression(
      pmlsm_args(domain, {"record", "--compression", "gzip", "-o", (dir / "y.mcap").string()}),
      (dir / "compression.log").string());
  EXPECT_EQ(run_to_end(compression), 2) << compression.output();

  test::ChildProcess nowhere(pmlsm_args(domain, {"record", "-o", (dir / "no" / "x.mcap").string()}),
                             (dir / "nowhere.log").string());
  EXPECT_EQ(run_to_end(nowhere), 2) << nowhere.output();
  EXPECT_NE(nowhere.output().find("no folder"), std::string::npos) << nowhere.output();
  fs::remove_all(dir);
}

/// What the processes of the topic tools' run printed and returned.
struct TopicToolsRun {
  std::string echo, hz, delay, list, plant, controller;
  int echo_code = -1, hz_code = -1, delay_code = -1, list_code = -1, plant_code = -1, controller_code = -1;
};

/// The number after the last `label` in a tool's output; none when the label is missing.
std::optional<double> last_number_after(const std::string& text, const std::string& label) {
  const auto at = text.rfind(label);
  if (at == std::string::npos) return std::nullopt;
  return std::stod(text.substr(at + label.size()));
}

TopicToolsRun run_topic_tools(const std::string& domain, const fs::path& dir) {
  const std::string scenario = source("configs/scenarios/free_vibration.yaml");  // 8 s at 1 kHz
  test::ChildProcess controller(
      node_args("controller", domain, scenario, {"--clock", "realtime", "--plant-lost-ms", "5000"}),
      (dir / "controller.log").string());
  // The tools are under test, not the drive's timing: a generous watchdog, so a host that holds
  // the loop for a few milliseconds (six processes on two cores) does not fault the run.
  test::ChildProcess plant(
      node_args("plant_sim", domain, scenario,
                {"--peers", "1", "--clock", "realtime", "--watchdog-ms", "1000", "--controller-lost-ms", "5000"}),
      (dir / "plant.log").string());
  test::ChildProcess echo(pmlsm_args(domain, {"topic", "echo", "/pmlsm/motor_feedback", "-n", "3", "--timeout-s", "6"}),
                          (dir / "echo.log").string());
  test::ChildProcess hz(pmlsm_args(domain, {"topic", "hz", "/pmlsm/motor_feedback", "--duration-s", "3"}),
                        (dir / "hz.log").string());
  test::ChildProcess delay(pmlsm_args(domain, {"topic", "delay", "/pmlsm/force_command", "--duration-s", "3"}),
                           (dir / "delay.log").string());
  test::ChildProcess list(pmlsm_args(domain, {"topic", "list", "--wait-s", "2", "-v"}), (dir / "list.log").string());
  TopicToolsRun run;
  run.echo_code = run_to_end(echo);
  run.hz_code = run_to_end(hz);
  run.delay_code = run_to_end(delay);
  run.list_code = run_to_end(list);
  run.plant_code = run_to_end(plant);
  run.controller_code = run_to_end(controller);
  run.echo = echo.output();
  run.hz = hz.output();
  run.delay = delay.output();
  run.list = list.output();
  run.plant = plant.output();
  run.controller = controller.output();
  return run;
}

TEST(Topic, ListEchoHzDelayOnARealtimeLoop) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "topic");
  // Four short-lived tool participants beside the loop: the abort the shipped 20 s lease avoids
  // (docs/hardening.md, "Participants that come and go") is a failure here, not retried.
  const TopicToolsRun run = run_topic_tools(test_domain(36), dir);
  EXPECT_EQ(run.echo_code, 0) << run.echo;
  EXPECT_NE(run.echo.find("stamp:\n  tick: "), std::string::npos) << run.echo;
  EXPECT_NE(run.echo.find("velocity_mps: "), std::string::npos) << run.echo;

  EXPECT_EQ(run.hz_code, 0) << run.hz;
  const std::optional<double> rate_hz = last_number_after(run.hz, "average rate: ");
  ASSERT_TRUE(rate_hz.has_value()) << run.hz;
  // A functional check (the loop runs at 1 kHz), with room for a loaded machine.
  EXPECT_GT(*rate_hz, 500.0) << run.hz;
  EXPECT_LT(*rate_hz, 2000.0) << run.hz;

  EXPECT_EQ(run.delay_code, 0) << run.delay;
  const std::optional<double> delay_s = last_number_after(run.delay, "average delay: ");
  ASSERT_TRUE(delay_s.has_value()) << run.delay;
  EXPECT_GT(*delay_s, 0.0) << run.delay;
  EXPECT_LT(*delay_s, 0.5) << run.delay;

  EXPECT_EQ(run.list_code, 0) << run.list;
  EXPECT_NE(run.list.find("/pmlsm/motor_feedback [pmlsm_msgs::msg::dds_::MotorFeedback_]  writers: 1"),
            std::string::npos)
      << run.list;
  EXPECT_NE(run.list.find("writer plant_sim  reliable, transient-local"), std::string::npos) << run.list;
  EXPECT_NE(run.list.find("reader controller"), std::string::npos) << run.list;

  EXPECT_EQ(run.plant_code, 0) << run.plant;
  EXPECT_EQ(run.controller_code, 0) << run.controller;
  fs::remove_all(dir);
}

// Commissioning on DDS: the PI-alone identification run of a plant the shipped models do not
// match, recorded, gives `pmlsm identify` the same fit as the in-process commissioning of that
// plant (the lockstep trace is the in-process one), written into a system file that loads.
TEST(Identify, ARecordedCommissioningRunGivesTheInProcessFit) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "identify");
  const std::vector<std::string> plant{"--set", "plant.mechanics.load_mass_kg=2",
                                       "plant.mechanics.spring_n_per_m=27400"};
  record_lockstep_run(test_domain(88), dir, {"/pmlsm/motor_feedback"}, plant, 0, "identification");
  const std::string recorded = (dir / "recorded.yaml").string(), simulated = (dir / "simulated.yaml").string();
  const std::vector<std::string> files{"-c", source("configs/system.yaml"), "-s",
                                       source("configs/scenarios/identification.yaml")};
  test::ChildProcess from_file(pmlsm_args(test_domain(88), {"identify", (dir / "run.mcap").string(), "-o", recorded,
                                                            "-c", source("configs/system.yaml")}),
                               (dir / "identify.log").string());
  EXPECT_EQ(run_to_end(from_file), 0) << from_file.output();
  std::vector<std::string> simulate{"identify", "--simulate", "-o", simulated};
  simulate.insert(simulate.end(), files.begin(), files.end());
  simulate.insert(simulate.end(), plant.begin(), plant.end());
  test::ChildProcess in_process(pmlsm_args(test_domain(88), simulate), (dir / "simulate.log").string());
  EXPECT_EQ(run_to_end(in_process), 0) << in_process.output();
  const SystemParams a = load_system_params(recorded), b = load_system_params(simulated);
  EXPECT_EQ(a.kalman.model.load_mass_kg, b.kalman.model.load_mass_kg);
  EXPECT_EQ(a.kalman.model.spring_n_per_m, b.kalman.model.spring_n_per_m);
  EXPECT_EQ(a.kalman.friction_input.model.coulomb_n, b.kalman.friction_input.model.coulomb_n);
  EXPECT_NEAR(a.kalman.model.load_mass_kg, 2.0, 0.3);
  EXPECT_NEAR(std::sqrt(a.kalman.model.spring_n_per_m / a.kalman.model.load_mass_kg), std::sqrt(27400.0 / 2.0), 1.5);
  EXPECT_EQ(a.compensator.state_feedback.model.load_mass_kg, a.kalman.model.load_mass_kg);
  // From the recording the plant is the file's; --simulate wrote its --set plant with the models.
  EXPECT_EQ(a.plant.mechanics.load_mass_kg,
            load_system_params(source("configs/system.yaml")).plant.mechanics.load_mass_kg);
  EXPECT_EQ(b.plant.mechanics.load_mass_kg, 2.0);
  EXPECT_EQ(b.plant.mechanics.spring_n_per_m, 27400.0);
  fs::remove_all(dir);
}

// A commissioning run with the drive's force off is no commissioning run; a load the run does not
// pin (the search box too narrow to reach it) is not written; bad command lines say what is wrong.
TEST(Identify, RefusesWhatCannotBeFittedAndWritesNothing) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "identify_refused");
  record_lockstep_run(test_domain(89), dir, {"/pmlsm/motor_feedback"}, {"--auto-enable", "false"}, 5, "identification");
  const std::string out = (dir / "out.yaml").string();
  const auto identify = [&](std::vector<std::string> args, const char* log) {
    args.insert(args.begin(), {"identify", "-c", source("configs/system.yaml"), "-s",
                               source("configs/scenarios/identification.yaml")});
    test::ChildProcess p(pmlsm_args(test_domain(89), args), (dir / log).string());
    const int exit_code = run_to_end(p);
    return std::make_pair(exit_code, p.output());
  };
  auto [code, text] = identify({(dir / "run.mcap").string(), "-o", out}, "off.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("force off at tick 0"), std::string::npos) << text;
  std::tie(code, text) = identify({"--simulate", "--range-ratio", "1.2", "--set", "plant.mechanics.load_mass_kg=2",
                                   "plant.mechanics.spring_n_per_m=27400", "-o", out},
                                  "bound.log");
  EXPECT_EQ(code, 6) << text;
  EXPECT_NE(text.find("not pinned"), std::string::npos) << text;
  std::tie(code, text) = identify({}, "none.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("give a recording or --simulate"), std::string::npos) << text;
  std::tie(code, text) = identify({(dir / "no_such.mcap").string()}, "missing.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("no such file"), std::string::npos) << text;
  // Nowhere to write: said before the identification runs, not after it.
  std::tie(code, text) = identify({"--simulate", "-o", (dir / "no" / "out.yaml").string()}, "folder.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("no folder"), std::string::npos) << text;
  EXPECT_EQ(text.find("innovation rms"), std::string::npos) << "it identified first:\n" << text;
  EXPECT_FALSE(fs::exists(out));
  fs::remove_all(dir);
}

// `pmlsm commission --simulate --tune` on a plant the shipped model does not match: the modes
// printed on their own lines within 0.5 % of the plant's, the report (the response per line, the
// raw samples, the Bode plot) and a system file with the measured two-mass model and the tuned
// PI gains that loads.
TEST(Commission, SimulatedPlantGivesItsModesAReportAndASystemFile) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "commission");
  const std::string out = (dir / "commissioned.yaml").string(), report = (dir / "report").string();
  test::ChildProcess p(
      pmlsm_args(test_domain(94),
                 {"commission", "--simulate", "-c", source("configs/system.yaml"), "--identification",
                  source("configs/scenarios/identification.yaml"), "--set", "plant.mechanics.load_mass_kg=8", "-o", out,
                  "--report", report, "--tune", "--verify", source("configs/sweeps/plant_family.yaml")}),
      (dir / "commission.log").string());
  ASSERT_EQ(run_to_end(p), 0) << p.output();
  const auto number_after = [&](const std::string& label) {
    const auto at = p.output().find("\n" + label + " ");
    return at == std::string::npos ? 0.0 : std::stod(p.output().substr(at + label.size() + 2));
  };
  const double anti_hz = std::sqrt(13700.0 / 8.0) / (2 * M_PI),
               resonance_hz = std::sqrt(13700.0 * (1 / 8.0 + 1 / 20.0)) / (2 * M_PI);
  EXPECT_NEAR(number_after("anti-resonance"), anti_hz, 0.005 * anti_hz) << p.output();
  EXPECT_NEAR(number_after("resonance"), resonance_hz, 0.005 * resonance_hz) << p.output();
  const SystemParams written = load_system_params(out);
  EXPECT_NEAR(written.kalman.model.load_mass_kg, 8.0, 0.16);
  EXPECT_NEAR(written.kalman.model.spring_n_per_m, 13700.0, 274.0);
  EXPECT_EQ(written.compensator.state_feedback.model.load_mass_kg, written.kalman.model.load_mass_kg);
  // The simulated plant keeps the command's --set: the copy runs the plant it was measured on.
  EXPECT_EQ(written.plant.mechanics.load_mass_kg, 8.0);
  EXPECT_EQ(written.plant.mechanics.spring_n_per_m, 13700.0);
  // --tune: the PI's gains scaled together to the margins (printed), the gain margin binding.
  EXPECT_NE(p.output().find("velocity loop as measured (Kp 10000 N s/m): phase margin 54."), std::string::npos)
      << p.output();
  EXPECT_GT(written.velocity_loop.kp_n_s_per_m, 10000.0);
  EXPECT_NEAR(written.velocity_loop.ki_n_per_m / written.velocity_loop.kp_n_s_per_m, 0.01 / 10000.0, 1e-12);
  EXPECT_NE(p.output().find("velocity loop tuned to 45 deg and 8 dB: Kp "), std::string::npos) << p.output();
  // --tune: state feedback's output filter tried on the commissioned system, written when on.
  const auto filter_line =
      p.output().find("state feedback's output filter (notch at 200 Hz) on the commissioned system");
  ASSERT_NE(filter_line, std::string::npos) << p.output();
  const std::string verdict = p.output().substr(filter_line, p.output().find('\n', filter_line) - filter_line);
  EXPECT_EQ(written.compensator.state_feedback.output_filter_enabled, verdict.substr(verdict.size() - 3) == ": on")
      << verdict;
  // --tune: acceleration feedback's gain and the RNN's output scale tried at seven factors each,
  // written at the factor chosen (the line's last word) times the shipped value.
  const SystemParams shipped = load_system_params(source("configs/system.yaml"));
  for (const auto& [key, configured, value] :
       {std::tuple<std::string, double, double>{"compensator.acceleration_feedback.gain_kg",
                                                shipped.compensator.acceleration_feedback.gain_kg,
                                                written.compensator.acceleration_feedback.gain_kg},
        {"compensator.rnn.output_scale", shipped.compensator.rnn.output_scale, written.compensator.rnn.output_scale}}) {
    const auto line_at = p.output().find(key + " on the commissioned system (mean cost over PI alone's");
    ASSERT_NE(line_at, std::string::npos) << p.output();
    const std::string line = p.output().substr(line_at, p.output().find('\n', line_at) - line_at);
    EXPECT_NE(line.find("x0.67 "), std::string::npos) << line;
    EXPECT_NE(line.find(", x2.5 "), std::string::npos) << line;
    const auto chosen_at = line.rfind(": x");
    ASSERT_NE(chosen_at, std::string::npos) << line;
    EXPECT_DOUBLE_EQ(value, configured * std::stod(line.substr(chosen_at + 3))) << line;
  }
  std::ifstream response(fs::path(report) / "response.csv");
  std::size_t lines = 0;
  for (std::string line; std::getline(response, line);) ++lines;
  EXPECT_EQ(lines, 1u + 195u);
  EXPECT_GT(fs::file_size(fs::path(report) / "bode.png"), 10000u);
  EXPECT_GT(fs::file_size(fs::path(report) / "samples.csv"), 24000u * 20u);
  // Verified as the sweep judges a plant: PI alone and each compensator on pulse and free vibration.
  EXPECT_NE(p.output().find("verification: every compensator clean and cheaper than PI alone"), std::string::npos)
      << p.output();
  std::ifstream verification(fs::path(report) / "verification.csv");
  std::size_t rows = 0;
  for (std::string line; std::getline(verification, line);) ++rows;
  EXPECT_EQ(rows, 1u + 2u * 4u);
  std::ifstream report_md(fs::path(report) / "report.md");
  const std::string md((std::istreambuf_iterator<char>(report_md)), std::istreambuf_iterator<char>());
  EXPECT_NE(md.find("Exit 0. The system file: " + out), std::string::npos) << md;
  EXPECT_NE(md.find("![Bode plot](bode.png)"), std::string::npos) << md;
  EXPECT_NE(md.find("\nanti-resonance "), std::string::npos) << md;
  fs::remove_all(dir);
}

// `pmlsm commission --simulate --design-filters --tune` on a plant whose encoder sits on a 250 Hz
// mount: the resonance found over the two-mass model, a notch placed in the force command's
// first slot that raises the gain the margins allow, and the system file written with it.
TEST(Commission, DesignsANotchForAResonanceAboveTheTwoMassModel) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "commission_notch");
  const std::string out = (dir / "commissioned.yaml").string(), report = (dir / "report").string();
  test::ChildProcess p(pmlsm_args(test_domain(95), {"commission", "--simulate", "-c", source("configs/system.yaml"),
                                                    "--identification", source("configs/scenarios/identification.yaml"),
                                                    "--set", "plant.encoder.mount_frequency_hz=250", "-o", out,
                                                    "--report", report, "--design-filters", "--tune", "--no-verify"}),
                       (dir / "commission.log").string());
  ASSERT_EQ(run_to_end(p), 0) << p.output();
  EXPECT_NE(p.output().find("filter design: resonance 25"), std::string::npos) << p.output();
  EXPECT_NE(p.output().find("with a notch: placed"), std::string::npos) << p.output();
  EXPECT_NE(p.output().find("with the force command's filters at the tuned gains"), std::string::npos) << p.output();
  const SystemParams written = load_system_params(out);
  const BiquadParams& notch = written.force_command_filters.slots[0];
  EXPECT_EQ(notch.kind, FilterKind::kNotch);
  EXPECT_NEAR(notch.frequency_hz, 250.0, 12.5);
  EXPECT_LT(notch.damping, notch.second_damping);
  EXPECT_EQ(written.force_command_filters.slots[1].kind, FilterKind::kNone);
  // The gains the margins allow without the notch (measured: x0.43) raised by it.
  EXPECT_GT(written.velocity_loop.kp_n_s_per_m, 10000.0 * 0.5);
  EXPECT_LT(written.velocity_loop.kp_n_s_per_m, 10000.0);
  // On the shipped (rigid) plant nothing stands out over the model: no notch.
  test::ChildProcess rigid(
      pmlsm_args(test_domain(95), {"commission", "--simulate", "--no-plots", "-c", source("configs/system.yaml"),
                                   "--identification", source("configs/scenarios/identification.yaml"), "--report",
                                   report, "--design-filters", "--no-verify"}),
      (dir / "rigid.log").string());
  ASSERT_EQ(run_to_end(rigid), 0) << rigid.output();
  EXPECT_NE(rigid.output().find("filter design: no resonance 6 dB or more over the two-mass model above 40 Hz"),
            std::string::npos)
      << rigid.output();
  fs::remove_all(dir);
}

// A run that would leave the stroke or exceed the force limit is refused before it starts (2); a
// measurement a limit ends (a noisy encoder saturates the loop) exits 5; a response not coherent
// enough and a commissioned system that fails its verification exit 6; none writes the file.
TEST(Commission, RefusesARunBeyondItsLimitsAndWritesNothingFromABadOne) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "commission_refused");
  const std::string out = (dir / "out.yaml").string();
  const auto commission = [&](const std::string& set, const char* log) {
    test::ChildProcess p(
        pmlsm_args(test_domain(94), {"commission", "--simulate", "--no-plots", "-c", source("configs/system.yaml"),
                                     "--identification", source("configs/scenarios/identification.yaml"), "--verify",
                                     source("configs/sweeps/plant_family.yaml"), "--set", set, "-o", out, "--report",
                                     (dir / "report").string()}),
        (dir / log).string());
    const int exit_code = run_to_end(p);
    return std::make_pair(exit_code, p.output());
  };
  auto [code, text] = commission("commissioning.frequency_response.max_travel_m=0.2", "stroke.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("would leave the stroke"), std::string::npos) << text;
  // Above the Nyquist frequency: the system's period is known before a tick is measured.
  std::tie(code, text) = commission("commissioning.frequency_response.max_frequency_hz=600", "nyquist.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("commissioning.frequency_response.max_frequency_hz: must lie above min_frequency_hz (2) and "
                      "below the Nyquist frequency 500, got 600"),
            std::string::npos)
      << text;
  EXPECT_EQ(text.find("measuring"), std::string::npos) << text;
  std::tie(code, text) = commission("commissioning.frequency_response.amplitude_n=700", "force.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("exceed the force limit"), std::string::npos) << text;
  std::tie(code, text) = commission("plant.encoder.position_noise_std_m=3e-5", "noise.log");
  EXPECT_EQ(code, 5) << text;
  EXPECT_NE(text.find("ended early: force [N] at tick"), std::string::npos) << text;
  std::tie(code, text) = commission("commissioning.frequency_response.min_coherence=0.9999", "coherence.log");
  EXPECT_EQ(code, 6) << text;
  EXPECT_NE(text.find("poor coherence"), std::string::npos) << text;
  // A verification the commissioned system fails (a free vibration to settle in 10 ms): exit 6.
  std::ifstream family(source("configs/sweeps/plant_family.yaml"));
  std::string sweep((std::istreambuf_iterator<char>(family)), std::istreambuf_iterator<char>());
  for (std::size_t at; (at = sweep.find("../")) != std::string::npos;) sweep.replace(at, 3, source("configs/"));
  const std::string settling = "max_free_vibration_settling_s: {value: 1.0";
  ASSERT_NE(sweep.find(settling), std::string::npos);
  sweep.replace(sweep.find(settling), settling.size(), "max_free_vibration_settling_s: {value: 0.01");
  std::ofstream((dir / "strict.yaml").string()) << sweep;
  test::ChildProcess strict(
      pmlsm_args(test_domain(94), {"commission", "--simulate", "--no-plots", "-c", source("configs/system.yaml"),
                                   "--identification", source("configs/scenarios/identification.yaml"), "--verify",
                                   (dir / "strict.yaml").string(), "-o", out, "--report", (dir / "report").string()}),
      (dir / "strict.log").string());
  EXPECT_EQ(run_to_end(strict), 6) << strict.output();
  EXPECT_NE(strict.output().find("the verification failed; nothing written"), std::string::npos) << strict.output();
  EXPECT_FALSE(fs::exists(out));
  // An input that does not load, or nowhere to write: refused before the measurement starts.
  fs::remove_all(dir / "report");
  const auto before_measuring = [&](std::vector<std::string> args, const char* log) {
    std::vector<std::string> a{"commission",
                               "--simulate",
                               "--no-plots",
                               "-c",
                               source("configs/system.yaml"),
                               "--report",
                               (dir / "report").string()};
    a.insert(a.end(), args.begin(), args.end());
    test::ChildProcess p(pmlsm_args(test_domain(94), a), (dir / log).string());
    const int exit_code = run_to_end(p);
    EXPECT_FALSE(fs::exists(dir / "report")) << "it measured:\n" << p.output();
    return std::make_pair(exit_code, p.output());
  };
  std::tie(code, text) = before_measuring({"--identification", (dir / "none.yaml").string()}, "identification.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("none.yaml"), std::string::npos) << text;
  std::tie(code, text) = before_measuring({"--verify", (dir / "none.yaml").string()}, "verify.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("none.yaml"), std::string::npos) << text;
  std::tie(code, text) =
      before_measuring({"--no-verify", "-o", (dir / "no" / "such" / "out.yaml").string()}, "out.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("no folder"), std::string::npos) << text;
  fs::remove_all(dir);
}

/// The rows of a CSV file after its header.
std::vector<std::string> csv_rows(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> rows;
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) rows.push_back(line);
  return rows;
}

// `pmlsm commission --simulate --family --tune`: every plant of a family (here its centre and two
// drawn; on two threads and on one, the same files) commissioned as one plant is: a row each with
// the modes within 0.5 %, the tuned loop's margins measured again, state feedback's output filter
// and the compensators' gains decided and the verification run; the centre's decisions and
// verification rows equal a single commissioning's.
TEST(Commission, AFamilyIsCommissionedPlantByPlantAsOnePlantIs) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "commission_family");
  std::ifstream family_file(source("configs/sweeps/plant_family.yaml"));
  std::string sweep((std::istreambuf_iterator<char>(family_file)), std::istreambuf_iterator<char>());
  for (std::size_t at; (at = sweep.find("../")) != std::string::npos;) sweep.replace(at, 3, source("configs/"));
  for (const auto& [from, to] :
       {std::pair<std::string, std::string>{"grid_points: {value: 2", "grid_points: {value: 0"},
        {"random: {value: 50", "random: {value: 2"}}) {
    ASSERT_NE(sweep.find(from), std::string::npos) << from;
    sweep.replace(sweep.find(from), from.size(), to);
  }
  const std::string family = (dir / "family.yaml").string();
  std::ofstream(family) << sweep;
  const std::vector<std::string> common = {"commission",
                                           "--simulate",
                                           "--no-plots",
                                           "-c",
                                           source("configs/system.yaml"),
                                           "--identification",
                                           source("configs/scenarios/identification.yaml"),
                                           "--tune",
                                           "--verify",
                                           source("configs/sweeps/plant_family.yaml")};
  std::vector<std::string> args = common;
  args.insert(args.end(), {"--family", family, "--report", (dir / "family").string(), "-j", "2"});
  test::ChildProcess p(pmlsm_args(test_domain(103), args), (dir / "family.log").string());
  ASSERT_EQ(run_to_end(p), 0) << p.output();
  // On one thread: the same files (the rows in the family's order whatever the threads), and
  // with plots, the family's PNG.
  args = common;
  args.erase(std::find(args.begin(), args.end(), "--no-plots"));
  args.insert(args.end(), {"--family", family, "--report", (dir / "family_1").string(), "-j", "1"});
  test::ChildProcess one_thread(pmlsm_args(test_domain(103), args), (dir / "family_1.log").string());
  ASSERT_EQ(run_to_end(one_thread), 0) << one_thread.output();
  for (const char* file : {"family.csv", "family_verification.csv"}) {
    EXPECT_EQ(test::read_file(dir / "family" / file), test::read_file(dir / "family_1" / file)) << file;
  }
  EXPECT_GT(fs::file_size(dir / "family_1" / "family.png"), 10000u);
  EXPECT_FALSE(fs::exists(dir / "family" / "family.png"));  // --no-plots
  EXPECT_NE(p.output().find("family of 3 plants (" + family + "): 0 failed"), std::string::npos) << p.output();
  EXPECT_NE(p.output().find("verification (" + source("configs/sweeps/plant_family.yaml") + "): 0 plants failed it"),
            std::string::npos)
      << p.output();
  const std::vector<std::string> rows = csv_rows(dir / "family" / "family.csv");
  ASSERT_EQ(rows.size(), 3u);
  std::vector<std::string> centre_cells;
  for (const std::string& row : rows) {
    std::vector<std::string> cell;
    std::stringstream in(row);
    for (std::string c; std::getline(in, c, ',');) cell.push_back(c);
    ASSERT_EQ(cell.size(), 20u) << row;
    EXPECT_LT(std::fabs(std::stod(cell[3])), 0.5) << row;  // anti-resonance, per cent
    EXPECT_LT(std::fabs(std::stod(cell[4])), 0.5) << row;  // resonance
    EXPECT_GE(std::stod(cell[9]), 45.0) << row;            // phase margin measured at the tuned gains
    EXPECT_GE(std::stod(cell[10]), 8.0) << row;            // gain margin
    EXPECT_EQ(cell[14], "6") << row;                       // 2 scenarios x 3 compensators verified
    EXPECT_EQ(cell[15], "0") << row;
    EXPECT_EQ(cell[17], "nan") << row;  // no load sensor: its side not measured
    EXPECT_EQ(cell[19], "0") << row;
    if (cell[0] == "centre") centre_cells = cell;
  }
  ASSERT_FALSE(centre_cells.empty());
  // The centre (5 kg, 17,125 N/m, the nominal friction) commissioned alone decides the same.
  const std::string out = (dir / "centre.yaml").string();
  args = common;
  args.insert(args.end(), {"--set", "plant.mechanics.load_mass_kg=5", "--set", "plant.mechanics.spring_n_per_m=17125",
                           "-o", out, "--report", (dir / "centre").string()});
  test::ChildProcess centre(pmlsm_args(test_domain(103), args), (dir / "centre.log").string());
  ASSERT_EQ(run_to_end(centre), 0) << centre.output();
  const SystemParams centre_system = load_system_params(out);
  EXPECT_EQ(centre_system.compensator.state_feedback.output_filter_enabled, centre_cells[11] == "on");
  std::ostringstream gains;  // as family.csv writes them
  gains << centre_system.compensator.acceleration_feedback.gain_kg << ',' << centre_system.compensator.rnn.output_scale;
  EXPECT_EQ(gains.str(), centre_cells[12] + ',' + centre_cells[13]);
  std::vector<std::string> family_centre;
  for (const std::string& row : csv_rows(dir / "family" / "family_verification.csv")) {
    if (row.rfind("centre,", 0) == 0) family_centre.push_back(row.substr(7));
  }
  EXPECT_EQ(family_centre.size(), 2u * 4u);
  EXPECT_EQ(family_centre, csv_rows(dir / "centre" / "verification.csv"));
  fs::remove_all(dir);
}

// With a load encoder the report holds the load's side: printed beside the motor side's fit, per
// line in load_side.csv, and the load's velocity in samples.csv.
TEST(Commission, ALoadEncoderAddsTheLoadsSideToTheReport) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "commission_load_side");
  const fs::path report = dir / "report";
  test::ChildProcess p(
      pmlsm_args(test_domain(128), {"commission", "--simulate", "--no-plots", "-c", source("configs/system.yaml"),
                                    "--identification", source("configs/scenarios/identification.yaml"), "--set",
                                    "sensors.load.kind=encoder", "--report", report.string()}),
      (dir / "commission.log").string());
  ASSERT_EQ(run_to_end(p), 0) << p.output();
  EXPECT_NE(p.output().find("the load's side (its sensor against the motor's encoder, "), std::string::npos)
      << p.output();
  EXPECT_NE(p.output().find("anti-resonance 9.314 Hz (the motor side's fit 9.314 Hz"), std::string::npos) << p.output();
  const std::vector<std::string> rows = csv_rows(report / "load_side.csv");
  EXPECT_EQ(rows.size(), 195u);
  std::ifstream samples(report / "samples.csv");
  std::string header;
  std::getline(samples, header);
  EXPECT_EQ(header, "tick,excitation_n,force_n,velocity_mps,load_velocity_mps");
  fs::remove_all(dir);
}

/// configs/scenarios/external.yaml lasting `duration_s`: a drive's run with nothing commanded by
/// the scenario (commission commands the force).
std::string drive_run_scenario(const fs::path& dir, double duration_s) {
  std::ifstream in(source("configs/scenarios/external.yaml"));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string key = "duration_s: {value: ";
  const std::size_t at = text.find(key);
  EXPECT_NE(at, std::string::npos);
  text.replace(at + key.size(), text.find_first_of(",}", at) - at - key.size(), std::to_string(duration_s));
  const fs::path path = dir / "drive_run.yaml";
  std::ofstream(path.string()) << text;
  return path.string();
}

// `pmlsm commission` on a live drive over DDS (plant_sim, lockstep, on the shipped
// configs/scenarios/commissioning.yaml run), in the controller's place,
// recorded by `pmlsm record` alongside: every tick answered, the modes within 0.5 % of the plant's,
// the drive's run valid to its end (exit 0, nothing rejected), the system file written, and the
// recording holding the measurement's force commands.
TEST(Commission, ALiveDriveIsMeasuredOverDdsInTheControllersPlace) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "commission_live");
  const std::string domain = test_domain(97), scenario = source("configs/scenarios/commissioning.yaml");
  test::ChildProcess recorder(
      pmlsm_args(domain, {"record", "-o", (dir / "run.mcap").string(), "--stop-after-idle-s", "2", "--no-progress",
                          "/pmlsm/motor_feedback", "/pmlsm/force_command"}),
      (dir / "record.log").string());
  ASSERT_TRUE(recorder.wait_for_output("topics on domain", std::chrono::seconds(20))) << recorder.output();
  test::ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "2"}), (dir / "plant.log").string());
  const std::string out = (dir / "live.yaml").string();
  test::ChildProcess commission(pmlsm_args(domain, {"commission", "-c", source("configs/system.yaml"), "--verify",
                                                    source("configs/sweeps/plant_family.yaml"), "--peer-timeout-s", "3",
                                                    "--no-plots", "-o", out, "--report", (dir / "report").string()}),
                                (dir / "commission.log").string());
  const auto code = commission.wait_for(std::chrono::seconds(150));
  ASSERT_TRUE(code.has_value()) << commission.output();
  EXPECT_EQ(*code, 0) << commission.output();
  EXPECT_EQ(run_to_end(plant), 0) << plant.output();
  EXPECT_NE(plant.output().find("27000 ticks in"), std::string::npos) << plant.output();
  EXPECT_NE(plant.output().find("late 0, rejected 0, foreign 0"), std::string::npos) << plant.output();
  EXPECT_NE(commission.output().find("27000 ticks answered"), std::string::npos) << commission.output();
  const std::string& text = commission.output();
  const auto number_after = [&](const std::string& label) {
    const auto at = text.find("\n" + label + " ");
    return at == std::string::npos ? 0.0 : std::stod(text.substr(at + label.size() + 2));
  };
  const double anti_hz = std::sqrt(13700.0 / 4.0) / (2 * M_PI),
               resonance_hz = std::sqrt(13700.0 * 1.2 / 4.0) / (2 * M_PI);
  EXPECT_NEAR(number_after("anti-resonance"), anti_hz, 0.005 * anti_hz) << text;
  EXPECT_NEAR(number_after("resonance"), resonance_hz, 0.005 * resonance_hz) << text;
  EXPECT_NEAR(load_system_params(out).kalman.model.load_mass_kg, 4.0, 0.12);
  EXPECT_EQ(run_to_end(recorder), 0) << recorder.output();
  const FileContents recorded = read_all(dir / "run.mcap");
  EXPECT_EQ(recorded.by_topic.at("/pmlsm/force_command").size(), 27000u);
  EXPECT_EQ(recorded.by_topic.at("/pmlsm/motor_feedback").size(), 27000u);
  fs::remove_all(dir);
}

// A drive that is not enabled: the measurement ends at once (exit 5), nothing written.
TEST(Commission, ADriveNotInOperationEnabledEndsTheMeasurementWithNothingWritten) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "commission_disabled");
  const std::string domain = test_domain(98), scenario = drive_run_scenario(dir, 2.0);
  test::ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "1", "--auto-enable", "false"}),
                           (dir / "plant.log").string());
  const std::string out = (dir / "out.yaml").string();
  test::ChildProcess commission(
      pmlsm_args(domain, {"commission", "-c", source("configs/system.yaml"), "--peer-timeout-s", "3", "--no-plots",
                          "-o", out, "--report", (dir / "report").string()}),
      (dir / "commission.log").string());
  EXPECT_EQ(run_to_end(commission), 5) << commission.output();
  EXPECT_NE(commission.output().find("the measurement ended early: the drive left operation enabled at tick 0"),
            std::string::npos)
      << commission.output();
  EXPECT_FALSE(fs::exists(out));
  run_to_end(plant);
  fs::remove_all(dir);
}

// An independent ROS 2 node (Foxglove's TypeScript implementation of the protocol, @foxglove/ros2
// on @foxglove/rtps: no Fast DDS, no ROS 2 installation) built against the generated interface
// package listens to a lockstep run of sim.yaml, separate processes or composed: it sees every
// topic under its ROS 2 name and type, finds every node on ros_discovery_info with its endpoints,
// receives every MotorFeedback sample in order, and the launch still ends clean with it attached
// (its readers neither hold a tick nor the shutdown).
void expect_a_ros2_node_gets_every_tick_and_node(const std::string& domain, const std::string& compose) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "ros2_node_" + compose);
  std::vector<std::string> listener_args{PMLSM_NODE,    source("tests/node/ros2_listener.mjs"),
                                         "--package",   PMLSM_ROS2_PACKAGE_DIR,
                                         "--domain",    domain,
                                         "--timeout-s", "45"};
  // Every tick of the separate run. Composed, a lockstep writer waits for the acknowledgments of
  // readers outside every 256 samples, and @foxglove/rtps acknowledges slowly (docs/ros2.md): the
  // listener takes the topics and nodes and leaves.
  const bool every_tick = compose == "false";
  if (every_tick) listener_args.insert(listener_args.end(), {"--count", "2000"});
  for (const char* topic :
       {"/pmlsm/motor_feedback", "/pmlsm/force_command", "/pmlsm/plant_truth", "/pmlsm/estimated_state",
        "/pmlsm/velocity_reference", "/pmlsm/node_status", "/pmlsm/drive_state"}) {
    listener_args.insert(listener_args.end(), {"--expect-topic", topic});
  }
  // Separate, only the drive's node is sure to be there long enough: it waits for the listener's
  // reader, the other nodes may leave the lockstep run before it has taken their announcements.
  // Composed, the four are one participant's.
  const std::vector<const char*> nodes =
      every_tick ? std::vector<const char*>{"plant_sim"}
                 : std::vector<const char*>{"plant_sim", "controller", "kalman_estimator", "evaluator"};
  for (const char* node : nodes) listener_args.insert(listener_args.end(), {"--expect-node", node});
  test::ChildProcess listener(listener_args, (dir / "listener.log").string());
  ASSERT_TRUE(listener.wait_for_output("ros2_listener: started", kRunTimeout)) << listener.output();
  // The plant waits for the listener's MotorFeedback reader too: it must see tick 0.
  test::ChildProcess launch(
      {bin("launcher"), source("launch/sim.yaml"), "--arg", "domain=" + domain, "--arg",
       "config=" + source("configs/system.yaml"), "--arg", "scenario=" + source("configs/scenarios/pulse.yaml"),
       "--arg", "profiles=" + source("configs/dds/profiles.xml"), "--arg", "out=" + dir.string(), "--arg",
       "feedback_readers=4", "--arg", "compose=" + compose},
      (dir / "launch.log").string());
  EXPECT_EQ(run_to_end(launch), 0) << launch.output();
  EXPECT_EQ(run_to_end(listener), 0) << listener.output();
  if (every_tick) {
    EXPECT_NE(listener.output().find("\"received\":2000,\"in_order\":true"), std::string::npos) << listener.output();
  }
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

TEST(Ros2Node, AnIndependentRos2NodeGetsEveryTickAndNodeOfSeparateProcesses) {
  expect_a_ros2_node_gets_every_tick_and_node(test_domain(106), "false");
}

// Composed, the container is one participant holding the four nodes (before, @foxglove/rtps took
// only the first of its five participants and got no sample).
TEST(Ros2Node, AnIndependentRos2NodeGetsEveryTickAndNodeOfAComposedChain) {
  expect_a_ros2_node_gets_every_tick_and_node(test_domain(108), "true");
}

}  // namespace
}  // namespace pmlsm

namespace pmlsm {
namespace {

// `pmlsm ethercat` against `pmlsm ethercat serve`, two processes: over UDP on loopback always, and
// on raw Ethernet across a veth pair between two network namespaces the test makes (root only).

/// The port `serve` printed ("... on UDP port N"), 0 when it printed none.
int served_port(const std::string& output) {
  const std::size_t at = output.find("UDP port ");
  return at == std::string::npos ? 0 : std::atoi(output.c_str() + at + 9);
}

TEST(Ethercat, AVirtualSlaveOverUdpIsScannedWalkedAndReadOverCoe) {
  const fs::path dir = test::fresh_dir("pmlsm_tool", "ethercat_udp");
  test::ChildProcess slave({bin("pmlsm"), "ethercat", "serve", "--udp-port", "0", "--seconds", "120"},
                           (dir / "serve.log").string());
  ASSERT_TRUE(slave.wait_for_output("UDP port", kRunTimeout)) << slave.output();
  const std::string peer = "127.0.0.1:" + std::to_string(served_port(slave.output()));
  const auto ethercat = [&](std::vector<std::string> args, const std::string& log) {
    args.insert(args.begin(), {bin("pmlsm"), "ethercat", "--udp", peer});
    test::ChildProcess p(args, (dir / log).string());
    const int code = run_to_end(p);
    return std::make_pair(code, p.output());
  };
  const std::string capture = (dir / "scan.pcapng").string();
  auto [code, text] = ethercat({"--capture", capture, "scan"}, "scan.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find("1 slaves"), std::string::npos) << text;
  EXPECT_NE(text.find("0x1001  0x00000000 0x00005001"), std::string::npos) << text;
  EXPECT_NE(text.find("INIT    128/128 bytes, CoE PMLSM virtual drive"), std::string::npos) << text;
  const std::string sdo_capture = (dir / "sdo.pcapng").string();
  std::tie(code, text) =
      ethercat({"--capture", sdo_capture, "sdo", "read", "0x1001", "0x1000", "0"}, "device_type.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find("0x1001 0x1000:0 0x00020192"), std::string::npos) << text;
  // That capture decoded by `pmlsm ethercat pcap`: the request and the answer, as the master saw them.
  {
    test::ChildProcess pcap({bin("pmlsm"), "ethercat", "pcap", sdo_capture, "--sdo"}, (dir / "pcap.log").string());
    EXPECT_EQ(run_to_end(pcap), 0) << pcap.output();
    EXPECT_NE(pcap.output().find("0 malformed"), std::string::npos) << pcap.output();
    EXPECT_NE(pcap.output().find("station 0x1001  upload request 0x1000:00"), std::string::npos) << pcap.output();
    EXPECT_NE(pcap.output().find("station 0x1001  upload response 0x1000:00 = 0x20192 (4 bytes)"), std::string::npos)
        << pcap.output();
    test::ChildProcess not_a_capture({bin("pmlsm"), "ethercat", "pcap", (dir / "serve.log").string()},
                                     (dir / "not_a_capture.log").string());
    EXPECT_EQ(run_to_end(not_a_capture), 2) << not_a_capture.output();
    EXPECT_NE(not_a_capture.output().find("not a pcapng capture"), std::string::npos) << not_a_capture.output();
  }
  std::tie(code, text) = ethercat({"sdo", "write", "0x1001", "0x6060", "0", "10", "--size", "1"}, "mode.log");
  EXPECT_EQ(code, 0) << text;
  std::tie(code, text) = ethercat({"sdo", "read", "0x1001", "0x6060", "0"}, "mode_back.log");
  EXPECT_NE(text.find("0x6060:0 0x0A"), std::string::npos) << text;
  // The device name, a text: a normal upload, printed as text.
  std::tie(code, text) = ethercat({"sdo", "read", "0x1001", "0x1008", "0"}, "device_name.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find("0x1008:0 \"PMLSM virtual drive\" (19 bytes)"), std::string::npos) << text;
  std::tie(code, text) = ethercat({"sdo", "read", "0x1001", "0x7777", "0"}, "absent.log");
  EXPECT_EQ(code, 1) << text;
  EXPECT_NE(text.find("aborted: 0x06020000"), std::string::npos) << text;
  std::tie(code, text) = ethercat({"state", "0x1001", "op"}, "op.log");
  EXPECT_EQ(code, 0) << text;
  EXPECT_NE(text.find("0x1001: OP"), std::string::npos) << text;
  // Mapped from its CoE objects: the CiA 402 RxPDO and TxPDO.
  EXPECT_NE(text.find("0x1001: process data 4 bytes out, 8 bytes in"), std::string::npos) << text;
  std::tie(code, text) = ethercat({"state", "0x1009", "op"}, "no_such.log");
  EXPECT_EQ(code, 2) << text;
  EXPECT_NE(text.find("the bus has 1 slaves"), std::string::npos) << text;
  std::tie(code, text) = ethercat({"state", "0x1001", "operational"}, "bad_state.log");
  EXPECT_EQ(code, 2) << text;
  // The capture opens in tshark with every frame an EtherCAT one (where tshark is installed).
  if (std::system("tshark --version >/dev/null 2>&1") == 0) {
    const std::string count = "tshark -r '" + capture + "' -Y 'ecat && !_ws.malformed' 2>/dev/null | wc -l";
    FILE* pipe = ::popen(count.c_str(), "r");
    ASSERT_NE(pipe, nullptr);
    int frames = 0;
    EXPECT_EQ(std::fscanf(pipe, "%d", &frames), 1);
    ::pclose(pipe);
    EXPECT_GT(frames, 10);
  }
  slave.signal(SIGINT);
  const auto served = slave.wait_for(kRunTimeout);
  ASSERT_TRUE(served.has_value());
  EXPECT_EQ(*served, 0) << slave.output();
  // 5 SDO requests of the commands above and 11 of the mapping: 0x1C12 and 0x1C13 with their PDOs'.
  EXPECT_NE(slave.output().find("AL state OP; 16 SDO requests"), std::string::npos) << slave.output();
  // Nobody there: exit 3, said.
  test::ChildProcess nobody({bin("pmlsm"), "ethercat", "--udp", "127.0.0.1:9", "scan"}, (dir / "nobody.log").string());
  EXPECT_EQ(run_to_end(nobody), 3) << nobody.output();
  EXPECT_NE(nobody.output().find("no slave answered"), std::string::npos) << nobody.output();
}

int quiet_sh(const std::string& command) { return std::system((command + " >/dev/null 2>&1").c_str()); }

/// Two network namespaces joined by a veth pair, removed again at the end.
class VethPair {
 public:
  VethPair() : master_ns_("ecm" + std::to_string(getpid())), slave_ns_("ecs" + std::to_string(getpid())) {
    ok_ = quiet_sh("ip netns add " + master_ns_) == 0 && quiet_sh("ip netns add " + slave_ns_) == 0 &&
          quiet_sh("ip link add " + master_if() + " type veth peer name " + slave_if()) == 0 &&
          quiet_sh("ip link set " + master_if() + " netns " + master_ns_) == 0 &&
          quiet_sh("ip link set " + slave_if() + " netns " + slave_ns_) == 0 &&
          quiet_sh("ip netns exec " + master_ns_ + " ip link set " + master_if() + " up") == 0 &&
          quiet_sh("ip netns exec " + slave_ns_ + " ip link set " + slave_if() + " up") == 0;
  }
  ~VethPair() {
    quiet_sh("ip netns del " + master_ns_);
    quiet_sh("ip netns del " + slave_ns_);
  }
  VethPair(const VethPair&) = delete;
  VethPair& operator=(const VethPair&) = delete;
  bool ok() const { return ok_; }
  std::string master_if() const { return "ecm" + std::to_string(getpid() % 100000); }
  std::string slave_if() const { return "ecs" + std::to_string(getpid() % 100000); }
  std::vector<std::string> in(const std::string& ns, std::vector<std::string> argv) const {
    argv.insert(argv.begin(), {"/usr/sbin/ip", "netns", "exec", ns});
    return argv;
  }
  const std::string& master_ns() const { return master_ns_; }
  const std::string& slave_ns() const { return slave_ns_; }

 private:
  std::string master_ns_, slave_ns_;
  bool ok_ = false;
};

TEST(Ethercat, OnRawEthernetAcrossAVethPairTheVirtualSlaveIsScannedAndTakenToOp) {
  if (geteuid() != 0) GTEST_SKIP() << "raw sockets and network namespaces need root; not run";
  if (quiet_sh("command -v ip") != 0) GTEST_SKIP() << "no iproute2 (ip); not run";
  const VethPair pair;
  if (!pair.ok()) GTEST_SKIP() << "this machine does not allow network namespaces and veth pairs; not run";
  const fs::path dir = test::fresh_dir("pmlsm_tool", "ethercat_raw");
  test::ChildProcess slave(
      pair.in(pair.slave_ns(), {bin("pmlsm"), "ethercat", "serve", "--interface", pair.slave_if(), "--seconds", "120"}),
      (dir / "serve.log").string());
  ASSERT_TRUE(slave.wait_for_output("serving a virtual EtherCAT slave on", kRunTimeout)) << slave.output();
  const std::string capture = (dir / "raw.pcapng").string();
  test::ChildProcess scan(pair.in(pair.master_ns(), {bin("pmlsm"), "ethercat", "--interface", pair.master_if(),
                                                     "--capture", capture, "scan"}),
                          (dir / "scan.log").string());
  EXPECT_EQ(run_to_end(scan), 0) << scan.output();
  EXPECT_NE(scan.output().find("0x1001  0x00000000 0x00005001"), std::string::npos) << scan.output();
  test::ChildProcess op(
      pair.in(pair.master_ns(), {bin("pmlsm"), "ethercat", "--interface", pair.master_if(), "state", "0x1001", "op"}),
      (dir / "op.log").string());
  EXPECT_EQ(run_to_end(op), 0) << op.output();
  EXPECT_NE(op.output().find("0x1001: OP"), std::string::npos) << op.output();
  slave.signal(SIGINT);
  ASSERT_TRUE(slave.wait_for(kRunTimeout).has_value());
  EXPECT_NE(slave.output().find("AL state OP"), std::string::npos) << slave.output();
}

TEST(Ethercat, SoemAnIndependentMasterFindsTheVirtualSlaveReadsItOverCoeTakesItToOpAndExchangesProcessData) {
  if (geteuid() != 0) GTEST_SKIP() << "raw sockets and network namespaces need root; not run";
  if (quiet_sh("command -v node") != 0) GTEST_SKIP() << "no node (scripts/install_deps.sh installs it); not run";
  if (!fs::exists(source("tests/node/node_modules/soem-node/build/Release/soem_addon.node"))) {
    GTEST_SKIP() << "no soem-node in tests/node (scripts/install_deps.sh installs it from npm); not run";
  }
  const VethPair pair;
  if (!pair.ok()) GTEST_SKIP() << "this machine does not allow network namespaces and veth pairs; not run";
  const fs::path dir = test::fresh_dir("pmlsm_tool", "ethercat_soem");
  test::ChildProcess slave(
      pair.in(pair.slave_ns(), {bin("pmlsm"), "ethercat", "serve", "--interface", pair.slave_if(), "--seconds", "120"}),
      (dir / "serve.log").string());
  ASSERT_TRUE(slave.wait_for_output("serving a virtual EtherCAT slave on", kRunTimeout)) << slave.output();
  test::ChildProcess soem(
      pair.in(pair.master_ns(), {"/usr/bin/env", "node", source("tests/node/soem_master.mjs"), pair.master_if(),
                                 "--read", "1000:0", "--read", "1018:2", "--read", "1008:0"}),
      (dir / "soem.log").string());
  EXPECT_EQ(run_to_end(soem), 0) << soem.output();
  const std::string out = soem.output();
  EXPECT_NE(out.find("\"slaves\":1"), std::string::npos) << out;
  // SOEM names a slave by the name string its SII's general category points to.
  EXPECT_NE(out.find("\"name\":\"PMLSM virtual drive\""), std::string::npos) << out;
  EXPECT_NE(out.find("\"address\":4097"), std::string::npos) << out;  // SOEM's own station address, 0x1001
  EXPECT_NE(out.find("\"preop\":2"), std::string::npos) << out;
  // The CiA 402 device type and the product code, over CoE, little-endian as on the wire.
  EXPECT_NE(out.find("\"1000:0\":\"92010200\""), std::string::npos) << out;
  EXPECT_NE(out.find("\"1018:2\":\"01500000\""), std::string::npos) << out;
  // The device name, over 4 bytes: SOEM's normal upload of it ("PMLSM virtual drive").
  EXPECT_NE(out.find("\"1008:0\":\"504d4c534d207669727475616c206472697665\""), std::string::npos) << out;
  EXPECT_NE(out.find("\"safeop\":4"), std::string::npos) << out;
  EXPECT_NE(out.find("\"op\":8"), std::string::npos) << out;
  // The process data SOEM mapped from 0x1C12 / 0x1C13: the CiA 402 RxPDO (controlword, target
  // torque: 4 bytes) and TxPDO (statusword, torque actual, position actual: 8 bytes), exchanged by
  // LRW with working counter 3 (read 1, written 2), the outputs reaching the slave's dictionary.
  EXPECT_NE(out.find("\"output_bytes\":4,\"input_bytes\":8"), std::string::npos) << out;
  EXPECT_NE(out.find("\"process_wkc\":[3,3,3,3,3]"), std::string::npos) << out;
  EXPECT_NE(out.find("\"inputs\":\"0000000000000000\""), std::string::npos) << out;
  slave.signal(SIGINT);
  ASSERT_TRUE(slave.wait_for(kRunTimeout).has_value());
  // SOEM read the PDO assignment and mappings by complete access, as the SII offers it: 0x1C00,
  // 0x1C12, 0x1600, 0x1C13, 0x1A00 a request each, beside the three objects asked for.
  EXPECT_NE(slave.output().find("AL state OP; 8 SDO requests"), std::string::npos) << slave.output();
  EXPECT_NE(slave.output().find("outputs: controlword 0x0006, target torque 100 per mille (0 refused)"),
            std::string::npos)
      << slave.output();
}

/// The integer after `"key":` in a JSON line; nullopt when it is not there.
std::optional<long long> json_integer(const std::string& text, const std::string& key) {
  const std::string tag = "\"" + key + "\":";
  const std::size_t at = text.find(tag);
  if (at == std::string::npos) return std::nullopt;
  return std::stoll(text.substr(at + tag.size()));
}

TEST(Ethercat, SoemWalksTheVirtualDriveToOperationEnabledMovesTheMotorAndExchangesTenThousandCycles) {
  if (geteuid() != 0) GTEST_SKIP() << "raw sockets and network namespaces need root; not run";
  if (quiet_sh("command -v node") != 0) GTEST_SKIP() << "no node (scripts/install_deps.sh installs it); not run";
  if (!fs::exists(source("tests/node/node_modules/soem-node/build/Release/soem_addon.node"))) {
    GTEST_SKIP() << "no soem-node in tests/node (scripts/install_deps.sh installs it from npm); not run";
  }
  const VethPair pair;
  if (!pair.ok()) GTEST_SKIP() << "this machine does not allow network namespaces and veth pairs; not run";
  const fs::path dir = test::fresh_dir("pmlsm_tool", "ethercat_soem_drive");
  test::ChildProcess slave(pair.in(pair.slave_ns(), {bin("pmlsm"), "ethercat", "serve", "--drive", "--interface",
                                                     pair.slave_if(), "--seconds", "120"}),
                           (dir / "serve.log").string());
  ASSERT_TRUE(slave.wait_for_output("serving a virtual EtherCAT CiA 402 drive", kRunTimeout)) << slave.output();
  test::ChildProcess soem(pair.in(pair.master_ns(), {"/usr/bin/env", "node", source("tests/node/soem_master.mjs"),
                                                     pair.master_if(), "--walk", "--exchange", "10000"}),
                          (dir / "soem.log").string());
  EXPECT_EQ(run_to_end(soem), 0) << soem.output();
  const std::string out = soem.output();
  EXPECT_NE(out.find("\"op\":8"), std::string::npos) << out;
  // SOEM's controlwords walked the simulated drive to operation enabled (statusword 0x0237), and
  // its 100 per mille (67.5 N of configs/canopen/drive.yaml's 675 N) moved the motor forward.
  EXPECT_NE(out.find("\"statusword_enabled\":\"237\""), std::string::npos) << out;
  const std::optional<long long> start = json_integer(out, "position_start");
  const std::optional<long long> end = json_integer(out, "position_end");
  ASSERT_TRUE(start && end) << out;
  EXPECT_GT(*end - *start, 100) << "increments of 1 um over 200 cycles at 67.5 N; " << out;
  // Then 10,000 cycles of process data, each answered with working counter 3 (the target).
  EXPECT_NE(out.find("\"exchange\":{\"cycles\":10000,\"wkc_errors\":0,"), std::string::npos) << out;
  // SOEM stopped cycling without leaving OP: the process-data watchdog (100 ms) took the slave to
  // SAFEOP and faulted the enabled drive, force off.
  ASSERT_TRUE(slave.wait_for_output("process-data watchdog expired", kRunTimeout)) << slave.output();
  slave.signal(SIGINT);
  const std::optional<int> code = slave.wait_for(kRunTimeout);
  ASSERT_TRUE(code.has_value());
  EXPECT_EQ(*code, kExitSafeState) << "a drive that faulted while served is no clean run; " << slave.output();
  EXPECT_NE(slave.output().find("AL state SAFEOP;"), std::string::npos) << slave.output();
  EXPECT_NE(slave.output().find("(last 0x8700)"), std::string::npos) << slave.output();
}

}  // namespace
}  // namespace pmlsm

// foxglove_bridge against the running loop (plant_sim + controller, realtime), with
// third-party Foxglove clients: tests/node/ws_client.mjs under Node.js, which decodes what it
// gets with Foxglove's own libraries. Each test has its own DDS domain (offsets 25..29) and
// lets the bridge pick a free port, which it prints.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "integration_support.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::bin;
using test::ChildProcess;
using test::node_args;
using test::source;
using test::test_domain;

constexpr std::chrono::seconds kStartTimeout{15};
/// Topics in the catalog (common/dds/src/catalog.cpp), all of which the bridge advertises.
constexpr int kCatalogTopics = 24;

std::vector<std::string> bridge_args(const std::string& domain, std::vector<std::string> extra = {}) {
  std::vector<std::string> a{bin("foxglove_bridge"),
                             "--domain",
                             domain,
                             "--profiles",
                             source("configs/dds/profiles.xml"),
                             "--address",
                             "127.0.0.1",
                             "--port",
                             "0"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

std::vector<std::string> ws_client_args(const std::string& url, std::vector<std::string> extra) {
  std::vector<std::string> a{PMLSM_NODE, source("tests/node/ws_client.mjs"), "--url", url};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

/// The bridge's "listening on ws://127.0.0.1:PORT" line, as a URL; empty if it never came.
std::string wait_for_url(const ChildProcess& bridge) {
  const std::string prefix = "listening on ws://127.0.0.1:";
  if (!bridge.wait_for_output(prefix, kStartTimeout)) return "";
  std::smatch m;
  const std::string out = bridge.output();
  if (!std::regex_search(out, m, std::regex("listening on (ws://127\\.0\\.0\\.1:[0-9]+)"))) return "";
  return m[1];
}

/// The pulse scenario lasting `duration_s`: the stream a live view gets.
std::string scenario_lasting(const fs::path& dir, double duration_s) {
  std::istringstream in(test::read_file(source("configs/scenarios/pulse.yaml")));
  std::ofstream out(dir / "scenario.yaml");
  for (std::string line; std::getline(in, line);) {
    out << (line.rfind("duration_s:", 0) == 0 ? "duration_s: " + std::to_string(duration_s) : line) << "\n";
  }
  return (dir / "scenario.yaml").string();
}

/// The JSON summary ws_client.mjs prints last.
json summary_of(const std::string& output) {
  std::istringstream lines(output);
  json last;
  for (std::string line; std::getline(lines, line);) {
    if (!line.empty() && line.front() == '{') last = json::parse(line, nullptr, false);
  }
  return last;
}

/// A count from the bridge's exit line ("foxglove_bridge: 40 samples read, 12 frames sent, 3
/// dropped, ..."); -1 if absent.
long long bridge_count(const std::string& output, const std::string& what) {
  std::smatch line;
  if (!std::regex_search(output, line, std::regex("[0-9]+ samples read,[^\n]*"))) return -1;
  const std::string exit_line = line.str();
  std::smatch m;
  if (!std::regex_search(exit_line, m, std::regex("([0-9]+) " + what))) return -1;
  return std::stoll(m[1]);
}

/// plant_sim and controller in realtime for `scenario`; the plant waits for two MotorFeedback
/// readers, the controller's and the bridge's.
struct Loop {
  Loop(const std::string& domain, const std::string& scenario, const fs::path& dir)
      : controller(node_args("controller", domain, scenario, {"--clock", "realtime", "--plant-lost-ms", "5000"}),
                   (dir / "controller.log").string()),
        plant(
            node_args("plant_sim", domain, scenario,
                      {"--clock", "realtime", "--peers", "2", "--watchdog-ms", "1000", "--controller-lost-ms", "5000"}),
            (dir / "plant.log").string()) {}
  void expect_clean_exit() {
    for (auto* p : {&plant, &controller}) {
      const auto code = p->wait_for(std::chrono::seconds(30));
      ASSERT_TRUE(code.has_value()) << "still running:\n" << p->output();
      EXPECT_EQ(*code, 0) << p->output();
    }
  }
  ChildProcess controller;
  ChildProcess plant;
};

void expect_clean_stop(ChildProcess& bridge) {
  bridge.signal(SIGINT);
  const auto code = bridge.wait_for(std::chrono::seconds(10));
  ASSERT_TRUE(code.has_value()) << "bridge still running after SIGINT:\n" << bridge.output();
  EXPECT_EQ(*code, 0) << bridge.output();
}

TEST(FoxgloveBridge, AnUnknownTopicIsABadOptionListingTheKnownOnes) {
  const fs::path dir = test::fresh_dir("pmlsm_bridge", "unknown_topic");
  ChildProcess bridge(bridge_args(test_domain(25), {"--topics", "/pmlsm/motor_feedback,/pmlsm/nope"}),
                      (dir / "bridge.log").string());
  const auto code = bridge.wait_for(std::chrono::seconds(20));
  ASSERT_TRUE(code.has_value()) << bridge.output();
  EXPECT_EQ(*code, 2) << bridge.output();
  EXPECT_NE(bridge.output().find("unknown topic '/pmlsm/nope'"), std::string::npos) << bridge.output();
  EXPECT_NE(bridge.output().find("/pmlsm/force_command  (pmlsm_msgs::msg::ForceCommand)"), std::string::npos)
      << bridge.output();
  fs::remove_all(dir);
}

// The Foxglove client library connects, finds every topic advertised as cdr + omgidl, and
// decodes the loop's feedback and commands with Foxglove's IDL parser and CDR reader.
TEST(FoxgloveBridge, AFoxgloveClientDecodesTheLiveLoop) {
  const fs::path dir = test::fresh_dir("pmlsm_bridge", "live");
  const std::string domain = test_domain(26);
  const std::string scenario = scenario_lasting(dir, 3.0);
  ChildProcess bridge(bridge_args(domain), (dir / "bridge.log").string());
  const std::string url = wait_for_url(bridge);
  ASSERT_FALSE(url.empty()) << bridge.output();

  ChildProcess client(ws_client_args(url, {"--topics", "/pmlsm/motor_feedback,/pmlsm/force_command", "--min-messages",
                                           "1000", "--timeout-s", "25"}),
                      (dir / "client.log").string());
  ASSERT_TRUE(client.wait_for_output("ws_client: subscribed", kStartTimeout)) << client.output();
  ASSERT_TRUE(bridge.wait_for_output("reading 2 of " + std::to_string(kCatalogTopics) + " topics", kStartTimeout))
      << bridge.output();
  Loop loop(domain, scenario, dir);

  const auto code = client.wait_for(std::chrono::seconds(30));
  ASSERT_TRUE(code.has_value()) << client.output();
  EXPECT_EQ(*code, 0) << client.output() << bridge.output();
  const json summary = summary_of(client.output());
  ASSERT_TRUE(summary.is_object()) << client.output();
  EXPECT_EQ(summary["ok"], true) << summary.dump(2);
  EXPECT_EQ(summary["channels_advertised"], kCatalogTopics) << summary.dump(2);
  EXPECT_EQ(summary["server"]["name"], "pmlsm foxglove_bridge");
  for (const char* topic : {"/pmlsm/motor_feedback", "/pmlsm/force_command"}) {
    EXPECT_GE(summary["topics"][topic]["messages"].get<int>(), 1000) << summary.dump(2);
  }
  EXPECT_EQ(summary["topics"]["/pmlsm/force_command"]["schema_name"], "pmlsm_msgs::msg::ForceCommand");

  loop.expect_clean_exit();
  expect_clean_stop(bridge);
  EXPECT_GE(bridge_count(bridge.output(), "frames sent"), 2000) << bridge.output();
  EXPECT_EQ(bridge_count(bridge.output(), "bad requests"), 0) << bridge.output();
  if (!HasFailure()) fs::remove_all(dir);
}

// Garbage on other connections (not JSON, wrong types, binary frames, bad UTF-8, oversized,
// unknown ops, no subprotocol, not even HTTP): each is answered and closed or refused, while a
// good client keeps receiving the loop.
TEST(FoxgloveBridge, GarbageClientsAreDisconnectedWhileAGoodClientKeepsReceiving) {
  const fs::path dir = test::fresh_dir("pmlsm_bridge", "garbage");
  const std::string domain = test_domain(27);
  const std::string scenario = scenario_lasting(dir, 5.0);
  ChildProcess bridge(bridge_args(domain), (dir / "bridge.log").string());
  const std::string url = wait_for_url(bridge);
  ASSERT_FALSE(url.empty()) << bridge.output();

  // 3000 of the 5000 ticks: the good client must keep receiving after the garbage, which
  // starts with its first message and takes about a second.
  ChildProcess good(
      ws_client_args(url, {"--topics", "/pmlsm/motor_feedback", "--min-messages", "3000", "--timeout-s", "25"}),
      (dir / "good_client.log").string());
  ASSERT_TRUE(good.wait_for_output("ws_client: subscribed", kStartTimeout)) << good.output();
  ASSERT_TRUE(bridge.wait_for_output("reading 1 of " + std::to_string(kCatalogTopics) + " topics", kStartTimeout))
      << bridge.output();
  Loop loop(domain, scenario, dir);
  ASSERT_TRUE(good.wait_for_output("ws_client: receiving", kStartTimeout)) << good.output() << loop.plant.output();

  ChildProcess garbage(ws_client_args(url, {"--mode", "garbage", "--expect-data"}),
                       (dir / "garbage_client.log").string());
  const auto garbage_code = garbage.wait_for(std::chrono::seconds(30));
  ASSERT_TRUE(garbage_code.has_value()) << garbage.output();
  EXPECT_EQ(*garbage_code, 0) << garbage.output();
  const json garbage_summary = summary_of(garbage.output());
  EXPECT_EQ(garbage_summary["ok"], true) << garbage_summary.dump(2);

  const auto good_code = good.wait_for(std::chrono::seconds(30));
  ASSERT_TRUE(good_code.has_value()) << good.output();
  EXPECT_EQ(*good_code, 0) << good.output();
  const json summary = summary_of(good.output());
  EXPECT_GE(summary["topics"]["/pmlsm/motor_feedback"]["messages"].get<int>(), 3000) << summary.dump(2);

  loop.expect_clean_exit();
  expect_clean_stop(bridge);
  // not_json, not_an_object, no_op, bad_field_types, binary_frame, invalid_utf8_text, oversized_text.
  EXPECT_EQ(bridge_count(bridge.output(), "connections closed for bad input"), 7) << bridge.output();
  // no_subprotocol, raw_tcp_junk.
  EXPECT_EQ(bridge_count(bridge.output(), "handshakes refused"), 2) << bridge.output();
  if (!HasFailure()) fs::remove_all(dir);
}

// A client that stops reading loses frames (counted, and shown in the bridge's NodeStatus)
// while another client gets the loop at full rate.
TEST(FoxgloveBridge, ASlowClientLosesFramesNotTheOthers) {
  const fs::path dir = test::fresh_dir("pmlsm_bridge", "slow");
  const std::string domain = test_domain(28);
  const std::string scenario = scenario_lasting(dir, 5.0);
  ChildProcess bridge(
      bridge_args(domain, {"--client-buffer-kib", "32", "--queue-frames", "64", "--status-period-s", "0.2"}),
      (dir / "bridge.log").string());
  const std::string url = wait_for_url(bridge);
  ASSERT_FALSE(url.empty()) << bridge.output();

  ChildProcess stalled(
      ws_client_args(url, {"--mode", "stall", "--topics", "all", "--duration-s", "10", "--timeout-s", "25"}),
      (dir / "stalled_client.log").string());
  ASSERT_TRUE(stalled.wait_for_output("ws_client: stalled", kStartTimeout)) << stalled.output();
  ChildProcess good(ws_client_args(url, {"--topics", "/pmlsm/motor_feedback,/pmlsm/node_status", "--min-messages", "3",
                                         "--duration-s", "9", "--timeout-s", "25"}),
                    (dir / "good_client.log").string());
  ASSERT_TRUE(good.wait_for_output("ws_client: subscribed", kStartTimeout)) << good.output();
  ASSERT_TRUE(bridge.wait_for_output(
      "reading " + std::to_string(kCatalogTopics) + " of " + std::to_string(kCatalogTopics) + " topics", kStartTimeout))
      << bridge.output();
  Loop loop(domain, scenario, dir);

  const auto good_code = good.wait_for(std::chrono::seconds(30));
  ASSERT_TRUE(good_code.has_value()) << good.output();
  EXPECT_EQ(*good_code, 0) << good.output();
  const json summary = summary_of(good.output());
  EXPECT_GE(summary["topics"]["/pmlsm/motor_feedback"]["messages"].get<int>(), 4000) << summary.dump(2);
  const json& bridge_status = summary["node_status"]["foxglove_bridge"];
  ASSERT_TRUE(bridge_status.is_object()) << summary.dump(2);
  EXPECT_GT(std::stoll(bridge_status["late"].get<std::string>()), 0) << "dropped frames in NodeStatus.late\n"
                                                                     << summary.dump(2) << bridge.output();

  const auto stalled_code = stalled.wait_for(std::chrono::seconds(30));
  ASSERT_TRUE(stalled_code.has_value()) << stalled.output();
  EXPECT_EQ(*stalled_code, 0) << stalled.output();
  EXPECT_EQ(summary_of(stalled.output())["ok"], true) << stalled.output();
  loop.expect_clean_exit();
  expect_clean_stop(bridge);
  EXPECT_GT(bridge_count(bridge.output(), "dropped"), 0) << bridge.output();
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace pmlsm

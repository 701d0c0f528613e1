// Interoperation on the wire: our Fast DDS nodes and a Cyclone DDS participant (cyclone_subscriber,
// with Cyclone's own type support made by idlc from our IDL) on one domain. Cyclone must discover
// and match our writers and readers (type names, QoS), decode our XCDR1 samples to the very values
// the nodes computed, and the Fast DDS plant must run in lockstep on commands Cyclone serialised.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "integration_support.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/config/config.hpp"

namespace pmlsm {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

using test::bin;
using test::node_args;
using test::source;
using test::test_domain;

// cyclone_subscriber's CSV: per topic a "# topic: col,col,..." line, then one row per sample.
struct TopicRows {
  std::map<std::string, std::size_t> column;  // name -> index in a row
  std::vector<std::vector<std::string>> rows;

  const std::string& at(std::size_t row, const std::string& name) const { return rows.at(row).at(column.at(name)); }
  double number(std::size_t row, const std::string& name) const { return std::stod(at(row, name)); }
  std::uint64_t integer(std::size_t row, const std::string& name) const { return std::stoull(at(row, name)); }
};

std::vector<std::string> split(const std::string& line, char sep) {
  std::vector<std::string> fields;
  std::istringstream in(line);
  for (std::string f; std::getline(in, f, sep);) fields.push_back(f);
  return fields;
}

std::map<std::string, TopicRows> read_cyclone_csv(const fs::path& path) {
  std::map<std::string, TopicRows> topics;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("# ", 0) == 0) {
      const std::size_t colon = line.find(": ");
      if (colon == std::string::npos) continue;
      const std::vector<std::string> names = split(line.substr(colon + 2), ',');
      TopicRows& t = topics[line.substr(2, colon - 2)];
      for (std::size_t i = 0; i < names.size(); ++i) t.column[names[i]] = i;
    } else if (!line.empty()) {
      std::vector<std::string> fields = split(line, ',');
      topics[fields.front()].rows.push_back(std::move(fields));
    }
  }
  return topics;
}

// --linger-s: a Cyclone participant that exits as soon as it has its samples leaves the last ones
// unacknowledged, and Fast DDS 2.9 notices it gone only when its lease expires, so the nodes'
// final wait for acknowledgments would last that long; lingering until the writers have gone
// lets the nodes finish at once. The subscriber's 3 s lease (Cyclone's default is 10 s) bounds that
// wait when it fails.
std::vector<std::string> cyclone_args(const std::string& domain, const std::vector<std::string>& topics,
                                      std::uint64_t count, const fs::path& csv, std::vector<std::string> extra = {}) {
  std::vector<std::string> a{bin("cyclone_subscriber"),
                             "--domain",
                             domain,
                             "--count",
                             std::to_string(count),
                             "--timeout-s",
                             "45",
                             "--linger-s",
                             "20",
                             "--out",
                             csv.string(),
                             "--cyclone-config",
                             "<Discovery><LeaseDuration>3s</LeaseDuration></Discovery>"};
  for (const std::string& t : topics) {
    a.push_back("--topic");
    a.push_back(t);
  }
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

// Counts the rows where `received` differs from `expected` and names the first one, instead of
// one failure per tick.
class Mismatches {
 public:
  void check(bool equal, const std::string& what) {
    if (equal) return;
    if (count_ == 0) first_ = what;
    ++count_;
  }
  std::string report() const { return std::to_string(count_) + " mismatches; first: " + first_; }
  bool none() const { return count_ == 0; }

 private:
  std::size_t count_ = 0;
  std::string first_;
};

std::string describe(const std::string& topic, std::uint64_t tick, const std::string& field, double received,
                     double expected) {
  std::ostringstream s;
  s.precision(17);
  s << topic << " tick " << tick << " " << field << ": Cyclone got " << received << ", the loop computed " << expected;
  return s.str();
}

// Every tick 0..ticks-1 exactly once and in order: nothing lost, duplicated or reordered.
void expect_consecutive_ticks(const std::string& topic, const TopicRows& t, std::uint64_t ticks) {
  ASSERT_EQ(t.rows.size(), ticks) << topic;
  for (std::uint64_t k = 0; k < ticks; ++k) {
    ASSERT_EQ(t.integer(k, "tick"), k) << topic << " row " << k;
    // make_stamp: tick * 1 ms in ns.
    ASSERT_EQ(t.integer(k, "sim_time_ns"), k * 1000000) << topic << " row " << k;
  }
}

// Cyclone first, then the controller, then the plant, all lockstep on the pulse scenario. The
// plant waits for two MotorFeedback readers (the controller's and Cyclone's) before tick 0, but
// nothing in the controller waits for Cyclone, and the lockstep run is over in a fraction of a
// second: if Cyclone matched the controller's writers only after they were gone, their
// transient-local history would go with them. So the plant starts once Cyclone reports the
// controller's writers matched. The values must equal the in-process loop's bit for bit: the
// lockstep run is deterministic (DistributedLockstep checks the same for the evaluator).
TEST(CycloneSubscriber, GetsEveryTickOfTheLockstepLoopWithTheInProcessLoopsValues) {
  const std::string scenario = source("configs/scenarios/pulse.yaml");
  const SystemParams params = load_system_params(source("configs/system.yaml"));
  const Scenario sc = load_scenario(scenario, params.timing.control_period_s);
  const std::vector<TickRecord> expected = run_scenario(params, sc);
  const std::uint64_t ticks = expected.size();
  ASSERT_EQ(ticks, 2000u);

  const fs::path dir = test::fresh_dir("pmlsm_interop", "subscriber");
  const std::string domain = test_domain(20);
  const fs::path csv = dir / "cyclone.csv";
  test::ChildProcess cyclone(
      cyclone_args(domain, {"motor_feedback", "force_command", "plant_truth", "velocity_reference"}, ticks, csv),
      (dir / "cyclone.log").string());
  ASSERT_TRUE(cyclone.wait_for_output("readers ready", 20s)) << cyclone.output();
  test::ChildProcess controller(node_args("controller", domain, scenario), (dir / "controller.log").string());
  ASSERT_TRUE(cyclone.wait_for_output("rt/pmlsm/force_command: 1 matched writers", 20s)) << cyclone.output();
  ASSERT_TRUE(cyclone.wait_for_output("rt/pmlsm/velocity_reference: 1 matched writers", 20s)) << cyclone.output();
  test::ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", "2"}), (dir / "plant.log").string());

  for (auto* p : {&plant, &controller, &cyclone}) {
    const auto code = p->wait_for(60s);
    ASSERT_TRUE(code.has_value()) << "still running:\n" << p->output();
    EXPECT_EQ(*code, 0) << p->output();
  }
  EXPECT_NE(plant.output().find("late 0, rejected 0"), std::string::npos) << plant.output();

  const auto topics = read_cyclone_csv(csv);
  for (const char* topic : {"motor_feedback", "force_command", "plant_truth", "velocity_reference"}) {
    ASSERT_EQ(topics.count(topic), 1u) << topic << " missing in " << csv;
    expect_consecutive_ticks(topic, topics.at(topic), ticks);
  }
  const TopicRows& feedback = topics.at("motor_feedback");
  const TopicRows& command = topics.at("force_command");
  const TopicRows& truth = topics.at("plant_truth");
  const TopicRows& reference = topics.at("velocity_reference");
  Mismatches mismatches;
  auto same = [&](const std::string& topic, const TopicRows& t, std::uint64_t k, const std::string& field,
                  double want) {
    const double got = t.number(k, field);
    mismatches.check(got == want, describe(topic, k, field, got, want));
  };
  for (std::uint64_t k = 0; k < ticks; ++k) {
    const TickRecord& r = expected[k];
    same("motor_feedback", feedback, k, "position_m", r.encoder_position_m);
    same("motor_feedback", feedback, k, "velocity_mps", r.motor_velocity_measured_mps);
    same("motor_feedback", feedback, k, "applied_force_n", k == 0 ? 0.0 : expected[k - 1].force_command_n);
    same("motor_feedback", feedback, k, "applied_command_tick", k == 0 ? 0.0 : static_cast<double>(k - 1));
    same("force_command", command, k, "feedback_tick", static_cast<double>(k));
    same("force_command", command, k, "force_n", r.force_command_n);
    same("force_command", command, k, "compensation_force_n", 0.0);
    same("plant_truth", truth, k, "motor_position_m", r.motor_position_m);
    same("plant_truth", truth, k, "motor_velocity_mps", r.motor_velocity_mps);
    same("plant_truth", truth, k, "load_position_m", r.load_position_m);
    same("plant_truth", truth, k, "load_velocity_mps", r.load_velocity_mps);
    same("plant_truth", truth, k, "load_acceleration_mps2", r.load_accel_mps2);
    same("plant_truth", truth, k, "spring_force_n", r.spring_force_n);
    same("plant_truth", truth, k, "thrust_force_n", r.thrust_n);
    same("plant_truth", truth, k, "ripple_force_n", r.ripple_n);
    same("plant_truth", truth, k, "friction_force_n", r.friction_n);
    same("plant_truth", truth, k, "i_q_a", r.i_q_a);
    same("velocity_reference", reference, k, "velocity_command_mps", r.command_mps);
    same("velocity_reference", reference, k, "v_ref_mps", r.v_ref_mps);
  }
  EXPECT_TRUE(mismatches.none()) << mismatches.report() << " (" << dir << ")";
  // The pulse moves the load: equal values are not all zeros.
  EXPECT_GT(std::abs(truth.number(ticks - 1, "load_position_m")), 1e-3);
  if (!HasFailure()) fs::remove_all(dir);
}

// The other direction: Cyclone is the controller. It answers MotorFeedback tick k with a
// ForceCommand of (-1)^k * 20 N, and the Fast DDS plant, in lockstep, takes each one as the answer
// to its tick and applies it; its next MotorFeedback and PlantTruth report the force it applied.
//
// With `ros2_default_qos` the Cyclone readers are volatile, as ROS 2's default: a volatile reader
// gets what is written after it has matched the writer, and the plant's wait for its peers (its
// writer matched to the reader) can end before the reader's side has matched; tick 0, or the
// first ticks of PlantTruth, would then go unseen. So the plant waits for a second MotorFeedback
// reader, a transient-local Cyclone that only listens, started once the first reports both its
// readers matched. Every MotorFeedback is still seen and answered (the plant waits for each
// answer); PlantTruth is not paced by anything, and a keep-last-10 reader keeps only the newest
// 10 of a burst, as when a sample lost on the wire is repaired with the ones written meanwhile.
// Its samples come in order, end with the last tick and carry the commands' forces.
void expect_plant_runs_on_cyclone_commands(int domain_offset, const std::string& dir_name, bool ros2_default_qos) {
  std::vector<std::string> answer_args{"--answer-force-n", "20"};
  if (ros2_default_qos) {
    for (const char* a : {"--ros2-default-qos", "--lossy", "plant_truth"}) answer_args.emplace_back(a);
  }
  const std::string scenario = source("configs/scenarios/pulse.yaml");
  const std::uint64_t ticks = 2000;  // the pulse scenario's 2 s
  const double force_n = 20.0;
  const fs::path dir = test::fresh_dir("pmlsm_interop", dir_name);
  const std::string domain = test_domain(domain_offset);
  const fs::path csv = dir / "cyclone.csv";
  test::ChildProcess cyclone(cyclone_args(domain, {"motor_feedback", "plant_truth"}, ticks, csv, answer_args),
                             (dir / "cyclone.log").string());
  ASSERT_TRUE(cyclone.wait_for_output("readers ready", 20s)) << cyclone.output();
  test::ChildProcess plant(node_args("plant_sim", domain, scenario, {"--peers", ros2_default_qos ? "2" : "1"}),
                           (dir / "plant.log").string());
  std::optional<test::ChildProcess> gate;
  if (ros2_default_qos) {
    for (const char* topic : {"motor_feedback", "plant_truth"}) {
      ASSERT_TRUE(cyclone.wait_for_output(std::string("rt/pmlsm/") + topic + ": 1 matched writers", 20s))
          << cyclone.output();
    }
    gate.emplace(cyclone_args(domain, {"motor_feedback"}, ticks, dir / "gate.csv"), (dir / "gate.log").string());
  }

  for (auto* p : {&plant, &cyclone}) {
    const auto code = p->wait_for(60s);
    ASSERT_TRUE(code.has_value()) << "still running:\n" << p->output();
    EXPECT_EQ(*code, 0) << p->output();
  }
  if (gate) {
    const auto code = gate->wait_for(60s);
    ASSERT_TRUE(code.has_value()) << "still running:\n" << gate->output();
    EXPECT_EQ(*code, 0) << gate->output();
  }
  // Every tick answered in time, by a command for that very tick, with a finite force.
  EXPECT_NE(plant.output().find("2000 ticks in"), std::string::npos) << plant.output();
  EXPECT_NE(plant.output().find("late 0, rejected 0"), std::string::npos) << plant.output();
  EXPECT_NE(cyclone.output().find("answered 2000 ticks"), std::string::npos) << cyclone.output();

  const auto topics = read_cyclone_csv(csv);
  for (const char* topic : {"motor_feedback", "plant_truth"}) {
    ASSERT_EQ(topics.count(topic), 1u) << topic << " missing in " << csv;
  }
  const TopicRows& feedback = topics.at("motor_feedback");
  const TopicRows& truth = topics.at("plant_truth");
  expect_consecutive_ticks("motor_feedback", feedback, ticks);
  if (ros2_default_qos) {
    // In order and ending at the last tick; most of them (a burst loses what exceeds 10).
    ASSERT_GE(truth.rows.size(), ticks / 2) << csv;
    for (std::size_t row = 1; row < truth.rows.size(); ++row) {
      ASSERT_GT(truth.integer(row, "tick"), truth.integer(row - 1, "tick")) << "plant_truth row " << row;
    }
    ASSERT_EQ(truth.integer(truth.rows.size() - 1, "tick"), ticks - 1) << csv;
    std::printf("PlantTruth through ROS 2's default QoS: %zu of %llu ticks\n", truth.rows.size(),
                static_cast<unsigned long long>(ticks));
  } else {
    expect_consecutive_ticks("plant_truth", truth, ticks);
  }
  // The answer to tick k-1, applied in tick k.
  auto answer_to_previous = [&](std::uint64_t k) { return ((k - 1) % 2 == 0 ? 1.0 : -1.0) * force_n; };
  Mismatches mismatches;
  for (std::uint64_t k = 1; k < ticks; ++k) {
    const double sent = answer_to_previous(k);
    mismatches.check(feedback.number(k, "applied_force_n") == sent,
                     describe("motor_feedback", k, "applied_force_n", feedback.number(k, "applied_force_n"), sent));
    mismatches.check(
        feedback.integer(k, "applied_command_tick") == k - 1,
        "motor_feedback tick " + std::to_string(k) + " applied_command_tick " + feedback.at(k, "applied_command_tick"));
  }
  for (std::size_t row = 0; row < truth.rows.size(); ++row) {
    const std::uint64_t k = truth.integer(row, "tick");
    if (k == 0) continue;
    const double sent = answer_to_previous(k);
    mismatches.check(truth.number(row, "command_force_n") == sent,
                     describe("plant_truth", k, "command_force_n", truth.number(row, "command_force_n"), sent));
  }
  EXPECT_TRUE(mismatches.none()) << mismatches.report() << " (" << dir << ")";
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

TEST(CycloneController, FastDdsPlantRunsInLockstepOnCycloneCommands) {
  expect_plant_runs_on_cyclone_commands(21, "controller", false);
}

// A ROS 2 subscriber that asks for nothing (`ros2 topic echo`): the reader QoS rmw gives it by
// default (reliable, volatile, keep last 10) and ROS 2's DDS type names, which our writers
// register (pmlsm/dds/ros2_names.hpp). It matches our writers as they are and, once it has
// matched, answers every tick of a lockstep run and reads PlantTruth as `ros2 topic echo` would.
TEST(CycloneController, AReaderWithRos2DefaultQosMatchesOurWritersUnderRos2TypeNames) {
  expect_plant_runs_on_cyclone_commands(24, "ros2_qos", true);
}

// Bad input on the wire, from another vendor's writer: before some answers the Cyclone controller
// sends a command for a tick not yet published (999 N) and one with a NaN force. The realtime
// plant must reject and count both and never apply either; the genuine answers still drive it.
TEST(CycloneController, RealtimePlantRejectsFutureTicksAndNanForces) {
  const std::string scenario = source("configs/scenarios/pulse.yaml");
  const std::uint64_t ticks = 2000;
  const fs::path dir = test::fresh_dir("pmlsm_interop", "bad_commands");
  const std::string domain = test_domain(23);
  const fs::path csv = dir / "cyclone.csv";
  test::ChildProcess cyclone(
      cyclone_args(domain, {"motor_feedback", "plant_truth"}, ticks, csv, {"--answer-force-n", "20", "--bad-answers"}),
      (dir / "cyclone.log").string());
  ASSERT_TRUE(cyclone.wait_for_output("readers ready", 20s)) << cyclone.output();
  // A long watchdog: this test is about malformed commands, not about a busy machine's pauses.
  test::ChildProcess plant(
      node_args("plant_sim", domain, scenario, {"--peers", "1", "--clock", "realtime", "--watchdog-ms", "1000"}),
      (dir / "plant.log").string());
  for (auto* p : {&plant, &cyclone}) {
    const auto code = p->wait_for(60s);
    ASSERT_TRUE(code.has_value()) << "still running:\n" << p->output();
    EXPECT_EQ(*code, 0) << p->output();
  }
  const std::string out = plant.output();
  EXPECT_EQ(out.find("safe state"), std::string::npos) << out;

  // The plant's count of rejected commands: at most what was sent, and most of it (the last
  // few may come after the plant's last tick). Had a future tick been applied, every genuine
  // answer after it would have been rejected as stale, far more than was sent.
  const auto sent_at = cyclone.output().find(" malformed commands sent");
  ASSERT_NE(sent_at, std::string::npos) << cyclone.output();
  const std::uint64_t sent = std::stoull(cyclone.output().substr(cyclone.output().rfind(' ', sent_at - 1) + 1));
  const auto rejected_at = out.find("rejected ");
  ASSERT_NE(rejected_at, std::string::npos) << out;
  const std::uint64_t rejected = std::stoull(out.substr(rejected_at + 9));
  EXPECT_GT(sent, 500u) << cyclone.output();  // ticks 3, 10, 17, ... of 2000: 286, two commands each
  EXPECT_LE(rejected, sent) << out;
  EXPECT_GE(rejected, sent / 2) << out;

  const auto topics = read_cyclone_csv(csv);
  ASSERT_EQ(topics.count("motor_feedback"), 1u) << csv;
  ASSERT_EQ(topics.count("plant_truth"), 1u) << csv;
  Mismatches mismatches;
  bool pushed = false, pulled = false;
  for (const auto* rows : {&topics.at("motor_feedback"), &topics.at("plant_truth")}) {
    const std::string field = rows == &topics.at("motor_feedback") ? "applied_force_n" : "command_force_n";
    for (std::size_t r = 0; r < rows->rows.size(); ++r) {
      const double force_n = rows->number(r, field);
      mismatches.check(
          force_n == 0.0 || force_n == 20.0 || force_n == -20.0,
          field + " row " + std::to_string(r) + " = " + rows->at(r, field) + " (only 0 or +-20 N were sent)");
      pushed = pushed || force_n == 20.0;
      pulled = pulled || force_n == -20.0;
    }
  }
  EXPECT_TRUE(mismatches.none()) << mismatches.report() << " (" << dir << ")";
  EXPECT_TRUE(pushed && pulled) << "the genuine answers were not applied (" << dir << ")";
  if (!HasFailure()) fs::remove_all(dir);
}

TEST(CycloneSubscriber, ReportsPerTopicCountsWhenItTimesOut) {
  const fs::path dir = test::fresh_dir("pmlsm_interop", "timeout");
  // A domain with no writers of these topics.
  test::ChildProcess cyclone(
      {bin("cyclone_subscriber"), "--domain", test_domain(22), "--topic", "motor_feedback", "--topic", "force_command",
       "--count", "1", "--timeout-s", "0.5", "--out", (dir / "cyclone.csv").string()},
      (dir / "cyclone.log").string());
  const auto code = cyclone.wait_for(30s);
  ASSERT_TRUE(code.has_value()) << cyclone.output();
  EXPECT_EQ(*code, 1) << cyclone.output();
  const std::string out = cyclone.output();
  EXPECT_NE(out.find("timeout after 0.5 s"), std::string::npos) << out;
  EXPECT_NE(out.find("motor_feedback 0 (0 matched writers)"), std::string::npos) << out;
  EXPECT_NE(out.find("force_command 0 (0 matched writers)"), std::string::npos) << out;
  fs::remove_all(dir);
}

TEST(CycloneSubscriber, RefusesBadCommandLinesWithExitCode2) {
  const fs::path dir = test::fresh_dir("pmlsm_interop", "badargs");
  const std::string csv = (dir / "x.csv").string();
  const std::string exe = bin("cyclone_subscriber");
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases{
      {{exe, "--topic", "motor_feedbak", "--count", "1", "--out", csv}, "unknown topic 'motor_feedbak'"},
      {{exe, "--topic", "motor_feedback", "--out", csv}, "no --count given"},
      {{exe, "--topic", "motor_feedback", "--count", "0", "--out", csv}, "--count: '0' is not a positive integer"},
      {{exe, "--topic", "motor_feedback", "--count", "1"}, "no --out given"},
      {{exe, "--count", "1", "--out", csv}, "no --topic given"},
      {{exe, "--topic", "motor_feedback", "--count", "1", "--out", csv, "--domain", "233"}, "not a domain id"},
      {{exe, "--topic", "motor_feedback", "--count", "1", "--out", csv, "--timeout-s", "soon"}, "--timeout-s: 'soon'"},
      {{exe, "--topic", "force_command", "--count", "1", "--out", csv, "--answer-force-n", "1"},
       "add --topic motor_feedback"},
      {{exe, "--topic", "motor_feedback", "--count", "1", "--out", csv, "--verbose", "1"},
       "unknown option '--verbose'"},
      {{exe, "--topic", "motor_feedback", "--count", "1", "--out"}, "--out needs a value"},
      {{exe, "--topic", "motor_feedback", "--count", "1", "--out", csv, "--ros2-default-qos", "--lossy", "plant_truth"},
       "--lossy plant_truth: not a --topic"},
      {{exe, "--topic", "plant_truth", "--count", "1", "--out", csv, "--lossy", "plant_truth"},
       "--lossy needs --ros2-default-qos"},
  };
  for (const auto& [args, message] : cases) {
    test::ChildProcess p(args, (dir / "bad.log").string());
    const auto code = p.wait_for(30s);
    ASSERT_TRUE(code.has_value()) << message;
    EXPECT_EQ(*code, 2) << message << ": " << p.output();
    EXPECT_NE(p.output().find(message), std::string::npos) << p.output();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace pmlsm

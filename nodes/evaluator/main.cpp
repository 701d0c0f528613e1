// evaluator: the rig's scope. Collects every tick of MotorFeedback,
// PlantTruth, VelocityReference, ForceCommand and EstimatedState into the
// same records the in-process loop writes, and when the scenario's last tick
// is complete prints the results table and writes <out>/<scenario>.csv.
// It reads PlantTruth, which no controller may: evaluation only.
//
// It never presents an invalid run as valid:
//   - a tick at which the drive had its force off (MotorFeedback STATUS_SAFE_STATE or
//     STATUS_FAULT, or a power state other than operation enabled) marks the row INVALID with
//     the reason; the CSV is still written and the exit code is kExitSafeState (5);
//   - a sample of any topic stamped with another run_id than the first one seen (0 ignored)
//     means the drive restarted mid-run: no table, no CSV, exit kExitPeerLost (4).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <vector>

#include "EstimatedStatePubSubTypes.h"
#include "ForceCommandPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "PlantTruthPubSubTypes.h"
#include "VelocityReferencePubSubTypes.h"
#include "msg_mapping.hpp"
#include "node_support.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/metrics.hpp"
#include "results_table.hpp"
#include "run_validity.hpp"
#include "trace_csv.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;

enum Part : unsigned { kFeedback = 1, kTruth = 2, kReference = 4, kCommand = 8, kEstimate = 16, kAll = 31 };

int run(int argc, char** argv) {
  CLI::App app{"Collects a distributed run's topics per tick, prints the results table, writes the CSV trace"};
  node::CommonOptions common;
  common.spin_us = 0.0;
  std::string out_dir = "out";
  bool print_header = true;
  node::add_common_options(app, common);
  app.add_option("-o,--out", out_dir, "Folder for the CSV trace");
  app.add_option("--header", print_header, "Print the table header (true/false)");
  std::string label;
  app.add_option("--label", label, "Names this run in the table and the CSV (<scenario>_<label>.csv), e.g. pi_rnn");
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  node::NodeRuntime rt("evaluator", common);
  const node::LoadedConfig& cfg = rt.cfg;
  const double period = rt.period_s;
  auto feedback_reader = rt.participant.make_reader<pmlsm_msgs::msg::MotorFeedbackPubSubType>(pdds::topics::kMotorFeedback, rt.wakeup, pdds::kObserverProfile);
  auto truth_reader = rt.participant.make_reader<pmlsm_msgs::msg::PlantTruthPubSubType>(pdds::topics::kPlantTruth, rt.wakeup, pdds::kObserverProfile);
  auto reference_reader = rt.participant.make_reader<pmlsm_msgs::msg::VelocityReferencePubSubType>(pdds::topics::kVelocityReference, rt.wakeup, pdds::kObserverProfile);
  auto command_reader = rt.participant.make_reader<pmlsm_msgs::msg::ForceCommandPubSubType>(pdds::topics::kForceCommand, rt.wakeup, pdds::kObserverProfile);
  auto estimate_reader = rt.participant.make_reader<pmlsm_msgs::msg::EstimatedStatePubSubType>(pdds::topics::kEstimatedState, rt.wakeup, pdds::kObserverProfile);
  rt.status.publish(node_state::STATE_RUNNING, 0, period, "collecting");

  const std::uint64_t ticks = scenario_ticks(cfg.scenario, period);
  std::vector<TickRecord> trace(ticks);
  std::vector<unsigned> parts(ticks, 0);
  std::uint64_t complete = 0;
  std::uint64_t rejected = 0;
  node::RunValidity validity;  // the drive's status at every tick
  node::RunIdTracker run;      // the drive's run every sample must belong to
  std::optional<node::RunChange> restart;

  auto mark = [&](std::uint64_t tick, Part part) -> TickRecord* {
    if (tick >= ticks || (parts[tick] & part) != 0) {
      ++rejected;  // outside the scenario or a duplicate
      return nullptr;
    }
    parts[tick] |= part;
    if (parts[tick] == kAll) ++complete;
    TickRecord& r = trace[tick];
    r.tick = tick;
    r.time_s = static_cast<double>(tick) * period;
    return &r;
  };

  pmlsm_msgs::msg::MotorFeedback feedback;
  pmlsm_msgs::msg::PlantTruth truth;
  pmlsm_msgs::msg::VelocityReference reference;
  pmlsm_msgs::msg::ForceCommand command;
  pmlsm_msgs::msg::EstimatedState estimate;
  // A sample of another run than the first one seen ends the collection.
  auto same_run = [&](const pmlsm_msgs::msg::Stamp& stamp) {
    if (!restart) restart = run.observe(stamp.run_id(), stamp.tick());
    return !restart;
  };
  node::DriveTickStatus drive_status;
  auto drain = [&] {
    while (!restart && feedback_reader.take(feedback)) {
      if (!same_run(feedback.stamp())) break;
      if (TickRecord* r = mark(feedback.stamp().tick(), kFeedback)) {
        node::from_msg(feedback, *r);
        node::from_msg(feedback, drive_status);
        validity.add(feedback.stamp().tick(), drive_status);
      }
    }
    while (!restart && truth_reader.take(truth)) {
      if (!same_run(truth.stamp())) break;
      if (TickRecord* r = mark(truth.stamp().tick(), kTruth)) node::from_msg(truth, *r);
    }
    while (!restart && reference_reader.take(reference)) {
      if (!same_run(reference.stamp())) break;
      if (TickRecord* r = mark(reference.stamp().tick(), kReference)) node::from_msg(reference, *r);
    }
    while (!restart && command_reader.take(command)) {
      if (!same_run(command.stamp())) break;
      if (TickRecord* r = mark(command.feedback_tick(), kCommand)) node::from_msg(command, *r);
    }
    while (!restart && estimate_reader.take(estimate)) {
      if (!same_run(estimate.stamp())) break;
      if (TickRecord* r = mark(estimate.feedback_tick(), kEstimate)) node::from_msg(estimate, *r);
    }
    return complete == ticks || restart.has_value();
  };

  // Done when every tick is complete; no new complete tick for the peer timeout ends it (checked
  // every 100 ms, so a stall is reported after the timeout, not up to twice it).
  std::uint64_t last_complete = 0;
  auto last_progress = std::chrono::steady_clock::now();
  const auto stall_limit = std::chrono::duration<double>(common.peer_timeout_s);
  while (!pdds::stop_requested()) {
    if (node::wait_until(rt.wakeup, std::chrono::milliseconds(100), drain)) break;
    const auto now = std::chrono::steady_clock::now();
    if (complete != last_complete) {
      last_complete = complete;
      last_progress = now;
    } else if (now - last_progress >= stall_limit) {
      break;
    }
  }

  if (restart) {
    std::fprintf(stderr, "%s\n", node::restart_message("evaluator", *restart).c_str());
    rt.status.publish(node_state::STATE_ERROR, complete, period, "drive restarted mid-run");
    return kExitPeerLost;
  }

  if (complete < ticks) {
    std::fprintf(stderr, "evaluator: only %llu of %llu ticks complete (%s); no results\n",
                 static_cast<unsigned long long>(complete), static_cast<unsigned long long>(ticks),
                 pdds::stop_requested() ? "stopped" : "peers silent");
    // Which topics are missing, and from where: tells a late join from a loss.
    const char* names[] = {"MotorFeedback", "PlantTruth", "VelocityReference", "ForceCommand", "EstimatedState"};
    for (unsigned bit = 0; bit < 5; ++bit) {
      std::uint64_t missing = 0, first = ticks;
      for (std::uint64_t t = 0; t < ticks; ++t) {
        if ((parts[t] & (1u << bit)) == 0) {
          ++missing;
          first = std::min(first, t);
        }
      }
      if (missing > 0) {
        std::fprintf(stderr, "evaluator: %s missing for %llu ticks, the first %llu\n", names[bit],
                     static_cast<unsigned long long>(missing), static_cast<unsigned long long>(first));
      }
    }
    if (!validity.valid()) {
      std::fprintf(stderr, "evaluator: the ticks received are INVALID as well: %s\n", validity.reason().c_str());
    }
    rt.status.publish(node_state::STATE_ERROR, complete, period, "incomplete run");
    // Stopped or stalled before the run was complete: no results, and never exit 0 for that.
    return pdds::stop_requested() ? kExitError : kExitPeerLost;
  }
  const ScenarioMetrics m = compute_metrics(trace, cfg.scenario, period);
  std::filesystem::create_directories(out_dir);
  const std::string run_name = label.empty() ? cfg.scenario.name : cfg.scenario.name + "_" + label;
  write_trace_csv(out_dir + "/" + run_name + ".csv", trace);
  const std::string invalid_reason = validity.reason();  // empty: valid
  if (print_header) node::print_results_header();
  node::print_results_row(label.empty() ? cfg.scenario.name : cfg.scenario.name + " " + label, m,
                          invalid_reason);
  std::fflush(stdout);
  rt.status.status().rejected(rejected);
  if (!invalid_reason.empty()) {
    rt.status.publish(node_state::STATE_ERROR, ticks, period, "invalid run: drive force off");
    return kExitSafeState;
  }
  rt.status.publish(node_state::STATE_STOPPING, ticks, period, "done");
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  return pmlsm::node::run_node("evaluator", [&] { return run(argc, argv); });
}

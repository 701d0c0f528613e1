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
//   - an estimate that reports the load's sensor failed (EstimatedState LOAD_SENSOR_FAILED) marks
//     the row INVALID with the tick and why (the run lost the feedback it was asked to run with);
//     the CSV is still written and the exit code is kExitVerdictFailed (6);
//   - a sample of any topic stamped with another run_id than the first one seen (0 ignored)
//     means the drive restarted mid-run: no table, no CSV, exit kExitPeerLost (4).
// With --truth optional (a real drive, or the virtual rig in realtime, has no PlantTruth): when
// every other topic is complete and no PlantTruth sample came within a second, the row is
// printed with the truth's columns n/a and marked "(no PlantTruth)", and the CSV's true-plant
// columns are nan. A PlantTruth that came for some ticks and not others is an incomplete run.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "EstimatedStatePubSubTypes.h"
#include "ForceCommandPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "PlantTruthPubSubTypes.h"
#include "VelocityReferencePubSubTypes.h"
#include "evaluator_command_line.hpp"
#include "msg_mapping.hpp"
#include "cycle_component.hpp"
#include "node_support.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/metrics.hpp"
#include "results_table.hpp"
#include "run_validity.hpp"
#include "trace_csv.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;

enum Part : unsigned { kFeedback = 1, kTruth = 2, kReference = 4, kCommand = 8, kEstimate = 16, kAll = 31 };
constexpr unsigned kAllButTruth = kAll & ~static_cast<unsigned>(kTruth);
/// --truth optional: how long after the other topics are complete a first PlantTruth may come.
constexpr std::chrono::seconds kTruthGrace{1};

/// The fields from PlantTruth (record_truth in pmlsm/sim/closed_loop.cpp, and u_q_v) as nan.
void clear_truth(TickRecord& r) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  r.motor_position_m = r.motor_velocity_mps = r.load_position_m = r.load_velocity_mps = nan;
  r.load_accel_mps2 = r.spring_force_n = r.thrust_n = r.ripple_n = r.friction_n = r.i_q_a = r.u_q_v = nan;
}

using node::EvaluatorOptions;

class EvaluatorComponent final : public node::CycleComponent {
 public:
  EvaluatorComponent(const node::ComponentContext& context, node::CommonOptions common, const EvaluatorOptions& options)
      : common_(std::move(common)),
        opt_(options),
        rt_("evaluator", common_, context),
        period_s_(rt_.period_s),
        ticks_(scenario_ticks(rt_.cfg.scenario, period_s_)),
        feedback_reader_(observe<msg::MotorFeedbackPubSubType>(pdds::topics::kMotorFeedback)),
        truth_reader_(observe<msg::PlantTruthPubSubType>(pdds::topics::kPlantTruth)),
        reference_reader_(observe<msg::VelocityReferencePubSubType>(pdds::topics::kVelocityReference)),
        command_reader_(observe<msg::ForceCommandPubSubType>(pdds::topics::kForceCommand)),
        estimate_reader_(observe<msg::EstimatedStatePubSubType>(pdds::topics::kEstimatedState)),
        trace_(ticks_),
        parts_(ticks_, 0) {}

 private:
  void activate() override { rt_.status.publish(node_state::STATE_RUNNING, 0, period_s_, "collecting"); }
  /// Takes what arrived: finished when every tick is complete (or the drive restarted); a new
  /// complete tick is work (no new one for the peer timeout: the peers are silent).
  Update update() override {
    if (drain()) return Update::finished(kExitOk);
    // Progress: ticks complete, or (--truth optional) complete but for PlantTruth.
    const std::uint64_t progress = complete_ + complete_but_truth_;
    if (progress == last_progress_) return Update::waiting();
    last_progress_ = progress;
    return Update::worked();
  }
  std::chrono::duration<double> input_timeout() const override {
    return std::chrono::duration<double>(common_.peer_timeout_s);
  }
  int inputs_lost() override { return kExitOk; }  // finish() says what was missing
  /// What the run ends with depends on what was collected, not on how the collection ended.
  int finish(int exit_code) override;
  pdds::Wakeup& wakeup() override { return rt_.wakeup; }

  template <typename PubSubType>
  pdds::Reader<PubSubType> observe(const pdds::Topic<PubSubType>& topic) {
    return rt_.participant.make_reader(topic, rt_.wakeup, pdds::kObserverProfile);
  }
  /// The record of `tick` with `part` now in, or null (and counted) outside the scenario or for a duplicate.
  TickRecord* mark(std::uint64_t tick, Part part);
  /// A sample of another run than the first one seen ends the collection.
  bool same_run(const msg::Stamp& stamp);
  /// Takes what arrived on every topic; true when every tick is complete or the drive restarted.
  bool drain();
  /// --truth optional: every other topic complete and no PlantTruth within the grace.
  bool without_truth();
  int report_incomplete();
  int report_results();

  node::CommonOptions common_;
  EvaluatorOptions opt_;
  node::NodeRuntime rt_;
  double period_s_;
  std::uint64_t ticks_;
  pdds::Reader<msg::MotorFeedbackPubSubType> feedback_reader_;
  pdds::Reader<msg::PlantTruthPubSubType> truth_reader_;
  pdds::Reader<msg::VelocityReferencePubSubType> reference_reader_;
  pdds::Reader<msg::ForceCommandPubSubType> command_reader_;
  pdds::Reader<msg::EstimatedStatePubSubType> estimate_reader_;

  std::vector<TickRecord> trace_;
  std::vector<unsigned> parts_;
  std::uint64_t complete_ = 0;
  std::uint64_t complete_but_truth_ = 0;  ///< ticks with every topic but PlantTruth in
  std::uint64_t last_progress_ = 0;
  bool any_truth_ = false;
  std::optional<std::chrono::steady_clock::time_point> truthless_since_;
  std::uint64_t rejected_ = 0;
  node::RunValidity validity_;  // the drive's status at every tick
  node::RunIdTracker run_;      // the drive's run every sample must belong to
  std::optional<node::RunChange> restart_;
  node::DriveTickStatus drive_status_;
  msg::MotorFeedback feedback_;
  msg::PlantTruth truth_;
  msg::VelocityReference reference_;
  msg::ForceCommand command_;
  msg::EstimatedState estimate_;
};

TickRecord* EvaluatorComponent::mark(std::uint64_t tick, Part part) {
  if (tick >= ticks_ || (parts_[tick] & part) != 0) {
    ++rejected_;  // outside the scenario or a duplicate
    return nullptr;
  }
  parts_[tick] |= part;
  if (parts_[tick] == kAll) ++complete_;
  // Once per tick: when the last of the four topics other than PlantTruth arrives.
  if (part != kTruth && (parts_[tick] & kAllButTruth) == kAllButTruth) ++complete_but_truth_;
  if (part == kTruth) any_truth_ = true;
  TickRecord& r = trace_[tick];
  r.tick = tick;
  r.time_s = static_cast<double>(tick) * period_s_;
  return &r;
}

bool EvaluatorComponent::same_run(const msg::Stamp& stamp) {
  if (!restart_) restart_ = run_.observe(stamp.run_id(), stamp.tick());
  return !restart_;
}

bool EvaluatorComponent::drain() {
  while (!restart_ && feedback_reader_.take(feedback_)) {
    if (!same_run(feedback_.stamp())) break;
    if (TickRecord* r = mark(feedback_.stamp().tick(), kFeedback)) {
      node::from_msg(feedback_, *r);
      node::from_msg(feedback_, drive_status_);
      validity_.add(feedback_.stamp().tick(), drive_status_);
    }
  }
  while (!restart_ && truth_reader_.take(truth_)) {
    if (!same_run(truth_.stamp())) break;
    if (TickRecord* r = mark(truth_.stamp().tick(), kTruth)) node::from_msg(truth_, *r);
  }
  while (!restart_ && reference_reader_.take(reference_)) {
    if (!same_run(reference_.stamp())) break;
    if (TickRecord* r = mark(reference_.stamp().tick(), kReference)) node::from_msg(reference_, *r);
  }
  while (!restart_ && command_reader_.take(command_)) {
    if (!same_run(command_.stamp())) break;
    if (TickRecord* r = mark(command_.feedback_tick(), kCommand)) node::from_msg(command_, *r);
  }
  while (!restart_ && estimate_reader_.take(estimate_)) {
    if (!same_run(estimate_.stamp())) break;
    if (TickRecord* r = mark(estimate_.feedback_tick(), kEstimate)) node::from_msg(estimate_, *r);
  }
  return complete_ == ticks_ || restart_.has_value() || without_truth();
}

bool EvaluatorComponent::without_truth() {
  if (!opt_.truth_optional || any_truth_ || complete_but_truth_ < ticks_) return false;
  const auto now = std::chrono::steady_clock::now();
  if (!truthless_since_) truthless_since_ = now;
  return now - *truthless_since_ >= kTruthGrace;
}

int EvaluatorComponent::report_incomplete() {
  std::fprintf(stderr, "evaluator: only %llu of %llu ticks complete (%s); no results\n",
               static_cast<unsigned long long>(complete_), static_cast<unsigned long long>(ticks_),
               pdds::stop_requested() ? "stopped" : "peers silent");
  // Which topics are missing, and from where: tells a late join from a loss.
  const char* names[] = {"MotorFeedback", "PlantTruth", "VelocityReference", "ForceCommand", "EstimatedState"};
  for (unsigned bit = 0; bit < 5; ++bit) {
    std::uint64_t missing = 0, first = ticks_;
    for (std::uint64_t t = 0; t < ticks_; ++t) {
      if ((parts_[t] & (1u << bit)) == 0) {
        ++missing;
        first = std::min(first, t);
      }
    }
    if (missing > 0) {
      std::fprintf(stderr, "evaluator: %s missing for %llu ticks, the first %llu\n", names[bit],
                   static_cast<unsigned long long>(missing), static_cast<unsigned long long>(first));
    }
  }
  if (!validity_.valid()) {
    std::fprintf(stderr, "evaluator: the ticks received are INVALID as well: %s\n", validity_.reason().c_str());
  }
  rt_.status.publish(node_state::STATE_ERROR, complete_, period_s_, "incomplete run");
  // Stopped or stalled before the run was complete: no results, and never exit 0 for that.
  return pdds::stop_requested() ? kExitError : kExitPeerLost;
}

int EvaluatorComponent::report_results() {
  const Scenario& scenario = rt_.cfg.scenario;
  const bool has_truth = any_truth_;
  if (!has_truth) {
    // Nothing true is known: nan, never a zero that reads as a value.
    for (TickRecord& r : trace_) clear_truth(r);
    std::printf(
        "evaluator: no PlantTruth on the domain (a real drive, or the virtual rig in realtime): the true "
        "load's columns are n/a; cost_est is the Kalman estimate's\n");
  }
  const ScenarioMetrics m = compute_metrics(trace_, scenario, period_s_);
  std::filesystem::create_directories(opt_.out_dir);
  const std::string run_name = opt_.label.empty() ? scenario.name : scenario.name + "_" + opt_.label;
  write_trace_csv(opt_.out_dir + "/" + run_name + ".csv", trace_);
  // Empty: valid. The drive's force off first; a load sensor that failed is a lost feedback.
  const std::string drive_reason = validity_.reason();
  const std::string sensor_reason = load_sensor_failure_reason(trace_);
  const std::string invalid_reason = drive_reason.empty()    ? sensor_reason
                                     : sensor_reason.empty() ? drive_reason
                                                             : drive_reason + "; " + sensor_reason;
  if (opt_.print_header) node::print_results_header();
  node::print_results_row(opt_.label.empty() ? scenario.name : scenario.name + " " + opt_.label, m, invalid_reason,
                          has_truth);
  std::fflush(stdout);
  rt_.status.status().rejected(rejected_);
  if (!drive_reason.empty()) {
    rt_.status.publish(node_state::STATE_ERROR, ticks_, period_s_, "invalid run: drive force off");
    return kExitSafeState;
  }
  if (!sensor_reason.empty()) {
    rt_.status.publish(node_state::STATE_ERROR, ticks_, period_s_, "invalid run: the load's sensor failed");
    return kExitVerdictFailed;
  }
  rt_.status.publish(node_state::STATE_STOPPING, ticks_, period_s_, "done");
  return kExitOk;
}

int EvaluatorComponent::finish(int /*exit_code*/) {
  if (restart_) {
    std::fprintf(stderr, "%s\n", node::restart_message("evaluator", *restart_).c_str());
    rt_.status.publish(node_state::STATE_ERROR, complete_, period_s_, "drive restarted mid-run");
    return kExitPeerLost;
  }
  return complete_ == ticks_ || (without_truth() && complete_but_truth_ == ticks_) ? report_results()
                                                                                   : report_incomplete();
}

}  // namespace

namespace pmlsm::node {

PMLSM_COMPONENT(evaluator, make_evaluator, 2);

MadeComponent make_evaluator(const ComponentContext& context, int argc, char** argv) {
  CommonOptions common;
  common.spin_us = 0.0;
  EvaluatorOptions opt;
  if (const auto code = parse_evaluator_command_line(argc, argv, common, opt)) return {nullptr, *code};
  return {std::make_unique<EvaluatorComponent>(context, std::move(common), opt)};
}

}  // namespace pmlsm::node

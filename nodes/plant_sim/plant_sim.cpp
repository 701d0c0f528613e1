// plant_sim: the simulated servo drive on DDS, a thin adapter over the drive loop
// (common/drive/drive_loop.hpp: arbitration, watchdog, power states, statistics) with the
// simulated drive as its backend. Publishes MotorFeedback (what the drive measures),
// PlantTruth (evaluation only) and DriveState; applies ForceCommand; obeys DriveControl.
//
// Clocks:
//  - lockstep: the plant is the clock. It publishes tick k and integrates to k+1 only when the
//    command answering tick k has arrived: deterministic, as fast as the machine goes.
//  - realtime: ticks on absolute time. The plant waits at most --command-deadline-us into the
//    tick for that tick's command, then holds the newest one; the watchdog faults the drive
//    when feedback stays unanswered for --watchdog-ms; a controller silent for
//    --controller-lost-ms is lost.
//
// Power: the drive starts in switch on disabled. With --auto-enable (the default; simulation
// launch files say so) it walks to operation enabled once its peers are there; otherwise an
// operator enables it (`pmlsm drive enable`). A latched fault is cleared by fault reset and
// enable (`pmlsm drive fault-reset`, `pmlsm drive enable`), never by a restart.
//
// Exit codes: 0 the scenario ran with force on throughout; 4 the controller was lost (lockstep
// timeout; realtime with --on-controller-lost exit); 5 the drive spent ticks with force off
// after it was first enabled (fault, quick stop, disabled) or was never enabled.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "CurrentFeedbackPubSubTypes.h"
#include "PlantTruthPubSubTypes.h"
#include "VoltageCommandPubSubTypes.h"
#include "drive_node.hpp"
#include "msg_mapping.hpp"
#include "node_support.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/simulated_drive.hpp"
#include "plant_sim_command_line.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;

/// plant_sim's own parts of the drive node: PlantTruth, and the current loop's exchange at the
/// voltage command level.
class PlantSimHooks final : public node::DriveNodeHooks {
 public:
  explicit PlantSimHooks(node::NodeRuntime& rt)
      : voltage_level_(rt.cfg.command_level == node::CommandLevel::kVoltage),
        truth_writer_(rt.participant.make_writer(pdds::topics::kPlantTruth)),
        current_writer_(rt.participant.make_writer(pdds::topics::kCurrentFeedback)),
        voltage_reader_(rt.participant.make_reader(pdds::topics::kVoltageCommand, rt.wakeup)),
        backend_(rt.cfg.params, scenario_initial_condition(rt.cfg.scenario)) {}

  SimulatedDriveBackend& backend() { return backend_; }
  void attach(node::DriveNode& node) { node_ = &node; }

  bool peers_ready() override {
    return !voltage_level_ || (current_writer_.matched_readers() >= 1 && voltage_reader_.matched_writers() >= 1);
  }
  void before_publish(std::uint64_t /*k*/, const drive::TickReport& report) override {
    const SimulatedDrive& simulated = backend_.simulated_drive();
    node::to_msg(simulated.plant().truth(), {report.applied_force_n, simulated.last_u_d_v(), simulated.last_u_q_v()},
                 truth_);
    truth_.stamp(node_->feedback().stamp());
  }
  void after_publish(std::uint64_t /*k*/) override { truth_writer_.write(truth_); }
  Progress exchange(std::uint64_t k) override { return voltage_level_ ? exchange_voltages(k) : Progress::kFinished; }
  const char* awaited() const override { return "VoltageCommand"; }
  bool apply_force() override { return !voltage_level_; }
  void flush(std::chrono::seconds timeout) override {
    truth_writer_.wait_for_acknowledgments(timeout);
    if (voltage_level_) current_writer_.wait_for_acknowledgments(timeout);
  }
  std::uint64_t extra_late() const override { return stale_voltages_; }
  std::uint64_t extra_rejected() const override { return rejected_voltages_; }

 private:
  /// The voltage level: 32 exchanges per tick, each the currents out and the controller's voltage
  /// for that substep back; kWaiting while a voltage is due.
  Progress exchange_voltages(std::uint64_t k) {
    SimulatedDrive& drive = backend_.simulated_drive();
    bool moved = false;
    while (substep_ < drive.current_steps_per_tick()) {
      if (!currents_sent_) {
        const PlantMeasurement& m = drive.measurement();
        current_feedback_.stamp(node_->feedback().stamp());
        current_feedback_.substep(static_cast<std::uint32_t>(substep_));
        current_feedback_.i_d_a(m.i_d_a);
        current_feedback_.i_q_a(m.i_q_a);
        current_feedback_.velocity_mps(drive.tick_velocity_mps());
        current_feedback_.position_m(m.encoder_position_m);
        current_writer_.write(current_feedback_);
        currents_sent_ = true;
        moved = true;
      }
      if (!take_voltage(k)) return moved ? Progress::kWorked : Progress::kWaiting;
      // Force off outside operation enabled: no voltage either.
      const bool enabled = backend_.power_state() == drive::PowerState::kOperationEnabled;
      drive.apply_voltage(enabled ? u_d_v_ : 0.0, enabled ? u_q_v_ : 0.0);
      ++substep_;
      currents_sent_ = false;
      moved = true;
    }
    substep_ = 0;
    return Progress::kFinished;
  }

  /// The voltage of tick k's substep in hand, when it came (a stale one counted, a non-finite one
  /// rejected: the last finite voltage is held).
  bool take_voltage(std::uint64_t k) {
    while (voltage_reader_.take(voltage_command_)) {
      if (voltage_command_.stamp().tick() != k || voltage_command_.substep() != static_cast<std::uint32_t>(substep_)) {
        ++stale_voltages_;
        continue;
      }
      if (std::isfinite(voltage_command_.u_d_v()) && std::isfinite(voltage_command_.u_q_v())) {
        u_d_v_ = voltage_command_.u_d_v();
        u_q_v_ = voltage_command_.u_q_v();
      } else {
        ++rejected_voltages_;
      }
      return true;
    }
    return false;
  }

  bool voltage_level_;
  pdds::Writer<msg::PlantTruthPubSubType> truth_writer_;
  pdds::Writer<msg::CurrentFeedbackPubSubType> current_writer_;
  pdds::Reader<msg::VoltageCommandPubSubType> voltage_reader_;
  SimulatedDriveBackend backend_;
  node::DriveNode* node_ = nullptr;
  msg::PlantTruth truth_;
  msg::CurrentFeedback current_feedback_;
  msg::VoltageCommand voltage_command_;
  double u_d_v_ = 0.0, u_q_v_ = 0.0;  // held voltage at the voltage command level
  int substep_ = 0;                   // the voltage level's exchange in hand within the tick
  bool currents_sent_ = false;        // its currents are out
  std::uint64_t stale_voltages_ = 0, rejected_voltages_ = 0;
};

class PlantSimComponent final : public node::DriveComponent {
 public:
  PlantSimComponent(const node::ComponentContext& context, node::CommonOptions common,
                    const node::DriveNodeOptions& opt)
      : common_(std::move(common)),
        rt_("plant_sim", common_, context),
        hooks_(checked(rt_, opt, common_)),
        node_("plant_sim", common_, opt, rt_, hooks_.backend(), hooks_) {
    hooks_.attach(node_);
    drive_with(node_);
  }

 private:
  static node::NodeRuntime& checked(node::NodeRuntime& rt, const node::DriveNodeOptions& opt,
                                    const node::CommonOptions& common) {
    node::check_drive_node_options("plant_sim", opt, common, rt);
    return rt;
  }

  node::CommonOptions common_;
  node::NodeRuntime rt_;
  PlantSimHooks hooks_;
  node::DriveNode node_;
};

}  // namespace

namespace pmlsm::node {

PMLSM_COMPONENT(plant_sim, make_plant_sim, 0);

MadeComponent make_plant_sim(const ComponentContext& context, int argc, char** argv) {
  CommonOptions common;
  common.spin_us = 200.0;
  DriveNodeOptions opt;
  if (const auto code = parse_plant_sim_command_line(argc, argv, common, opt)) return {nullptr, *code};
  return {std::make_unique<PlantSimComponent>(context, std::move(common), opt)};
}

}  // namespace pmlsm::node

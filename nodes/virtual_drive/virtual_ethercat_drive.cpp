// virtual_drive --bus ethercat: the simulated drive (plant + current loop, as plant_sim) behind the
// virtual EtherCAT CiA 402 drive of pmlsm/ethercat/coe_drive.hpp, answering EtherCAT over UDP
// (--ethercat-udp-port) or raw frames on an interface (--ethercat-interface). Its dictionary is the
// CANopen device's (configs/canopen: the same objects, the command tick for lockstep) with the
// scaling of configs/ethercat/drive.yaml, so master and drive agree. One period each process-data
// cycle its master completes in OP (synchronous to SM2); the process-data watchdog checked between
// frames. PlantTruth (--publish-truth, lockstep) per period since the slave entered OP.
// Lockstep: the run ends when the master takes the slave out of OP (drive_bridge releases it to
// INIT at its end; before the scenario's last tick: exit 4), or no frame came for --peer-timeout-s
// (exit 4). Realtime: until SIGINT.
// Exit 0 ok, 2 bad input, 1 socket, 4 the master gone, 5 the drive faulted.
#include "virtual_ethercat_drive.hpp"

#include <algorithm>
#include <array>
#include <cinttypes>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include "ethercat_options.hpp"
#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "truth_publisher.hpp"

namespace pmlsm::node {

namespace {

namespace ec = pmlsm::ethercat;
namespace pdds = pmlsm::dds;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;

class VirtualEthercatDriveComponent final : public CycleComponent {
 public:
  VirtualEthercatDriveComponent(const ComponentContext& context, VirtualDriveOptions options)
      : opt_(std::move(options)),
        config_(load_ethercat_config(opt_.ethercat)),
        canopen_(rig_with_scaling()),
        device_(load_device_dictionary(opt_.dictionary_path)),
        rt_("virtual_drive", opt_.common, context),
        realtime_(rt_.cfg.clock == Clock::kRealtime),
        ticks_(scenario_ticks(rt_.cfg.scenario, rt_.period_s)),
        truth_(make_truth()),
        link_(open_drive_link(opt_.ethercat)),
        simulated_(rt_.cfg.params, scenario_initial_condition(rt_.cfg.scenario)),
        drive_(application_params(), simulated_,
               build_device_dictionary(canopen_, device_, rt_.period_s, canopen::kSupportedModesCyclicSynchronous),
               [this](bool error, const std::string& line, std::int64_t now_ns) { log(error, line, now_ns); }),
        segment_({&drive_.esc()}, [] { return monotonic_ns(); }) {
    drive_.esc().dc().set_drift_ppm(opt_.dc_drift_ppm);
  }

  void activate() override;
  Update update() override;
  std::chrono::duration<double> input_timeout() const override { return kNoInputTimeout; }
  int inputs_lost() override { return kExitPeerMissing; }  // never: its own rules end it
  int finish(int exit_code) override;
  pdds::Wakeup& wakeup() override { return rt_.wakeup; }
  int input_fd() const override { return link_->fd(); }

 private:
  /// The CANopen device's rig with the EtherCAT file's scaling (the dictionary's 0x6076, encoder).
  CanopenRigConfig rig_with_scaling() const {
    CanopenRigConfig rig = load_canopen_config(opt_.can);
    rig.master.scaling = config_.scaling;
    return rig;
  }
  canopen::Cia402ApplicationParams application_params() const {
    canopen::Cia402ApplicationParams p;
    p.scaling = config_.scaling;
    p.inject_fault_at_period = opt_.inject_fault_at_tick;
    // Velocity and position modes: the drive's own loops tuned as the system's controller.
    p.own_loops = canopen::DriveOwnLoopsParams::like_controller(rt_.cfg.params.velocity_loop, rt_.period_s);
    return p;
  }
  std::optional<TruthPublisher> make_truth() {
    if (rt_.cfg.command_level == CommandLevel::kVoltage) {
      throw ConfigError(
          "--command-level voltage: the virtual drive runs its own current loop (cyclic synchronous torque)");
    }
    if (opt_.publish_truth && realtime_) {
      std::printf("virtual_drive: --publish-truth: PlantTruth is published in lockstep only; realtime: none\n");
      return std::nullopt;
    }
    std::optional<TruthPublisher> truth;
    if (opt_.publish_truth) truth.emplace(rt_, ticks_);
    return truth;
  }
  void log(bool error, const std::string& line, std::int64_t now_ns) const {
    std::fprintf(error ? stderr : stdout, "virtual_drive: %s, %.3f s after start [wall %.6f s]\n", line.c_str(),
                 static_cast<double>(now_ns - start_ns_) * 1e-9, static_cast<double>(wall_time_ns()) * 1e-9);
  }
  /// The periods stepped since the last look into PlantTruth, from the slave's first OP on.
  void record_truth();

  VirtualDriveOptions opt_;
  ec::Cia402DriveConfig config_;
  CanopenRigConfig canopen_;
  DeviceDictionary device_;  // its entries' names are the dictionary's
  NodeRuntime rt_;
  bool realtime_;
  std::uint64_t ticks_;
  std::optional<TruthPublisher> truth_;
  std::unique_ptr<ec::Link> link_;
  SimulatedDriveBackend simulated_;
  ec::VirtualEthercatDrive drive_;
  ec::VirtualSegment segment_;
  std::array<std::uint8_t, ec::kMaxEthernetFrameBytes> frame_{};
  std::int64_t start_ns_ = 0;
  std::int64_t last_frame_ns_ = 0;
  std::uint64_t frames_ = 0;
  bool was_in_op_ = false;
  std::uint64_t base_ = 0;      ///< the periods stepped when the slave first entered OP
  std::uint64_t recorded_ = 0;  ///< periods whose truth was added
  bool released_ = false;       ///< lockstep: the master took the slave out of OP
  std::int64_t truth_deadline_ns_ = 0;
};

void VirtualEthercatDriveComponent::activate() {
  start_ns_ = monotonic_ns();
  last_frame_ns_ = start_ns_;
  std::printf("virtual_drive: a virtual EtherCAT CiA 402 drive on %s, %s clock, %s%" PRIu64
              " ticks of %.3g ms (scenario), rated force %.6g N, %.6g increments/m, %u bytes out, %u in\n",
              describe_link(opt_.ethercat, false).c_str(), realtime_ ? "realtime" : "lockstep",
              realtime_ ? "until SIGINT/SIGTERM, " : "", ticks_, rt_.period_s * 1e3, config_.scaling.rated_force_n,
              config_.scaling.increments_per_metre, static_cast<unsigned>(drive_.slave().process().output_bytes()),
              static_cast<unsigned>(drive_.slave().process().input_bytes()));
  std::fflush(stdout);
  rt_.status.publish(node_state::STATE_RUNNING, 0, rt_.period_s, "on EtherCAT");
}

void VirtualEthercatDriveComponent::record_truth() {
  const bool in_op = drive_.esc().al_state() == ec::AlState::kOp;
  if (in_op && !was_in_op_ && recorded_ == 0) {
    base_ = drive_.periods();  // tick 0: the state the run starts from
    recorded_ = 1;
    if (truth_) truth_->add(0, simulated_.simulated_drive(), 0.0);
  }
  if (was_in_op_ && !in_op && !realtime_) released_ = true;
  was_in_op_ = in_op;
  if (recorded_ == 0) return;
  while (base_ + recorded_ <= drive_.periods() && recorded_ < ticks_) {
    if (truth_) truth_->add(recorded_, simulated_.simulated_drive(), drive_.applied_force_n());
    ++recorded_;
  }
}

// Frames that queued are answered (bounded, so a flood cannot hold the update), each followed by
// the drive's application; the watchdog checked; PlantTruth sent as it can be.
CycleComponent::Update VirtualEthercatDriveComponent::update() {
  constexpr int kMaxFramesPerUpdate = 64;
  constexpr std::int64_t kPollNs = 2'000'000;
  std::int64_t now = monotonic_ns();
  if (released_) {
    if (truth_) truth_->flush();
    if (truth_ && truth_->held() > 0 && now < truth_deadline_ns_) {
      return Update::waiting_until(std::min(truth_deadline_ns_, now + kPollNs));
    }
    if (recorded_ >= ticks_) return Update::finished(kExitOk);
    // The master ended the run before its last tick (stopped, or its own fault): no whole run.
    std::fprintf(stderr,
                 "virtual_drive: the master took the drive out of OP after %" PRIu64 " of %" PRIu64 " ticks: exit %d\n",
                 recorded_, ticks_, kExitPeerLost);
    return Update::finished(kExitPeerLost);
  }
  int frames = 0;
  while (frames < kMaxFramesPerUpdate) {
    const std::size_t size = link_->receive(frame_.data(), 0);
    if (size == 0) break;
    ++frames;
    // At the time it came, when the link knows it: a SYNC0 pulse between its coming and now
    // comes after it, as on the wire.
    const std::int64_t arrived = link_->last_arrival_ns();
    const ec::FrameError error =
        arrived >= 0 ? segment_.pass(frame_.data(), size, arrived) : segment_.pass(frame_.data(), size);
    if (error != ec::FrameError::kNone) continue;  // dropped, as a slave drops it
    link_->send({frame_.data(), size});
    ++frames_;
    now = monotonic_ns();
    last_frame_ns_ = now;
    drive_.after_frame(now);
    record_truth();
  }
  now = monotonic_ns();
  // The drive's clock runs on between frames: its SYNC0 pulses (DC mode) come when due, frames or not.
  drive_.esc().set_time(now);
  record_truth();
  drive_.check_watchdog(now);
  if (truth_) truth_->flush();
  if (released_) {
    truth_deadline_ns_ = now + std::llround(opt_.common.peer_timeout_s * 1e9);
    return Update::worked();
  }
  if (!realtime_ && frames_ > 0 && now - last_frame_ns_ > std::llround(opt_.common.peer_timeout_s * 1e9)) {
    std::fprintf(stderr, "virtual_drive: no frame from the master for %.1f s (--peer-timeout-s): exit %d\n",
                 opt_.common.peer_timeout_s, kExitPeerLost);
    return Update::finished(kExitPeerLost);
  }
  if (frames > 0) return Update::worked();
  const std::int64_t to_sync0 = drive_.esc().ns_to_next_sync0();
  return Update::waiting_until(now + (to_sync0 >= 0 ? std::min(to_sync0, kPollNs) : kPollNs));
}

int VirtualEthercatDriveComponent::finish(int exit_code) {
  std::printf("virtual_drive: summary: %" PRIu64 " frames answered, AL state %s, periods stepped %" PRIu64 " (%" PRIu64
              " in the run), %" PRIu64 " cycles outside OP, %" PRIu64 " repeated cycles not stepped, faults %" PRIu64
              " (last error 0x%04X), power state %s%s\n",
              frames_, ec::to_string(drive_.esc().al_state()), drive_.periods(), recorded_ > 0 ? recorded_ - 1 : 0,
              drive_.cycles_outside_op(), drive_.unstepped_cycles(), simulated_.fault_count(),
              static_cast<unsigned>(simulated_.error_code()), drive::to_string(simulated_.power_state()),
              pdds::stop_requested() ? ", stopped by signal" : "");
  const ec::DcClock& dc = drive_.esc().dc();
  std::printf("virtual_drive: distributed clock: %.6g ppm crystal, %" PRIu64
              " times of the master followed, correction %.3g ppm, difference 0x092C %lld ns\n",
              opt_.dc_drift_ppm, dc.writes(), dc.correction_ppm(), static_cast<long long>(dc.difference_ns()));
  const ec::Sync0State& sync0 = drive_.esc().sync0();
  if (sync0.pulses > 0 || sync0.late_starts > 0) {
    std::printf("virtual_drive: SYNC0: %" PRIu64 " pulses of %.3f ms, %" PRIu64
                " in OP without new outputs (0x1C32:0B), %" PRIu64 " activations with the start time past, %" PRIu64
                " dropped by a jump of the clock\n",
                sync0.pulses, static_cast<double>(sync0.cycle_ns) * 1e-6, drive_.sync0_without_outputs(),
                sync0.late_starts, sync0.dropped);
  }
  if (truth_) {
    truth_->finish();
    std::printf("virtual_drive: PlantTruth: %llu ticks published, %llu not published\n",
                static_cast<unsigned long long>(truth_->published()),
                static_cast<unsigned long long>(truth_->dropped()));
  }
  if (simulated_.fault_count() > 0) {
    std::fprintf(stderr, "virtual_drive: the drive faulted %" PRIu64 " time(s) during the run: exit 5\n",
                 simulated_.fault_count());
    rt_.status.publish(node_state::STATE_SAFE, drive_.periods(), rt_.period_s, "the drive faulted during the run");
    return kExitSafeState;
  }
  rt_.status.publish(node_state::STATE_STOPPING, drive_.periods(), rt_.period_s, "done");
  return exit_code;
}

}  // namespace

MadeComponent make_virtual_ethercat_drive(const ComponentContext& context, VirtualDriveOptions options) {
  return {std::make_unique<VirtualEthercatDriveComponent>(context, std::move(options))};
}

}  // namespace pmlsm::node

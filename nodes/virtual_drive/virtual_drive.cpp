// virtual_drive: the rig in a box. The simulated drive (plant + current loop, as plant_sim)
// behind the CiA 402 slave of pmlsm/canopen/cia402_slave.hpp on a CAN bus (--bus ethercat: behind
// a virtual EtherCAT slave, virtual_ethercat_drive.cpp) (UDP multicast in
// python-can's format, or SocketCAN). Control is CAN only; on DDS: NodeStatus, and PlantTruth
// for the evaluator with --publish-truth in lockstep (truth_publisher.hpp). Dictionary:
// configs/canopen/drive.yaml (shared with drive_bridge) and --dictionary (the device's part).
// Lockstep: the SYNC is the clock, the run ends after the scenario's ticks; realtime: its own
// clock with the latest torque, until SIGINT. Exit 0 ok, 2 bad input, 1 socket, 5 it faulted.
#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include "can_options.hpp"
#include "cycle_component.hpp"
#include "pmlsm/canopen/cia402_slave.hpp"
#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/util/data_files.hpp"
#include "truth_publisher.hpp"
#include "virtual_drive_command_line.hpp"
#include "virtual_ethercat_drive.hpp"

namespace {

using namespace pmlsm;
namespace co = pmlsm::canopen;
namespace pdds = pmlsm::dds;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;

using Options = node::VirtualDriveOptions;

class VirtualDriveComponent final : public node::CycleComponent, co::Cia402SlaveEvents {
 public:
  VirtualDriveComponent(const node::ComponentContext& context, Options options)
      : opt_(std::move(options)),
        canopen_(node::load_canopen_config(opt_.can)),
        device_(load_device_dictionary(opt_.dictionary_path)),
        rt_("virtual_drive", opt_.common, context),
        realtime_(rt_.cfg.clock == node::Clock::kRealtime),
        ticks_(scenario_ticks(rt_.cfg.scenario, rt_.period_s)),
        period_ns_(std::llround(rt_.period_s * 1e9)),
        truth_(make_truth()),
        bus_(node::open_can_bus(opt_.can)),
        drive_(rt_.cfg.params, scenario_initial_condition(rt_.cfg.scenario)),
        slave_(
            slave_params(), [this] { return build_device_dictionary(canopen_, device_, rt_.period_s); }, drive_, *bus_,
            *this) {}

  void activate() override;
  Update update() override;
  std::chrono::duration<double> input_timeout() const override { return node::kNoInputTimeout; }
  int inputs_lost() override { return kExitPeerMissing; }  // never: its slave's SYNC timeout ends it
  int finish(int exit_code) override;
  pdds::Wakeup& wakeup() override { return rt_.wakeup; }
  int input_fd() const override { return bus_->fd(); }

 private:
  co::Cia402SlaveParams slave_params() const {
    co::Cia402SlaveParams p;
    p.node = co::NodeId(canopen_.master.node_id);
    p.scaling = canopen_.master.scaling;
    p.lockstep = !realtime_;
    p.ticks = ticks_;
    p.sync_timeout_ms = canopen_.drive_sync_timeout_ms;
    p.inject_fault_at_period = opt_.inject_fault_at_tick;
    return p;
  }
  /// PlantTruth's publisher, after the checks against the runtime. @throws ConfigError
  std::optional<node::TruthPublisher> make_truth() {
    if (rt_.cfg.command_level == node::CommandLevel::kVoltage) {
      throw ConfigError(
          "--command-level voltage: the virtual drive runs its own current loop (cyclic synchronous torque)");
    }
    if (opt_.publish_truth && realtime_) {
      std::printf("virtual_drive: --publish-truth: PlantTruth is published in lockstep only; realtime: none\n");
      return std::nullopt;
    }
    std::optional<node::TruthPublisher> truth;
    if (opt_.publish_truth) truth.emplace(rt_, ticks_);
    return truth;
  }
  void run_tick(std::uint64_t tick, double applied_force_n) override {
    if (truth_) truth_->add(tick, drive_.simulated_drive(), applied_force_n);
  }
  void log(bool error, const std::string& line, std::int64_t now_ns) override {
    std::fprintf(error ? stderr : stdout, "virtual_drive: %s, %.3f s after start [wall %.6f s]\n", line.c_str(),
                 static_cast<double>(now_ns - start_ns_) * 1e-9, static_cast<double>(wall_time_ns()) * 1e-9);
  }
  /// Realtime: tick k is due at start + k T; a late update catches up, a very late one (over 100
  /// periods) skips ahead and counts it.
  void keep_realtime(std::int64_t now);

  Options opt_;
  CanopenRigConfig canopen_;
  DeviceDictionary device_;  // its entries' names are the dictionary's
  node::NodeRuntime rt_;
  bool realtime_;
  std::uint64_t ticks_;
  std::int64_t period_ns_;
  std::optional<node::TruthPublisher> truth_;
  std::unique_ptr<can::CanBus> bus_;
  SimulatedDriveBackend drive_;
  co::Cia402Slave slave_;
  std::int64_t start_ns_ = 0;
  std::int64_t next_tick_ns_ = 0;
  /// Once the slave finished: until when PlantTruth still held may wait for its reader.
  std::int64_t truth_deadline_ns_ = 0;
  std::uint64_t deadline_misses_ = 0;
};

void VirtualDriveComponent::activate() {
  start_ns_ = monotonic_ns();
  std::printf("virtual_drive: node %u on %s, %s clock, %s%" PRIu64
              " ticks of %.3g ms (scenario), rated force %.6g N, "
              "%.6g increments/m\n",
              static_cast<unsigned>(canopen_.master.node_id), bus_->describe().c_str(),
              realtime_ ? "realtime" : "lockstep", realtime_ ? "until SIGINT/SIGTERM, " : "", ticks_,
              rt_.period_s * 1e3, canopen_.master.scaling.rated_force_n, canopen_.master.scaling.increments_per_metre);
  rt_.status.publish(node_state::STATE_RUNNING, 0, rt_.period_s, "on the CAN bus");
  slave_.start(start_ns_);
  next_tick_ns_ = start_ns_ + period_ns_;
}

// Frames that queued are taken (bounded, so a flooded bus cannot hold the update), the periods that
// came due stepped, the slave's timers polled. Lockstep waits for the next frame (the SYNC is the
// clock) at most 2 ms, for heartbeats and PlantTruth's reader; realtime until the next tick.
node::CycleComponent::Update VirtualDriveComponent::update() {
  constexpr int kMaxFramesPerUpdate = 64;
  constexpr std::int64_t kLockstepPollNs = 2'000'000;
  std::int64_t now = monotonic_ns();
  if (slave_.finished()) {
    // The run is over: what PlantTruth still holds waits for the bridge's run id and the evaluator.
    if (truth_) truth_->flush();
    if (!truth_ || truth_->held() == 0 || now >= truth_deadline_ns_) return Update::finished(kExitOk);
    return Update::waiting_until(std::min(truth_deadline_ns_, now + kLockstepPollNs));
  }
  co::CanFrame frame{};
  int frames = 0;
  while (frames < kMaxFramesPerUpdate && !slave_.finished() && bus_->receive(frame, std::chrono::nanoseconds(0))) {
    slave_.on_frame(frame, monotonic_ns());
    ++frames;
  }
  now = monotonic_ns();
  if (realtime_ && now >= next_tick_ns_) keep_realtime(now);
  slave_.poll(now);
  if (truth_) truth_->flush();
  if (slave_.finished()) {
    truth_deadline_ns_ = now + std::llround(opt_.common.peer_timeout_s * 1e9);
    return Update::worked();
  }
  if (frames > 0) return Update::worked();
  return Update::waiting_until(realtime_ ? next_tick_ns_ : now + kLockstepPollNs);
}

void VirtualDriveComponent::keep_realtime(std::int64_t now) {
  int steps = 0;
  while (now >= next_tick_ns_ && steps < 100) {
    slave_.step_period(now);
    slave_.check_timeouts(now);
    next_tick_ns_ += period_ns_;
    ++steps;
  }
  if (steps > 1) deadline_misses_ += static_cast<std::uint64_t>(steps - 1);
  if (now >= next_tick_ns_) {
    const std::int64_t behind = (now - next_tick_ns_) / period_ns_ + 1;
    deadline_misses_ += static_cast<std::uint64_t>(behind);
    next_tick_ns_ += behind * period_ns_;
  }
}

int VirtualDriveComponent::finish(int /*exit_code*/) {
  std::printf("virtual_drive: summary: periods stepped %" PRIu64 " of %" PRIu64 ", %s, bus-level malformed %" PRIu64
              ", faults %" PRIu64 " (last error 0x%04X), deadline misses %" PRIu64 ", power state %s, NMT %s%s\n",
              slave_.run_periods(), realtime_ ? ticks_ : ticks_ - 1, co::describe(slave_.counters()).c_str(),
              bus_->counters().malformed_dropped, drive_.fault_count(), static_cast<unsigned>(drive_.error_code()),
              deadline_misses_, drive::to_string(drive_.power_state()), co::to_string(slave_.nmt_state()),
              pdds::stop_requested() ? ", stopped by signal" : "");
  const co::IntervalStatistics& sync = slave_.sync_intervals();
  if (sync.count() > 0) {
    std::printf(
        "virtual_drive: SYNC intervals at the drive over %llu SYNCs: mean %.1f us, std %.1f us, p99 %.0f us, "
        "max %.1f us\n",
        static_cast<unsigned long long>(sync.count()), sync.mean_us(), sync.std_us(), sync.p99_us(), sync.max_us());
  }
  if (truth_) {
    truth_->finish();
    std::printf("virtual_drive: PlantTruth: %llu ticks published, %llu repeated answers not published\n",
                static_cast<unsigned long long>(truth_->published()),
                static_cast<unsigned long long>(truth_->dropped()));
  }
  if (drive_.fault_count() > 0) {
    std::fprintf(stderr, "virtual_drive: the drive faulted %" PRIu64 " time(s) during the run: exit 5\n",
                 drive_.fault_count());
    rt_.status.publish(node_state::STATE_SAFE, slave_.periods(), rt_.period_s, "the drive faulted during the run");
    return kExitSafeState;
  }
  rt_.status.publish(node_state::STATE_STOPPING, slave_.periods(), rt_.period_s, "done");
  return kExitOk;
}

}  // namespace

namespace pmlsm::node {

PMLSM_COMPONENT(virtual_drive, make_virtual_drive, kRunsAlone);

MadeComponent make_virtual_drive(const ComponentContext& context, int argc, char** argv) {
  Options opt;
  if (const auto code = parse_virtual_drive_command_line(argc, argv, opt)) return {nullptr, *code};
  if (opt.ethercat.bus == DriveBus::kEthercat) return make_virtual_ethercat_drive(context, std::move(opt));
  return {std::make_unique<VirtualDriveComponent>(context, std::move(opt))};
}

}  // namespace pmlsm::node

// drive_bridge: a real (or virtual) CiA 402 servo drive on CAN or EtherCAT, on DDS. The same drive node as
// plant_sim (nodes/support/drive_node.hpp: the drive loop, MotorFeedback and DriveState,
// ForceCommand, DriveControl, watchdog, summary, exit codes) with the CANopen master
// (pmlsm::canopen::Cia402Drive) as its backend instead of the simulation. MotorFeedback's
// STATUS_SIMULATED bit is off; there is no PlantTruth and no voltage command level.
//
// Bus: UDP multicast (python-can's udp_multicast: --can-group, --can-port, --can-iface) by
// default, SocketCAN with --can-interface NAME. The drive (node id, rated force, encoder,
// heartbeats, time-outs): configs/canopen/drive.yaml (--canopen-config, --canopen-set), the
// file the virtual drive reads too. Cyclic synchronous torque at 1 ms.
//
// Before tick 0 (once the DDS peers are there) the drive is booted (boot-up or heartbeat, SDO
// set-up, NMT start) and, with --auto-enable, walked to operation enabled without stepping it.
// Lockstep: each tick is one SYNC exchange in which the drive steps one period with the
// previous tick's command; realtime: a SYNC each tick, the TPDOs taken within
// master.realtime.tpdo_deadline_us. A drive that stops answering (after
// master.lockstep.sync_retries resends) or whose
// heartbeat is lost is a fault 0x8130: force off, the run ends not valid (exit 5).
//
// EtherCAT (--bus ethercat): our master (pmlsm::ethercat::Cia402Drive) over UDP (--ethercat-udp) or
// an interface (--ethercat-interface; --ethercat-capture FILE: every frame into a pcapng capture),
// the drive and the master's time-outs from
// configs/ethercat/drive.yaml (--ethercat-config, --ethercat-set). The boot takes the drive to OP;
// a cycle is its outputs written and its inputs read; lockstep needs the virtual drive's command
// tick, a real drive runs realtime. At the end the drive is disabled (realtime) and its slave
// walked to INIT.
//
// Exit codes as plant_sim's; a drive that cannot be booted or enabled: 1, with the reason.
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include "can_options.hpp"
#include "drive_bridge_command_line.hpp"
#include "drive_node.hpp"
#include "pmlsm/canopen/bus_load.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/cia402_drive.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/ethercat/cia402_drive.hpp"

namespace {

using namespace pmlsm;

/// The CiA 402 object a drive reports a load sensor of this kind in (not none).
const char* load_sensor_object(LoadSensorKind kind) { return kind == LoadSensorKind::kEncoder ? "0x60E4:1" : "0x2003"; }

/// A drive's problems reported once each, whatever its bus: lost, a new error code, a walk stuck
/// in one state.
class ProblemReports {
 public:
  template <typename Drive>
  void after_tick(node::DriveNode& node, std::uint64_t k, const Drive& drive) {
    if (drive.lost() && !lost_reported_) {
      lost_reported_ = true;
      std::fprintf(stderr, "%s: tick %llu: drive lost: %s: fault 0x%04x, zero force\n", node.name().c_str(),
                   static_cast<unsigned long long>(k), drive.last_problem(), drive.error_code());
      node.set_fault_reason(std::string("drive lost: ") + drive.last_problem());
    }
    if (drive.error_code() != reported_error_) {
      reported_error_ = drive.error_code();
      std::fprintf(stderr, "%s: tick %llu: drive error code 0x%04x (%s), drive %s\n", node.name().c_str(),
                   static_cast<unsigned long long>(k), reported_error_, drive.last_problem(),
                   drive::to_string(drive.power_state()));
      if (!drive.lost()) node.set_fault_reason(drive.last_problem());
    }
    if (drive.stuck_in() && !stuck_reported_) {
      stuck_reported_ = true;
      std::fprintf(stderr, "%s: tick %llu: the drive does not follow the controlword: stuck in %s\n",
                   node.name().c_str(), static_cast<unsigned long long>(k), drive::to_string(*drive.stuck_in()));
    } else if (!drive.stuck_in()) {
      stuck_reported_ = false;
    }
  }

 private:
  bool lost_reported_ = false;
  bool stuck_reported_ = false;
  std::uint16_t reported_error_ = 0;
};

/// drive_bridge's own parts of the drive node: the CANopen boot, the enable walk, and the
/// drive's problems reported once each.
class BridgeHooks final : public node::DriveNodeHooks {
 public:
  BridgeHooks(canopen::Cia402Drive& drive, const can::CanBus& bus) : drive_(drive), bus_(bus) {}

  void before_run(node::DriveNode& node) override {
    drive_.boot();
    drive_.start();
    std::printf(
        "%s: drive node %d booted on %s: cyclic synchronous torque, rated force %.1f N, %g increments/m, "
        "periods stepped %u, %s\n",
        node.name().c_str(), drive_.config().node_id, bus_.describe().c_str(), drive_.config().scaling.rated_force_n,
        drive_.config().scaling.increments_per_metre, drive_.periods_stepped(), drive::to_string(drive_.power_state()));
    if (drive_.config().load_sensor != LoadSensorKind::kNone) {
      std::printf("%s: a sensor on the load in the drive's TPDO3: %s (%s)\n", node.name().c_str(),
                  to_string(drive_.config().load_sensor), load_sensor_object(drive_.config().load_sensor));
    }
  }
  void enable_at_start(node::DriveNode& node) override {
    drive_.enable_and_wait();
    std::printf("%s: drive %s (auto-enable)\n", node.name().c_str(), drive::to_string(drive_.power_state()));
  }
  void after_tick(node::DriveNode& node, std::uint64_t k) override {
    reports_.after_tick(node, k, drive_);
    const canopen::Cia402DriveCounters& c = drive_.counters();
    if (c.foreign_syncs > 0 && !foreign_sync_reported_) {
      foreign_sync_reported_ = true;
      std::fprintf(stderr, "%s: tick %llu: a second SYNC producer on the bus (CiA 301 allows one); counted, ignored\n",
                   node.name().c_str(), static_cast<unsigned long long>(k));
      node.report("a second SYNC producer on the CAN bus");
    }
    if (c.foreign_nmt > 0 && !foreign_nmt_reported_) {
      foreign_nmt_reported_ = true;
      std::fprintf(stderr, "%s: tick %llu: an NMT command from another master on the bus; counted\n",
                   node.name().c_str(), static_cast<unsigned long long>(k));
      node.report("an NMT command from another master on the CAN bus");
    }
    if (c.foreign_rpdos > 0 && !foreign_rpdo_reported_) {
      foreign_rpdo_reported_ = true;
      std::fprintf(stderr,
                   "%s: tick %llu: another master's RPDO to the drive on the bus (COB-ID of this bridge's "
                   "drive, not sent by it); counted\n",
                   node.name().c_str(), static_cast<unsigned long long>(k));
      node.report("an RPDO from another master on the CAN bus");
    }
  }
  void at_end(node::DriveNode& node) override {
    // Realtime, the drive runs on its own clock and faults when SYNC stops while it is enabled:
    // disable it first (controlword shutdown, zero torque), so a run that ended well ends with
    // the drive ready to switch on, not faulted. Lockstep: the drive counts its periods and ends.
    if (!node.realtime() || drive_.power_state() != drive::PowerState::kOperationEnabled) return;
    const drive::TransitionResult r = drive_.request(drive::DriveCommand::kShutdown);
    if (!r.accepted) return;
    drive_.apply(0.0);
    std::printf("%s: run ended: drive disabled (shutdown) before the last SYNC\n", node.name().c_str());
  }
  void flush(std::chrono::seconds /*timeout*/) override {
    const canopen::Cia402DriveCounters& c = drive_.counters();
    std::printf(
        "drive_bridge: CAN: %llu SYNCs (%llu resent), %llu RPDO1 resent, %llu ticks without TPDOs in time, "
        "%llu EMCYs, %llu malformed frames of the drive, %llu SYNCs, %llu NMT commands and %llu RPDOs from "
        "another master\n",
        static_cast<unsigned long long>(c.syncs), static_cast<unsigned long long>(c.sync_resends),
        static_cast<unsigned long long>(c.rpdo_resends), static_cast<unsigned long long>(c.tpdo_missing),
        static_cast<unsigned long long>(c.emcys), static_cast<unsigned long long>(c.malformed),
        static_cast<unsigned long long>(c.foreign_syncs), static_cast<unsigned long long>(c.foreign_nmt),
        static_cast<unsigned long long>(c.foreign_rpdos));
  }

 private:
  canopen::Cia402Drive& drive_;
  const can::CanBus& bus_;
  ProblemReports reports_;
  bool foreign_sync_reported_ = false;
  bool foreign_nmt_reported_ = false;
  bool foreign_rpdo_reported_ = false;
};

using BridgeOptions = node::DriveBridgeOptions;

class DriveBridgeComponent final : public node::DriveComponent {
 public:
  DriveBridgeComponent(const node::ComponentContext& context, BridgeOptions options)
      : opt_(std::move(options)),
        rig_(node::load_canopen_config(opt_.can)),
        rt_("drive_bridge", opt_.common, context),
        drive_config_(checked_config()),
        bus_(node::open_can_bus(opt_.can)),
        drive_(drive_config_, *bus_, [] { return monotonic_ns(); }),
        hooks_(drive_, *bus_),
        node_("drive_bridge", opt_.common, opt_.drive, rt_, drive_, hooks_) {
    drive_with(node_);
  }

 private:
  /// The master's configuration after the checks against the runtime. @throws ConfigError
  canopen::Cia402DriveConfig checked_config();

  BridgeOptions opt_;
  CanopenRigConfig rig_;
  node::NodeRuntime rt_;
  canopen::Cia402DriveConfig drive_config_;
  std::unique_ptr<can::CanBus> bus_;
  canopen::Cia402Drive drive_;
  BridgeHooks hooks_;
  node::DriveNode node_;
};

/// What either bus asks of the runtime: force commands, a 1 ms period. Returns whether the run is
/// realtime. @throws ConfigError
bool check_bridge_runtime(const BridgeOptions& opt, const node::NodeRuntime& rt) {
  node::check_drive_node_options("drive_bridge", opt.drive, opt.common, rt);
  if (rt.cfg.command_level == node::CommandLevel::kVoltage) {
    throw ConfigError(
        "--command-level voltage: a CiA 402 drive runs its own current loop (cyclic synchronous "
        "torque); drive_bridge takes force commands only");
  }
  if (std::abs(rt.period_s - 1e-3) > 1e-9) {
    throw ConfigError("control period " + std::to_string(rt.period_s * 1e3) +
                      " ms: the drive is set to a 1 ms interpolation period (0x60C2)");
  }
  return rt.cfg.clock == node::Clock::kRealtime;
}

canopen::Cia402DriveConfig DriveBridgeComponent::checked_config() {
  canopen::Cia402DriveConfig drive_config = rig_.master;
  // The filter expects the load's readings the system file declares: a master that does not
  // read them would have every run end with the sensor failed.
  const LoadSensorKind declared = rt_.cfg.params.load_sensor.kind;
  if (declared != LoadSensorKind::kNone && declared != drive_config.load_sensor) {
    throw ConfigError(
        std::string("sensors.load.kind ") + to_string(declared) + " (the system file) but drive.load_sensor " +
        to_string(drive_config.load_sensor) + " (" + opt_.can.canopen_path +
        "): the master would not read the sensor; set --canopen-set drive.load_sensor=" + to_string(declared));
  }
  drive_config.reset_communication = !opt_.no_reset;
  drive_config.realtime = check_bridge_runtime(opt_, rt_);
  const canopen::BusLoad load = canopen::bus_load(
      canopen::bridge_cycle_frames(rt_.period_s, drive_config.drive_heartbeat_ms, drive_config.master_heartbeat_ms,
                                   drive_config.load_sensor != LoadSensorKind::kNone),
      rig_.bitrate_bps, rt_.period_s);
  std::printf(
      "drive_bridge: bus load per %.0f ms cycle at %.0f kbit/s: %.1f %% (%.0f bits; %.1f %% with worst-case bit "
      "stuffing)\n",
      rt_.period_s * 1e3, rig_.bitrate_bps * 1e-3, 100.0 * load.load, load.bits_per_cycle, 100.0 * load.load_worst);
  if (load.load_worst > 1.0) {
    throw ConfigError("bus.bitrate_bps " + std::to_string(rig_.bitrate_bps) + ": one cycle's frames need up to " +
                      std::to_string(static_cast<int>(load.bits_per_cycle_worst)) +
                      " bits, more than the bus carries in " + std::to_string(rt_.period_s * 1e3) + " ms");
  }
  if (load.load_worst > 0.5) {
    std::fprintf(stderr,
                 "drive_bridge: warning: the bus is more than half busy at worst; frames of other nodes "
                 "may delay the PDOs\n");
  }
  return drive_config;
}

/// drive_bridge's own parts with the EtherCAT master: the boot to OP, the enable walk, the drive's
/// problems reported once each, the slave released at the end.
class EthercatHooks final : public node::DriveNodeHooks {
 public:
  /// `capture` (nullptr: none) holds the run's frames, written to `capture_path`.
  /// `declared`: the system file's sensors.load.kind, which the drive's inputs must carry.
  EthercatHooks(ethercat::Cia402Drive& drive, std::string link, ethercat::PcapngWriter* capture,
                std::string capture_path, LoadSensorKind declared)
      : drive_(drive),
        link_(std::move(link)),
        capture_(capture),
        capture_path_(std::move(capture_path)),
        declared_load_sensor_(declared) {
    drive_.master().capture_to(capture_);
  }

  void before_run(node::DriveNode& node) override {
    boot_began_ns_ = monotonic_ns();
    drive_.boot();
    refuse_a_load_sensor_the_inputs_lack();
    drive_.start();
    const ethercat::SlaveInfo& s = drive_.slave();
    std::printf(
        "%s: EtherCAT drive at position %u (%s, vendor 0x%08X product 0x%08X) in OP on %s %.0f ms after the boot "
        "began: %s, %u bytes out, %u in%s, rated force %.1f N, %g increments/m, %s\n",
        node.name().c_str(), static_cast<unsigned>(drive_.config().position), s.name.c_str(), s.vendor_id,
        s.product_code, link_.c_str(), since_boot_ms(), canopen::describe_mode(drive_.config().mode),
        static_cast<unsigned>(drive_.layout().output_bytes), static_cast<unsigned>(drive_.layout().input_bytes),
        drive_.lockstep_contract() ? " (command tick mapped)" : "", drive_.config().scaling.rated_force_n,
        drive_.config().scaling.increments_per_metre, drive::to_string(drive_.power_state()));
    if (drive_.config().mode != canopen::kModeCyclicSynchronousTorque) {
      const bool offset = drive_.layout().output_offset(canopen::kObjectTorqueOffset) >= 0;
      std::printf(
          "%s: the drive closes its own %s loop on V_ref%s; %s\n", node.name().c_str(),
          drive_.config().mode == canopen::kModeCyclicSynchronousVelocity ? "velocity" : "position and velocity",
          drive_.config().mode == canopen::kModeCyclicSynchronousPosition ? "'s motion" : "",
          offset ? "the compensation goes in as its torque offset 0x60B2"
                 : "0x60B2 (torque offset) is not mapped: the compensation does not reach it");
    }
    if (const LoadSensorKind load = drive_.load_sensor(); load != LoadSensorKind::kNone) {
      std::printf("%s: a sensor on the load in the drive's inputs: %s (%s)\n", node.name().c_str(), to_string(load),
                  load_sensor_object(load));
    }
    if (drive_.sync0_start_ns() != 0) {
      std::printf("%s: the drive on SYNC0 (DC mode): every 1 ms, %u us into the cycle of the master's clock\n",
                  node.name().c_str(), static_cast<unsigned>(drive_.config().sync0_shift_us));
    }
  }
  void enable_at_start(node::DriveNode& node) override {
    drive_.enable_and_wait();
    std::printf("%s: drive %s (auto-enable) %.0f ms after the boot began\n", node.name().c_str(),
                drive::to_string(drive_.power_state()), since_boot_ms());
  }
  void after_tick(node::DriveNode& node, std::uint64_t k) override {
    reports_.after_tick(node, k, drive_);
    if (drive_.emergencies() != emergencies_reported_) {
      // A warning the drive posts (or a fault's, read with it): said as it comes.
      emergencies_reported_ = drive_.emergencies();
      std::fprintf(stderr, "%s: tick %llu: CoE emergency from the drive: 0x%04X (%s)\n", node.name().c_str(),
                   static_cast<unsigned long long>(k), drive_.last_emergency_code(),
                   canopen::describe_emcy(drive_.last_emergency_code()));
    }
  }
  void at_end(node::DriveNode& node) override {
    // A drive that is enabled when its slave leaves OP faults: disable it first (shutdown, zero
    // torque, one cycle), then the slave to SAFEOP and INIT.
    if (node.realtime() && drive_.power_state() == drive::PowerState::kOperationEnabled &&
        drive_.request(drive::DriveCommand::kShutdown).accepted) {
      drive_.apply(0.0);
      std::printf("%s: run ended: drive disabled (shutdown)\n", node.name().c_str());
    }
    release();
  }
  void flush(std::chrono::seconds /*timeout*/) override {
    release();  // a run that ended otherwise (its controller lost, a fault) leaves no slave in OP either
    const ethercat::Cia402DriveCounters& c = drive_.counters();
    std::printf(
        "drive_bridge: EtherCAT: %llu cycles (%llu outputs sent again), %llu exchanges without a reply (%llu "
        "frames lost, resends included), %llu working counter errors, %llu cycles without the inputs in time, "
        "%llu CoE emergencies read\n",
        static_cast<unsigned long long>(c.cycles), static_cast<unsigned long long>(c.output_resends),
        static_cast<unsigned long long>(c.frames_lost), static_cast<unsigned long long>(drive_.master().frames_lost()),
        static_cast<unsigned long long>(c.working_counter_errors), static_cast<unsigned long long>(c.missed_inputs),
        static_cast<unsigned long long>(drive_.emergencies()));
    if (const std::optional<std::int64_t> dc = dc_difference_ns_) {
      std::printf(
          "drive_bridge: EtherCAT distributed clock: %llu writes of the master's time (%llu lost), the "
          "drive's difference 0x092C %lld ns at the end\n",
          static_cast<unsigned long long>(c.dc_writes), static_cast<unsigned long long>(c.dc_writes_lost),
          static_cast<long long>(*dc));
    }
    if (drive_.sync0_start_ns() != 0) {
      std::printf("drive_bridge: EtherCAT SYNC0: %llu of %llu outputs sent after their tick's pulse (%u us into it)\n",
                  static_cast<unsigned long long>(c.outputs_after_sync0), static_cast<unsigned long long>(c.cycles),
                  static_cast<unsigned>(drive_.config().sync0_shift_us));
    }
    const drive::LatencySummary trip = drive_.round_trips();
    if (trip.count > 0) {
      std::printf("drive_bridge: EtherCAT frame round trip over %zu exchanges: p50 %.1f us, p99 %.1f us, max %.1f us\n",
                  trip.count, trip.p50_us, trip.p99_us, trip.max_us);
    }
    flush_capture();
  }
  bool outputs_complete() override { return !capture_failed_; }

 private:
  double since_boot_ms() const { return static_cast<double>(monotonic_ns() - boot_began_ns_) * 1e-6; }
  /// The filter expects the load's readings the system file declares: inputs that do not carry
  /// them would have the run end with the sensor failed, so the boot stops (the mapping is known
  /// only once the drive has it) and the slave goes back to INIT. @throws ConfigError
  void refuse_a_load_sensor_the_inputs_lack() {
    const LoadSensorKind carried = drive_.load_sensor();
    if (declared_load_sensor_ == LoadSensorKind::kNone || declared_load_sensor_ == carried) return;
    release();
    throw ConfigError(std::string("sensors.load.kind ") + to_string(declared_load_sensor_) +
                      " (the system file) but the drive's inputs (0x1C13's TxPDOs) carry " +
                      (carried == LoadSensorKind::kNone
                           ? std::string("no sensor on the load")
                           : std::string(to_string(carried)) + " (" + load_sensor_object(carried) + ")") +
                      ": the master would not read it; map " + load_sensor_object(declared_load_sensor_) +
                      " in pdo.inputs (--ethercat-set)");
  }
  /// The drive's slave out of OP (SAFEOP, INIT), once; its DC difference read before.
  void release() {
    if (released_ || drive_.lost() || !drive_.booted()) return;
    released_ = true;
    dc_difference_ns_ = drive_.dc_difference_ns();
    if (drive_.release()) {
      std::printf("drive_bridge: the drive's slave released to INIT\n");
    } else {
      std::fprintf(stderr, "drive_bridge: the drive's slave did not leave OP: %s\n", drive_.last_problem());
    }
  }

  /// The capture's last frames onto the disk, and how many it holds; a write that failed named.
  void flush_capture() {
    if (capture_ == nullptr) return;
    drive_.master().capture_to(nullptr);
    capture_failed_ = drive_.master().capture_failed();
    if (!capture_failed_) {
      try {
        capture_->flush();
      } catch (const std::runtime_error& e) {
        std::fprintf(stderr, "drive_bridge: EtherCAT capture: %s\n", e.what());
        capture_failed_ = true;
      }
    }
    if (capture_failed_) {
      std::fprintf(stderr, "drive_bridge: EtherCAT capture %s is not whole: a write failed after %llu frames\n",
                   capture_path_.c_str(), static_cast<unsigned long long>(capture_->frames()));
      return;
    }
    std::printf("drive_bridge: EtherCAT capture: %llu frames in %s\n",
                static_cast<unsigned long long>(capture_->frames()), capture_path_.c_str());
  }

  ethercat::Cia402Drive& drive_;
  std::string link_;
  ethercat::PcapngWriter* capture_;
  std::string capture_path_;
  LoadSensorKind declared_load_sensor_;
  std::uint64_t emergencies_reported_ = 0;
  bool capture_failed_ = false;
  ProblemReports reports_;
  std::int64_t boot_began_ns_ = 0;
  std::optional<std::int64_t> dc_difference_ns_;  ///< read before the slave is released
  bool released_ = false;
};

class EthercatBridgeComponent final : public node::DriveComponent {
 public:
  EthercatBridgeComponent(const node::ComponentContext& context, BridgeOptions options)
      : opt_(std::move(options)),
        rt_("drive_bridge", opt_.common, context),
        drive_config_(checked_config()),
        link_(node::open_master_link(opt_.ethercat)),
        capture_(node::open_ethercat_capture(opt_.ethercat)),
        drive_(drive_config_, *link_),
        hooks_(drive_, node::describe_link(opt_.ethercat, true), capture_.get(), opt_.ethercat.capture_path,
               rt_.cfg.params.load_sensor.kind),
        node_("drive_bridge", opt_.common, opt_.drive, rt_, drive_, hooks_) {
    drive_with(node_);
  }

 private:
  ethercat::Cia402DriveConfig checked_config() {
    ethercat::Cia402DriveConfig c = node::load_ethercat_config(opt_.ethercat);
    c.realtime = check_bridge_runtime(opt_, rt_);
    if (c.sync0 && !c.realtime) {
      throw ConfigError(
          "drive.sync0: SYNC0 runs on the drive's clock, which a lockstep run does not follow: "
          "realtime only (--clock realtime)");
    }
    // In csp the drive pulls its motor to 0x607A on its own encoder while our position loop pushes
    // the velocity offset 0x60B1 towards the load's (or the motor's) position: two position loops
    // in one axis, with neither's margins measured. csv follows V_ref plus our correction.
    if (const PositionFeedback outer = rt_.cfg.params.position_loop.closes_on;
        c.mode == canopen::kModeCyclicSynchronousPosition && outer != PositionFeedback::kNone) {
      throw ConfigError(std::string("position_loop.closes_on ") + to_string(outer) +
                        " (the system file) with drive.mode csp: the drive closes its own position loop on "
                        "its encoder; run the dual loop with drive.mode csv or cst, or set "
                        "position_loop.closes_on: none");
    }
    return c;
  }

  BridgeOptions opt_;
  node::NodeRuntime rt_;
  ethercat::Cia402DriveConfig drive_config_;
  std::unique_ptr<ethercat::Link> link_;
  std::unique_ptr<ethercat::PcapngWriter> capture_;
  ethercat::Cia402Drive drive_;
  EthercatHooks hooks_;
  node::DriveNode node_;
};

}  // namespace

namespace pmlsm::node {

PMLSM_COMPONENT(drive_bridge, make_drive_bridge, 0);

MadeComponent make_drive_bridge(const ComponentContext& context, int argc, char** argv) {
  BridgeOptions opt;
  opt.common.spin_us = 200.0;
  if (const auto code = parse_drive_bridge_command_line(argc, argv, opt)) return {nullptr, *code};
  if (opt.ethercat.bus == DriveBus::kEthercat)
    return {std::make_unique<EthercatBridgeComponent>(context, std::move(opt))};
  return {std::make_unique<DriveBridgeComponent>(context, std::move(opt))};
}

}  // namespace pmlsm::node

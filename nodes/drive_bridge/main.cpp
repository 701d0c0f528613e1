// drive_bridge: a real (or virtual) CiA 402 servo drive on CAN, on DDS. The same drive node as
// plant_sim (nodes/support/drive_node.hpp: the drive loop, MotorFeedback and DriveState,
// ForceCommand, DriveControl, watchdog, summary, exit codes) with the CANopen master
// (pmlsm::canopen::Cia402Drive) as its backend instead of the simulation. MotorFeedback's
// STATUS_SIMULATED bit is off; there is no PlantTruth and no voltage command level.
//
// Bus: UDP multicast (python-can's udp_multicast: --can-group, --can-port, --can-iface) by
// default, SocketCAN with --can-interface NAME. The drive: --node-id (1), cyclic synchronous
// torque, rated force --rated-force-n (675 N), --increments-per-metre (1e6).
//
// Before tick 0 (once the DDS peers are there) the drive is booted (boot-up or heartbeat, SDO
// set-up, NMT start) and, with --auto-enable, walked to operation enabled without stepping it.
// Lockstep: each tick is one SYNC exchange in which the drive steps one period with the
// previous tick's command; realtime: a SYNC each tick, the TPDOs taken within
// --tpdo-deadline-us. A drive that stops answering (after --sync-retries resends) or whose
// heartbeat is lost is a fault 0x8130: force off, the run ends not valid (exit 5).
//
// Exit codes as plant_sim's; a drive that cannot be booted or enabled: 1, with the reason.
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "drive_node.hpp"
#include "pmlsm/can/socketcan_bus.hpp"
#include "pmlsm/can/udp_multicast_bus.hpp"
#include "pmlsm/canopen/cia402_drive.hpp"

namespace {

using namespace pmlsm;

struct BusOptions {
  std::string group = "239.74.163.2";
  int port = 43113;
  std::string iface = "127.0.0.1";
  std::string interface_name;  // SocketCAN when set
};

std::unique_ptr<can::CanBus> open_bus(const BusOptions& options) {
  if (!options.interface_name.empty()) return std::make_unique<can::SocketCanBus>(options.interface_name);
  can::UdpMulticastParams params;
  params.group = options.group;
  params.port = options.port;
  params.interface_address = options.iface;
  return std::make_unique<can::UdpMulticastBus>(params);
}

/// drive_bridge's own parts of the drive node: the CANopen boot, the enable walk, and the
/// drive's problems reported once each.
class BridgeHooks final : public node::DriveNodeHooks {
 public:
  BridgeHooks(canopen::Cia402Drive& drive, const can::CanBus& bus) : drive_(drive), bus_(bus) {}

  void before_run(node::DriveNode& node) override {
    drive_.boot();
    drive_.start();
    std::printf("%s: drive node %d booted on %s: cyclic synchronous torque, rated force %.1f N, %g increments/m, "
                "periods stepped %u, %s\n",
                node.name().c_str(), drive_.config().node_id, bus_.describe().c_str(),
                drive_.config().scaling.rated_force_n, drive_.config().scaling.increments_per_metre,
                drive_.periods_stepped(), drive::to_string(drive_.power_state()));
  }
  void enable_at_start(node::DriveNode& node) override {
    drive_.enable_and_wait();
    std::printf("%s: drive %s (auto-enable)\n", node.name().c_str(), drive::to_string(drive_.power_state()));
  }
  void after_tick(node::DriveNode& node, std::uint64_t k) override {
    if (drive_.lost() && !lost_reported_) {
      lost_reported_ = true;
      std::fprintf(stderr, "%s: tick %llu: drive lost: %s: fault 0x%04x, zero force\n", node.name().c_str(),
                   static_cast<unsigned long long>(k), drive_.last_problem(), drive_.error_code());
      node.set_fault_reason(std::string("drive lost: ") + drive_.last_problem());
    }
    if (drive_.error_code() != reported_error_) {
      reported_error_ = drive_.error_code();
      std::fprintf(stderr, "%s: tick %llu: drive error code 0x%04x (%s), drive %s\n", node.name().c_str(),
                   static_cast<unsigned long long>(k), reported_error_, drive_.last_problem(),
                   drive::to_string(drive_.power_state()));
      if (!drive_.lost()) node.set_fault_reason(drive_.last_problem());
    }
    if (drive_.stuck_in() && !stuck_reported_) {
      stuck_reported_ = true;
      std::fprintf(stderr, "%s: tick %llu: the drive does not follow the controlword: stuck in %s\n",
                   node.name().c_str(), static_cast<unsigned long long>(k), drive::to_string(*drive_.stuck_in()));
    } else if (!drive_.stuck_in()) {
      stuck_reported_ = false;
    }
  }
  void flush() override {
    const canopen::Cia402DriveCounters& c = drive_.counters();
    std::printf("drive_bridge: CAN: %llu SYNCs (%llu resent), %llu RPDO1 resent, %llu ticks without TPDOs in time, "
                "%llu EMCYs\n",
                static_cast<unsigned long long>(c.syncs), static_cast<unsigned long long>(c.sync_resends),
                static_cast<unsigned long long>(c.rpdo_resends), static_cast<unsigned long long>(c.tpdo_missing),
                static_cast<unsigned long long>(c.emcys));
  }

 private:
  canopen::Cia402Drive& drive_;
  const can::CanBus& bus_;
  bool lost_reported_ = false;
  bool stuck_reported_ = false;
  std::uint16_t reported_error_ = 0;
};

int run(int argc, char** argv) {
  CLI::App app{"Bridge from DDS to a CiA 402 servo drive on CAN (cyclic synchronous torque)"};
  node::CommonOptions common;
  common.spin_us = 200.0;
  node::DriveNodeOptions opt;
  BusOptions bus_options;
  canopen::Cia402DriveConfig drive_config;
  node::add_common_options(app, common);
  node::add_drive_node_options(app, opt);
  app.add_option("--can-group", bus_options.group, "UDP multicast bus: the group")->capture_default_str();
  app.add_option("--can-port", bus_options.port, "UDP multicast bus: the port")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
  app.add_option("--can-iface", bus_options.iface, "UDP multicast bus: the interface address")
      ->capture_default_str();
  app.add_option("--can-interface", bus_options.interface_name,
                 "SocketCAN interface (can0, vcan0); when given, used instead of the UDP multicast bus");
  app.add_option("--node-id", drive_config.node_id, "the drive's CANopen node id")
      ->check(CLI::Range(1, 126))
      ->capture_default_str();
  app.add_option("--rated-force-n", drive_config.scaling.rated_force_n,
                 "the drive's rated force (0x6076): the torque objects' per mille refer to it")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--increments-per-metre", drive_config.scaling.increments_per_metre, "encoder increments per metre")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--sync-timeout-ms", drive_config.sync_timeout_ms,
                 "lockstep: how long a SYNC waits for its TPDOs before it is resent")
      ->check(CLI::Range(1, 60000))
      ->capture_default_str();
  app.add_option("--sync-retries", drive_config.sync_retries, "lockstep: SYNC resends before the drive is lost")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  app.add_option("--tpdo-deadline-us", drive_config.tpdo_deadline_us,
                 "realtime: how long into a tick the TPDOs are waited for")
      ->check(CLI::Range(0, 1000000))
      ->capture_default_str();
  app.add_option("--boot-timeout-ms", drive_config.boot_timeout_ms, "how long to wait for the drive's boot-up")
      ->check(CLI::Range(1, 600000))
      ->capture_default_str();
  app.add_option("--drive-heartbeat-ms", drive_config.drive_heartbeat_ms,
                 "the drive's heartbeat period (0x1017; 0: not watched)")
      ->capture_default_str();
  app.add_option("--drive-heartbeat-timeout-ms", drive_config.drive_heartbeat_timeout_ms,
                 "no drive heartbeat this long -> fault 0x8130")
      ->capture_default_str();
  app.add_option("--master-heartbeat-ms", drive_config.master_heartbeat_ms, "the bridge's heartbeat period")
      ->check(CLI::Range(1, 60000))
      ->capture_default_str();
  app.add_option("--master-heartbeat-timeout-ms", drive_config.master_heartbeat_timeout_ms,
                 "what the drive is told to allow between the bridge's heartbeats (0x1016)")
      ->capture_default_str();
  bool no_reset = false;
  app.add_flag("--no-reset-communication", no_reset,
               "do not start the boot with NMT reset communication: wait for the drive's own boot-up or heartbeat");
  if (const auto code = node::parse_command_line(app, argc, argv)) return *code;
  drive_config.reset_communication = !no_reset;
  try {
    drive_config.validate();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(e.what());
  }
  node::NodeRuntime rt("drive_bridge", common);
  node::check_drive_node_options("drive_bridge", opt, common, rt);
  if (rt.cfg.command_level == node::CommandLevel::kVoltage) {
    throw ConfigError("--command-level voltage: a CiA 402 drive runs its own current loop (cyclic synchronous "
                      "torque); drive_bridge takes force commands only");
  }
  if (std::abs(rt.period_s - 1e-3) > 1e-9) {
    throw ConfigError("control period " + std::to_string(rt.period_s * 1e3) +
                      " ms: the drive is set to a 1 ms interpolation period (0x60C2)");
  }
  drive_config.realtime = rt.cfg.clock == node::Clock::kRealtime;
  const std::unique_ptr<can::CanBus> bus = open_bus(bus_options);
  canopen::Cia402Drive drive(drive_config, *bus, [] { return monotonic_ns(); });
  BridgeHooks hooks(drive, *bus);
  node::DriveNode node("drive_bridge", common, opt, rt, drive, hooks);
  return node.run();
}

}  // namespace

int main(int argc, char** argv) {
  return pmlsm::node::run_node("drive_bridge", [&] { return run(argc, argv); });
}

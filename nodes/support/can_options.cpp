#include "can_options.hpp"
#include <CLI/CLI.hpp>

#include <stdexcept>

#include "pmlsm/can/socketcan_bus.hpp"

namespace pmlsm::node {

void add_can_options(CLI::App& app, CanOptions& options) {
  auto* group = app.add_option("--can-group", options.udp.group, "UDP multicast CAN bus: the group address")
                    ->capture_default_str();
  auto* port = app.add_option("--can-port", options.udp.port, "UDP multicast CAN bus: the port")
                   ->check(CLI::Range(1, 65535))
                   ->capture_default_str();
  auto* iface = app.add_option("--can-iface", options.udp.interface_address,
                               "UDP multicast CAN bus: the local interface address (0.0.0.0: the default route's)")
                    ->capture_default_str();
  app.add_option("--can-interface", options.interface_name,
                 "SocketCAN interface (can0, vcan0) instead of the UDP multicast bus")
      ->excludes(group)
      ->excludes(port)
      ->excludes(iface);
  app.add_option("--canopen-config", options.canopen_path,
                 "the CANopen settings both ends of the bus share (node ids, scaling, heartbeats, time-outs)")
      ->capture_default_str();
  app.add_option("--canopen-set", options.canopen_overrides,
                 "override a value of the CANopen settings: key.path=value (repeatable)");
}

std::unique_ptr<can::CanBus> open_can_bus(const CanOptions& options) {
  if (!options.interface_name.empty()) return std::make_unique<can::SocketCanBus>(options.interface_name);
  try {
    can::validate(options.udp);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("CAN bus: ") + e.what());
  }
  return std::make_unique<can::UdpMulticastBus>(options.udp);
}

CanopenRigConfig load_canopen_config(const CanOptions& options) {
  return pmlsm::load_canopen_config(options.canopen_path, parse_overrides(options.canopen_overrides));
}

}  // namespace pmlsm::node

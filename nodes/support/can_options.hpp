// What both ends of a CAN bus take on the command line (drive_bridge, virtual_drive): where
// the bus is and the CANopen file they share.
//   --can-group ADDR --can-port N --can-iface ADDR   the UDP multicast bus (python-can's
//                                                    udp_multicast wire format), the default
//   --can-interface NAME                             SocketCAN (can0) instead
//   --canopen-config FILE                            configs/canopen/drive.yaml
//   --canopen-set key.path=value                     overrides one value of it (repeatable)
#pragma once

#include "pmlsm/util/data_files.hpp"

#include <memory>
#include <string>
#include <vector>

#include "pmlsm/can/can_bus.hpp"
#include "pmlsm/can/udp_multicast_bus.hpp"
#include "pmlsm/config/canopen_config.hpp"

// Only declared, as in node_support.hpp: CLI11 is compiled only where options are declared.
namespace CLI {
class App;
}  // namespace CLI

namespace pmlsm::node {

struct CanOptions {
  can::UdpMulticastParams udp;  // group, port, interface address (its defaults)
  std::string interface_name;   // SocketCAN when set
  std::string canopen_path = pmlsm::data_file("configs/canopen/drive.yaml");
  std::vector<std::string> canopen_overrides;
};

void add_can_options(CLI::App& app, CanOptions& options);

/// @throws ConfigError for a bad group / port / interface address, std::runtime_error when
///         the socket cannot be opened.
std::unique_ptr<can::CanBus> open_can_bus(const CanOptions& options);

/// @throws ConfigError naming the file, key path and value.
CanopenRigConfig load_canopen_config(const CanOptions& options);

}  // namespace pmlsm::node

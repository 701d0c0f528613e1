// What both ends of an EtherCAT link take on the command line (drive_bridge and virtual_drive with
// --bus ethercat): where the frames go and the rig file they share.
//   --bus can|ethercat                   the bus to the drive (can: the CANopen options apply)
//   --ethercat-udp ADDRESS:PORT          master: EtherCAT over UDP to the drive (IPv4; the default,
//                                        127.0.0.1:34980)
//   --ethercat-udp-port N                virtual drive: answer EtherCAT over UDP on this port
//   --ethercat-interface IF              raw EtherCAT on an interface instead (CAP_NET_RAW); the
//                                        master then does not use --ethercat-udp ("": UDP, so a
//                                        launch file can pass both)
//   --ethercat-capture FILE              master: every frame of the run into a pcapng capture ("": none)
//   --ethercat-config FILE               configs/ethercat/drive.yaml
//   --ethercat-set key.path=value        overrides one value of it (repeatable)
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "pmlsm/ethercat/cia402_drive.hpp"
#include "pmlsm/ethercat/link.hpp"
#include "pmlsm/ethercat/pcapng.hpp"
#include "pmlsm/util/data_files.hpp"

namespace CLI {
class App;
}  // namespace CLI

namespace pmlsm::node {

enum class DriveBus : std::uint8_t { kCan, kEthercat };

struct EthercatOptions {
  DriveBus bus = DriveBus::kCan;
  std::string udp = "127.0.0.1:34980";  ///< master: the drive's address
  int udp_port = 34980;                 ///< drive: the port it answers on
  std::string interface_name;           ///< raw EtherCAT when set
  std::string capture_path;             ///< master: the run's frames into this pcapng file when set
  std::string config_path = pmlsm::data_file("configs/ethercat/drive.yaml");
  std::vector<std::string> overrides;
};

/// `master`: the bridge's options (--ethercat-udp), else the drive's (--ethercat-udp-port).
void add_ethercat_options(CLI::App& app, EthercatOptions& options, bool master);

/// The master's link to the drive. @throws ConfigError for a bad address, std::runtime_error when
/// the socket cannot be made.
std::unique_ptr<ethercat::Link> open_master_link(const EthercatOptions& options);
/// The drive's link, answering its master. @throws as open_master_link.
std::unique_ptr<ethercat::Link> open_drive_link(const EthercatOptions& options);
/// Where the link goes, for the log ("UDP 127.0.0.1:34980", "interface veth0").
std::string describe_link(const EthercatOptions& options, bool master);

/// @throws ConfigError naming the file, key path and value.
ethercat::Cia402DriveConfig load_ethercat_config(const EthercatOptions& options);

/// The capture --ethercat-capture asks for, nullptr when none. @throws ConfigError naming the path
/// when it cannot be written.
std::unique_ptr<ethercat::PcapngWriter> open_ethercat_capture(const EthercatOptions& options);

}  // namespace pmlsm::node

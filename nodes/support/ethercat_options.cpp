#include "ethercat_options.hpp"
#include <CLI/CLI.hpp>

#include <arpa/inet.h>

#include <map>

#include "pmlsm/config/config.hpp"
#include "pmlsm/config/ethercat_config.hpp"

namespace pmlsm::node {

void add_ethercat_options(CLI::App& app, EthercatOptions& options, bool master) {
  app.add_option("--bus", options.bus, "the bus to the drive: can (CANopen) or ethercat (CoE)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, DriveBus>{{"can", DriveBus::kCan}, {"ethercat", DriveBus::kEthercat}}))
      ->default_str("can");
  CLI::Option* udp = nullptr;
  if (master) {
    udp = app.add_option("--ethercat-udp", options.udp,
                         "--bus ethercat: EtherCAT over UDP to the drive at HOST:PORT (unless --ethercat-interface)")
              ->capture_default_str();
  } else {
    udp = app.add_option("--ethercat-udp-port", options.udp_port,
                         "--bus ethercat: answer EtherCAT over UDP on this port (0: any, printed)")
              ->check(CLI::Range(0, 65535))
              ->capture_default_str();
  }
  CLI::Option* raw =
      app.add_option("--ethercat-interface", options.interface_name,
                     "--bus ethercat: raw EtherCAT on this interface instead of UDP (needs CAP_NET_RAW; \"\": UDP)");
  if (!master) raw->excludes(udp);
  if (master) {
    app.add_option("--ethercat-capture", options.capture_path,
                   "--bus ethercat: every frame of the run into this pcapng capture (Wireshark, `pmlsm ethercat "
                   "pcap`; \"\": none)");
  }
  app.add_option("--ethercat-config", options.config_path,
                 "--bus ethercat: the EtherCAT settings both ends share (position, identity, scaling, time-outs)")
      ->capture_default_str();
  app.add_option("--ethercat-set", options.overrides,
                 "override a value of the EtherCAT settings: key.path=value (repeatable)");
}

namespace {

ethercat::UdpLinkParams master_udp(const EthercatOptions& options) {
  const std::size_t colon = options.udp.rfind(':');
  int port = -1;
  if (colon != std::string::npos && colon > 0) {
    try {
      std::size_t used = 0;
      port = std::stoi(options.udp.substr(colon + 1), &used);
      if (used != options.udp.size() - colon - 1) port = -1;
    } catch (const std::exception&) {
      port = -1;
    }
  }
  in_addr host{};
  if (port < 1 || port > 65535 || inet_pton(AF_INET, options.udp.substr(0, colon).c_str(), &host) != 1) {
    throw ConfigError("--ethercat-udp: expected an IPv4 address and a port in 1..65535 (127.0.0.1:34980), got '" +
                      options.udp + "'");
  }
  // The master binds a port of its own; the drive answers whoever sent.
  return {"0.0.0.0", 0, options.udp.substr(0, colon), static_cast<std::uint16_t>(port)};
}

}  // namespace

std::unique_ptr<ethercat::Link> open_master_link(const EthercatOptions& options) {
  if (!options.interface_name.empty()) return std::make_unique<ethercat::RawSocketLink>(options.interface_name);
  return std::make_unique<ethercat::UdpLink>(master_udp(options));
}

std::unique_ptr<ethercat::Link> open_drive_link(const EthercatOptions& options) {
  if (!options.interface_name.empty()) return std::make_unique<ethercat::RawSocketLink>(options.interface_name);
  return std::make_unique<ethercat::UdpLink>(
      ethercat::UdpLinkParams{"0.0.0.0", static_cast<std::uint16_t>(options.udp_port), "", 0});
}

std::string describe_link(const EthercatOptions& options, bool master) {
  if (!options.interface_name.empty()) return "raw EtherCAT on " + options.interface_name;
  return master ? "EtherCAT over UDP to " + options.udp
                : "EtherCAT over UDP on port " + std::to_string(options.udp_port);
}

ethercat::Cia402DriveConfig load_ethercat_config(const EthercatOptions& options) {
  return pmlsm::load_ethercat_config(options.config_path, parse_overrides(options.overrides));
}

std::unique_ptr<ethercat::PcapngWriter> open_ethercat_capture(const EthercatOptions& options) {
  if (options.capture_path.empty()) return nullptr;
  try {
    return std::make_unique<ethercat::PcapngWriter>(options.capture_path);
  } catch (const std::runtime_error& e) {
    throw ConfigError(std::string("--ethercat-capture: ") + e.what());
  }
}

}  // namespace pmlsm::node

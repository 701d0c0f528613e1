// configs/ethercat/drive.yaml: the EtherCAT side of a rig, read by the master (drive_bridge --bus
// ethercat) and the simulated drive (virtual_drive --bus ethercat), by the declarations of
// ethercat::visit_parameters. Unknown, duplicate or missing keys and out-of-range values are
// ConfigErrors naming the file, the key path and the value.
#pragma once

#include <string>
#include <vector>

#include "pmlsm/config/config.hpp"
#include "pmlsm/ethercat/cia402_drive.hpp"

namespace pmlsm {

/// @throws ConfigError naming the file, key path and value of the first problem.
ethercat::Cia402DriveConfig load_ethercat_config(const std::string& path,
                                                 const std::vector<ConfigOverride>& overrides = {});
ethercat::Cia402DriveConfig parse_ethercat_config(const std::string& yaml_text, const std::string& origin,
                                                  const std::vector<ConfigOverride>& overrides = {});

}  // namespace pmlsm

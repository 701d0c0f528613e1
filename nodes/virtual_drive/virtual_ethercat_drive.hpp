// virtual_drive --bus ethercat: the simulated drive behind a virtual EtherCAT slave.
#pragma once

#include "cycle_component.hpp"
#include "virtual_drive_command_line.hpp"

namespace pmlsm::node {

/// @throws ConfigError for bad options or files, std::runtime_error when the link cannot be made.
MadeComponent make_virtual_ethercat_drive(const ComponentContext& context, VirtualDriveOptions options);

}  // namespace pmlsm::node

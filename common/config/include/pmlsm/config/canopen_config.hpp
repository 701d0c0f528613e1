// configs/canopen/drive.yaml: the CANopen side of a rig, read by both ends of the bus
// (drive_bridge, the master, and virtual_drive, the simulated slave), so they always agree.
//
//   bus.bitrate_bps                1e4..1e6      for the bus load figure (the master does not set it)
//   drive.node_id                  1..127
//   drive.rated_force_n            > 0           0x6076 (as mN); 0x6071 / 0x6077 are per mille of it
//   drive.increments_per_metre     > 0           0x6064, 0x606C
//   drive.heartbeat_ms             0..65535      0x1017 (written by the master at boot; 0: none)
//   drive.sync_timeout_ms          1..65535      the drive's own SYNC watch (virtual drive, realtime)
//   master.node_id                 1..127        its heartbeat's node id (0x1016.1 bits 16-23)
//   master.heartbeat_ms            1..65535
//   master.heartbeat_timeout_ms    1..65535      > master.heartbeat_ms; written to 0x1016.1
//   master.drive_heartbeat_timeout_ms 1..65535   > drive.heartbeat_ms when that is not 0
//   master.boot_timeout_ms, master.sdo_timeout_ms, master.enable_timeout_cycles, master.sync_overflow
//   master.lockstep.sync_timeout_ms, master.lockstep.sync_retries, master.realtime.tpdo_deadline_us,
//   master.realtime.max_missed_answers
//
// Unknown, duplicate or missing keys and out-of-range values are ConfigErrors naming the file,
// the key path and the value.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "pmlsm/canopen/cia402_drive.hpp"
#include "pmlsm/config/config.hpp"

namespace pmlsm {

struct CanopenRigConfig {
  /// The master's settings; `realtime` and `reset_communication` are the program's to set.
  canopen::Cia402DriveConfig master;
  /// The drive's own SYNC watch: no SYNC this long while enabled -> fault (virtual drive).
  std::uint16_t drive_sync_timeout_ms = 10;
  std::uint32_t bitrate_bps = 1000000;
};

/// @throws ConfigError naming the file, key path and value of the first problem.
CanopenRigConfig load_canopen_config(const std::string& path, const std::vector<ConfigOverride>& overrides = {});
CanopenRigConfig parse_canopen_config(const std::string& yaml_text, const std::string& origin,
                                      const std::vector<ConfigOverride>& overrides = {});

}  // namespace pmlsm

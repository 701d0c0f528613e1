// configs/canopen/virtual_drive.yaml: the CANopen side of the virtual drive. Every value is a
// sourced leaf `{value: ..., source: "..."}` as in configs/system.yaml:
//
//   node_id                 1..127           the drive's node id
//   rated_force_n           > 0              0x6076 (as mN), the base of the per-mille torques
//   increments_per_metre    > 0              encoder increments per metre (0x6064, 0x606C)
//   heartbeat_producer_ms   0..65535         0x1017 (0: no heartbeat)
//   heartbeat_consumer:
//     master_node_id        1..127           the master whose heartbeat is watched (0x1016.1)
//     time_ms               0..65535         consumer time (0: not watched)
//   sync_timeout_ms         1..65535         realtime: no SYNC this long in operation enabled -> fault
//
// Unknown, duplicate or missing keys and out-of-range values are errors (ConfigError) naming
// the file, the key path and the value.
#pragma once

#include <cstdint>
#include <string>

#include "pmlsm/config/config.hpp"

namespace pmlsm::virtual_drive {

struct CanopenConfig {
  int node_id = 5;
  double rated_force_n = 675.0;
  double increments_per_metre = 1e6;
  std::uint16_t heartbeat_producer_ms = 100;
  int master_node_id = 1;
  std::uint16_t consumer_time_ms = 0;
  std::uint16_t sync_timeout_ms = 10;
};

/// @throws ConfigError naming the file, key path and offending value.
CanopenConfig load_canopen_config(const std::string& path);
CanopenConfig parse_canopen_config(const std::string& yaml_text, const std::string& origin);

}  // namespace pmlsm::virtual_drive

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

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/cia402_drive.hpp"
#include "pmlsm/canopen/object_dictionary.hpp"
#include "pmlsm/canopen/pdo.hpp"
#include "pmlsm/config/config.hpp"

namespace pmlsm {

struct CanopenRigConfig {
  /// The master's settings; `realtime` and `reset_communication` are the program's to set.
  canopen::Cia402DriveConfig master;
  /// The drive's own SYNC watch: no SYNC this long while enabled -> fault (virtual drive).
  std::uint16_t drive_sync_timeout_ms = 10;
  std::uint32_t bitrate_bps = 1000000;
  /// The ranges of visit_rig_parameters, then the master's relations.
  /// @throws std::invalid_argument naming the key and the value.
  void validate() const;
};

/// Every setting of configs/canopen/drive.yaml, declared once (pmlsm/util/parameter_table.hpp):
/// the rig's own and the master's (canopen::visit_parameters). Config is CanopenRigConfig or
/// const CanopenRigConfig.
template <typename Config, typename Visitor>
void visit_rig_parameters(Config& c, Visitor& v) {
  v.integer("bus.bitrate_bps", c.bitrate_bps,
            {10000.0, 1000000.0, "CiA 301 bit rates: 10 kbit/s to 1 Mbit/s (for the bus load figure)"});
  v.integer("drive.sync_timeout_ms", c.drive_sync_timeout_ms,
            {1.0, 65535.0, "the drive's own SYNC watch: 16 bits of milliseconds"});
  canopen::visit_parameters(c.master, v);
}

/// The device-specific part of a slave's object dictionary, EDS-like
/// (configs/canopen/virtual_drive_od.yaml): the identity (0x1018), manufacturer-specific objects
/// (0x2000-0x5FFF) and the PDOs' default communication and mapping. The CiA 301 / 402 profile
/// objects (with their value checks) come from canopen::make_cia402_dictionary.
struct DictionaryObject {
  std::uint16_t index = 0;
  std::uint8_t subindex = 0;
  std::string name;
  canopen::DataType type = canopen::DataType::kU8;
  canopen::Access access = canopen::Access::kRo;
  bool pdo_mappable = false;
  std::int64_t value = 0;
};

struct PdoDefault {
  /// "rpdo1", "tpdo1", "tpdo2" or "tpdo3".
  std::string channel;
  /// The COB-ID: cob_id + the node id when node_relative (EDS: "$NODEID+0x180").
  std::uint32_t cob_id = 0;
  bool node_relative = true;
  /// false: the PDO is mapped but not sent until a master makes it valid (EDS: bit 31 of the
  /// COB-ID set, "$NODEID+0x80000380").
  bool valid = true;
  std::uint8_t transmission_type = 1;
  std::vector<canopen::PdoMapEntry> mapping;
};

struct DeviceDictionary {
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision_number = 0;
  std::uint32_t serial_number = 0;
  std::vector<DictionaryObject> objects;
  std::vector<PdoDefault> pdos;
};

/// @throws ConfigError naming the file, key path and value of the first problem (an index
///         outside 0x2000-0x5FFF, an unknown type or access, a mapping entry "0xIIII:SS:BITS"
///         whose bit length is not 8, 16 or 32, an unknown or repeated PDO channel).
DeviceDictionary load_device_dictionary(const std::string& path);
DeviceDictionary parse_device_dictionary(const std::string& yaml_text, const std::string& origin);

/// @throws ConfigError naming the file, key path and value of the first problem.
CanopenRigConfig load_canopen_config(const std::string& path, const std::vector<ConfigOverride>& overrides = {});
CanopenRigConfig parse_canopen_config(const std::string& yaml_text, const std::string& origin,
                                      const std::vector<ConfigOverride>& overrides = {});

/// The virtual drive's dictionary: CiA 301 / 402's objects (make_cia402_dictionary) for the rig's
/// scaling, heartbeats and an interpolation period (0x60C2) of `control_period_s`, TPDO2's entries (as
/// TPDO1's, invalid and empty), then the device's part from its description (identity,
/// manufacturer objects, the PDOs' defaults written as a master would: CiA 301's order, every
/// check). `device` must outlive the dictionary (the entries' names point into it).
/// @throws ConfigError naming the object or PDO entry the dictionary refused, or a control period
///         that is not a whole number of milliseconds in [1, 255].
/// `supported_drive_modes`: 0x6502 (canopen::kSupportedModes*; velocity and position only for a
/// drive whose application closes those loops).
canopen::ObjectDictionary build_device_dictionary(const CanopenRigConfig& rig, const DeviceDictionary& device,
                                                  double control_period_s,
                                                  std::uint32_t supported_drive_modes = canopen::kSupportedModesTorque);

}  // namespace pmlsm

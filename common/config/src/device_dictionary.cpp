#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/cia402_slave.hpp"
#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/canopen/nmt.hpp"
#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/config/config.hpp"

namespace pmlsm {

namespace co = canopen;

namespace {

/// 0x60C2's interpolation period: a whole number of milliseconds.
std::uint8_t interpolation_ms(double period_s) {
  const double ms = period_s * 1e3;
  if (std::fabs(ms - std::round(ms)) > 1e-9 || ms < 1.0 || ms > 255.0) {
    throw ConfigError("timing.control_period_s " + std::to_string(period_s) +
                      ": the virtual drive needs a whole number of milliseconds in [1, 255] (0x60C2)");
  }
  return static_cast<std::uint8_t>(std::lround(ms));
}

void must(co::Status s, const std::string& what) {
  if (s) return;
  char code[16];
  std::snprintf(code, sizeof code, "0x%08X", static_cast<unsigned>(s.abort_code));
  throw ConfigError("device dictionary: " + what + ": refused (" + s.detail + ", abort " + code + ")");
}

/// TPDO n's (2 or 3) communication and mapping entries, copied from TPDO1's (the same checks);
/// invalid and empty until the description configures them.
void add_tpdo(co::ObjectDictionary& od, co::NodeId node, int n) {
  static const char* const kCommNames[2][6] = {
      {"TPDO2 communication: highest sub-index", "TPDO2 COB-ID", "TPDO2 transmission type", "TPDO2 inhibit time", "",
       "TPDO2 event timer"},
      {"TPDO3 communication: highest sub-index", "TPDO3 COB-ID", "TPDO3 transmission type", "TPDO3 inhibit time", "",
       "TPDO3 event timer"}};
  static const char* const kCountNames[2] = {"TPDO2 mapping: number of entries", "TPDO3 mapping: number of entries"};
  const auto offset = static_cast<std::uint16_t>(n - 1);
  for (std::uint8_t sub : {0, 1, 2, 3, 5}) {
    const co::Entry* from = od.find(co::kObjectTpdo1Communication, sub);
    if (from == nullptr) throw std::logic_error("device dictionary: 0x1800 lacks a sub-index");
    co::Entry copy = *from;
    copy.index = static_cast<std::uint16_t>(co::kObjectTpdo1Communication + offset);
    copy.name = kCommNames[n - 2][sub];
    if (sub == 1) copy.value = co::tpdo_cob_id(n, node) | co::kPdoCobIdInvalid;
    od.add(copy);
  }
  for (std::uint8_t sub = 0; sub <= 8; ++sub) {
    const co::Entry* from = od.find(co::kObjectTpdo1Mapping, sub);
    if (from == nullptr) throw std::logic_error("device dictionary: 0x1A00 lacks a sub-index");
    co::Entry copy = *from;
    copy.index = static_cast<std::uint16_t>(co::kObjectTpdo1Mapping + offset);
    if (sub == 0) copy.name = kCountNames[n - 2];
    copy.value = 0;
    od.add(copy);
  }
}

/// A PDO's defaults as a master would write them (CiA 301's order, with every check): PDO
/// invalid, mapping count 0, the entries, the count, the transmission type, PDO valid.
void write_pdo_default(co::ObjectDictionary& od, co::NodeId node, const PdoDefault& pdo) {
  const std::uint16_t comm = pdo.channel == "rpdo1"   ? co::kObjectRpdo1Communication
                             : pdo.channel == "tpdo1" ? co::kObjectTpdo1Communication
                             : pdo.channel == "tpdo2" ? co::kObjectTpdo2Communication
                                                      : co::kObjectTpdo3Communication;
  const auto map = static_cast<std::uint16_t>(comm + co::kPdoMappingOffset);
  const std::uint32_t cob = pdo.cob_id + (pdo.node_relative ? node.value() : 0U);
  const auto write = [&](std::uint16_t index, std::uint8_t sub, std::uint32_t value, const std::string& what) {
    must(od.write(index, sub, co::SdoData{value, 0}), pdo.channel + " " + what);
  };
  write(comm, 1, cob | co::kPdoCobIdInvalid, "COB-ID (invalid while remapped)");
  write(map, 0, 0, "mapping count 0");
  for (std::size_t i = 0; i < pdo.mapping.size(); ++i) {
    char entry[80];  // the longest: 20 digits of %zu, 4 hex digits, 3 + 3 decimals
    std::snprintf(entry, sizeof entry, "mapping entry %zu (0x%04X:%u:%u)", i + 1,
                  static_cast<unsigned>(pdo.mapping[i].index), static_cast<unsigned>(pdo.mapping[i].subindex),
                  static_cast<unsigned>(pdo.mapping[i].bit_length));
    write(map, static_cast<std::uint8_t>(i + 1), co::encode_pdo_mapping(pdo.mapping[i]), entry);
  }
  write(map, 0, static_cast<std::uint32_t>(pdo.mapping.size()), "mapping count");
  write(comm, 2, pdo.transmission_type, "transmission type");
  if (pdo.valid) write(comm, 1, cob, "COB-ID");  // else left invalid, as the description says
}

}  // namespace

co::ObjectDictionary build_device_dictionary(const CanopenRigConfig& rig, const DeviceDictionary& device,
                                             double control_period_s, std::uint32_t supported_drive_modes) {
  const co::NodeId node(rig.master.node_id);
  const co::UnitScaling scaling(rig.master.scaling);
  co::Cia402DictionaryConfig dc;
  dc.rated_torque = scaling.rated_torque_object();
  dc.producer_heartbeat_ms = rig.master.drive_heartbeat_ms;
  dc.interpolation_period_ms = interpolation_ms(control_period_s);
  dc.vendor_id = device.vendor_id;
  dc.product_code = device.product_code;
  dc.revision_number = device.revision_number;
  dc.serial_number = device.serial_number;
  dc.supported_drive_modes = supported_drive_modes;
  co::ObjectDictionary od = co::make_cia402_dictionary(node, dc);

  for (const DictionaryObject& obj : device.objects) {
    co::Entry e;
    e.index = obj.index;
    e.subindex = obj.subindex;
    e.name = obj.name.c_str();
    e.type = obj.type;
    e.access = obj.access;
    e.pdo_mappable = obj.pdo_mappable;
    e.value = obj.value;
    try {
      od.add(e);
    } catch (const std::invalid_argument& error) {
      throw ConfigError(std::string("device dictionary: ") + error.what());
    }
  }
  must(od.set(co::kObjectConsumerHeartbeatTime, 1,
              co::consumer_heartbeat_entry(static_cast<std::uint8_t>(rig.master.master_node_id),
                                           rig.master.master_heartbeat_timeout_ms)),
       "0x1016.1");
  add_tpdo(od, node, 2);
  add_tpdo(od, node, 3);
  for (const PdoDefault& pdo : device.pdos) write_pdo_default(od, node, pdo);
  for (std::uint16_t mapping :
       {co::kObjectRpdo1Mapping, co::kObjectTpdo1Mapping, co::kObjectTpdo2Mapping, co::kObjectTpdo3Mapping}) {
    const co::Result<co::PdoMap> pdo_map = co::read_pdo_map(od, mapping);
    if (!pdo_map) throw ConfigError("device dictionary: mapping invalid: " + std::string(pdo_map.detail));
  }
  return od;
}

}  // namespace pmlsm

// configs/canopen/drive.yaml and configs/canopen/virtual_drive_od.yaml: the shipped files load
// with the values they say; every bad value is refused naming the file, the key and the value.
#include <gtest/gtest.h>

#include <string>

#include "config_edit.hpp"
#include "pmlsm/canopen/cia402_application.hpp"
#include "pmlsm/config/canopen_config.hpp"

namespace pmlsm {
namespace {

using test::error_of;
const auto& shipped = test::read_text;

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

TEST(CanopenConfig, TheShippedFileLoadsWithItsValues) {
  const CanopenRigConfig c = parse_canopen_config(shipped("configs/canopen/drive.yaml"), "drive.yaml");
  EXPECT_EQ(c.bitrate_bps, 1000000U);
  EXPECT_EQ(c.master.node_id, 1);
  EXPECT_EQ(c.master.master_node_id, 127);
  EXPECT_DOUBLE_EQ(c.master.scaling.rated_force_n, 675.0);
  EXPECT_DOUBLE_EQ(c.master.scaling.increments_per_metre, 1e6);
  EXPECT_EQ(c.master.drive_heartbeat_ms, 100);
  EXPECT_EQ(c.master.master_heartbeat_timeout_ms, 350);
  EXPECT_EQ(c.master.sync_retries, 5U);
  EXPECT_EQ(c.master.max_missed_answers, 10U);
  EXPECT_EQ(c.drive_sync_timeout_ms, 10);
}

TEST(CanopenConfig, OverridesAndBadValuesNameTheKeyAndValue) {
  const std::string text = shipped("configs/canopen/drive.yaml");
  const CanopenRigConfig c = parse_canopen_config(text, "drive.yaml", {ConfigOverride::parse("drive.node_id=5")});
  EXPECT_EQ(c.master.node_id, 5);
  EXPECT_NE(error_of([&] {
              parse_canopen_config(text, "drive.yaml", {ConfigOverride::parse("drive.node_id=128")});
            }).find("drive.yaml: drive.node_id: must be in [1, 127] (a CANopen node id"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              parse_canopen_config(text, "drive.yaml", {ConfigOverride::parse("master.node_id=1")});
            }).find("master.node_id: must differ from drive.node_id 1"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              parse_canopen_config(text, "drive.yaml", {ConfigOverride::parse("master.heartbeat_timeout_ms=50")});
            }).find("master.heartbeat_timeout_ms: must exceed"),
            std::string::npos);
  EXPECT_NE(error_of([&] { parse_canopen_config(text + "extra: 1\n", "drive.yaml"); }).find("extra: unknown key"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              parse_canopen_config(text, "drive.yaml", {ConfigOverride::parse("drive.rated_force_n=-1")});
            }).find("drive.rated_force_n"),
            std::string::npos);
}

TEST(CanopenConfig, AnErrorInTheFileNamesItsLine) {
  const std::string text = shipped("configs/canopen/drive.yaml");
  std::size_t line = 1;
  for (std::size_t i = 0; i < text.find("  node_id: {value: 1,"); ++i) line += text[i] == '\n' ? 1 : 0;
  const std::string where = "(line " + std::to_string(line) + ")";
  // Out of range (found by validate(), after reading) and not a number (found while reading).
  EXPECT_NE(error_of([&] {
              parse_canopen_config(replaced(text, "node_id: {value: 1,", "node_id: {value: 0,"), "drive.yaml");
            }).find("drive.node_id: must be in [1, 127] (a CANopen node id (CiA 301: 1 to 127)), got 0 " + where),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              parse_canopen_config(replaced(text, "node_id: {value: 1,", "node_id: {value: one,"), "drive.yaml");
            }).find("drive.node_id: expected a non-negative integer, got 'one' " + where),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              parse_canopen_config(replaced(text, "node_id: {value: 127,", "node_id: {value: 1,"), "drive.yaml");
            }).find("master.node_id: must differ from drive.node_id 1 (line "),
            std::string::npos);
}

TEST(DeviceDictionary, TheShippedDescriptionLoads) {
  const DeviceDictionary d = parse_device_dictionary(shipped("configs/canopen/virtual_drive_od.yaml"), "od.yaml");
  EXPECT_EQ(d.product_code, 0x402U);
  ASSERT_EQ(d.objects.size(), 3U);
  EXPECT_EQ(d.objects[0].index, 0x2001);
  EXPECT_EQ(d.objects[0].name, "periods stepped");
  EXPECT_EQ(d.objects[1].access, canopen::Access::kRw);
  EXPECT_EQ(d.objects[2].index, canopen::kObjectLoadAcceleration);
  EXPECT_EQ(d.objects[2].type, canopen::DataType::kI32);
  ASSERT_EQ(d.pdos.size(), 4U);
  EXPECT_EQ(d.pdos[0].channel, "rpdo1");
  EXPECT_TRUE(d.pdos[0].node_relative);
  EXPECT_EQ(d.pdos[0].cob_id, 0x200U);
  ASSERT_EQ(d.pdos[2].mapping.size(), 2U);
  EXPECT_EQ(d.pdos[2].mapping[1], (canopen::PdoMapEntry{0x2001, 0, 32}));
  EXPECT_TRUE(d.pdos[2].valid);
  // TPDO3, the load's sensor: mapped, not valid (bit 31) until a master asks for it.
  EXPECT_EQ(d.pdos[3].channel, "tpdo3");
  EXPECT_EQ(d.pdos[3].cob_id, 0x380U);
  EXPECT_FALSE(d.pdos[3].valid);
  EXPECT_EQ(d.pdos[3].mapping[0], (canopen::PdoMapEntry{0x60E4, 1, 32}));
}

TEST(DeviceDictionary, BadDescriptionsAreRefusedNamingTheItem) {
  const std::string text = shipped("configs/canopen/virtual_drive_od.yaml");
  const auto refused = [&](const std::string& from, const std::string& to, const std::string& expected) {
    const std::string e = error_of([&] { parse_device_dictionary(replaced(text, from, to), "od.yaml"); });
    EXPECT_NE(e.find(expected), std::string::npos) << from << " -> " << to << ": " << e;
  };
  refused("index: \"0x2001\"", "index: \"0x6040\"",
          "objects[0].index: a manufacturer-specific object lies in 0x2000-0x5FFF");
  refused("type: u32, access: ro", "type: u64, access: ro", "objects[0].type: one of u8");
  refused("access: ro", "access: rx", "objects[0].access: one of ro, rw, wo, const, got 'rx'");
  refused("index: \"0x2002\"", "index: \"0x2001\"", "objects[1]: object 0x2001 sub 0 is listed twice");
  refused("\"0x6040:0:16\"", "\"0x6040:0:12\"", "pdos[0].mapping[0]: the bit length must be 8, 16 or 32");
  refused("\"0x6040:0:16\"", "\"0x6040\"", "pdos[0].mapping[0]: expected \"0xIIII:SS:BITS\"");
  refused("channel: tpdo2", "channel: tpdo1", "pdos[2].channel: tpdo1 is listed twice");
  refused("channel: tpdo2", "channel: tpdo9", "pdos[2].channel: one of rpdo1, tpdo1, tpdo2, tpdo3");
  refused("cob_id: \"$NODEID+0x200\"", "cob_id: \"$NODEID+0x900\"",
          "pdos[0].cob_id: an 11-bit id (bit 31 may mark the PDO not valid), got '$NODEID+0x900'");
  refused("vendor_id: \"0x00000000\"", "vendor_id: \"-1\"", "identity.vendor_id");
  EXPECT_NE(error_of([&] { parse_device_dictionary(text + "eds: 1\n", "od.yaml"); }).find("eds: unknown key"),
            std::string::npos);
}

}  // namespace
}  // namespace pmlsm

// Our master against virtual slave controllers (pmlsm/ethercat/master.hpp, esc.hpp) on a virtual
// segment in this thread: the bus scanned and addressed by position, each slave's identity read
// from its SII through the EEPROM interface, the AL state walk with every refusal the standard
// names, logical process data through FMMUs with its working counter, and, where the shared
// captures are there, a real Kollmorgen AKD's SII image read as the AKD reports itself.
#include "pmlsm/ethercat/master.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/ethercat/mailbox.hpp"
#include "pmlsm/ethercat/sii.hpp"

namespace pmlsm::ethercat {
namespace {

/// An SII image: identity, a standard mailbox at 0x1000 and 0x1080 (128 bytes each, CoE), and
/// the end of the categories.
std::vector<std::uint16_t> sii_image(std::uint32_t vendor, std::uint32_t product, std::uint32_t serial) {
  std::vector<std::uint16_t> w(sii::kMinWords, 0);
  const auto put = [&](std::uint16_t at, std::uint32_t v) {
    w[at] = static_cast<std::uint16_t>(v & 0xFFFF);
    w[at + 1] = static_cast<std::uint16_t>(v >> 16);
  };
  put(sii::kVendorId, vendor);
  put(sii::kProductCode, product);
  put(sii::kRevision, 0x00020001);
  put(sii::kSerial, serial);
  w[sii::kMailboxReceiveOffset] = 0x1000;
  w[sii::kMailboxReceiveSize] = 128;
  w[sii::kMailboxSendOffset] = 0x1080;
  w[sii::kMailboxSendSize] = 128;
  w[sii::kMailboxProtocols] = 0x0004;
  w[sii::kFirstCategory] = 0xFFFF;
  return w;
}

/// Three slaves on a segment the master reaches in this thread.
struct Bus {
  std::vector<std::unique_ptr<Esc>> slaves;
  std::unique_ptr<VirtualSegment> segment;
  std::unique_ptr<VirtualSegmentLink> link;
  Bus() {
    std::vector<Esc*> line;
    for (std::uint32_t i = 0; i < 3; ++i) {
      EscParams p;
      p.sii = sii_image(0x0000006A + i, 0x00414B44 + i, 1000 + i);
      p.output_bytes = 4;
      p.input_bytes = 6;
      slaves.push_back(std::make_unique<Esc>(p));
      line.push_back(slaves.back().get());
    }
    segment = std::make_unique<VirtualSegment>(line);
    link = std::make_unique<VirtualSegmentLink>(*segment);
  }
};

TEST(EtherCatMaster, ScansTheBusAddressesItByPositionAndReadsEachSlavesIdentity) {
  Bus bus;
  Master master(*bus.link);
  ASSERT_EQ(master.count_slaves(), 3);
  const std::vector<std::uint16_t> stations = master.assign_station_addresses(3);
  ASSERT_EQ(stations, (std::vector<std::uint16_t>{0x1001, 0x1002, 0x1003}));
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(bus.slaves[i]->station_address(), stations[i]);
    const SlaveInfo info = master.read_slave_info(stations[i]);
    EXPECT_EQ(info.vendor_id, 0x0000006AU + i);
    EXPECT_EQ(info.product_code, 0x00414B44U + i);
    EXPECT_EQ(info.revision, 0x00020001U);
    EXPECT_EQ(info.serial, 1000U + i);
    EXPECT_EQ(info.mailbox_receive_offset, 0x1000);
    EXPECT_EQ(info.mailbox_send_size, 128);
    EXPECT_EQ(info.mailbox_protocols, 0x0004);
  }
  // An odd number of words from the end category (type 0xFFFF, size 0) on, past the image (an
  // erased EEPROM reads 0xFFFF).
  const std::vector<std::uint16_t> tail = master.read_sii(0x1002, sii::kFirstCategory, 5);
  EXPECT_EQ(tail, (std::vector<std::uint16_t>{0xFFFF, 0, 0xFFFF, 0xFFFF, 0xFFFF}));
  EXPECT_EQ(master.frames_lost(), 0u);
}

TEST(EtherCatMaster, WalksTheAlStatesAndReadsEachRefusalByName) {
  Bus bus;
  Master master(*bus.link);
  master.assign_station_addresses(3);
  const std::uint16_t s = 0x1001;
  // Without its mailbox sync managers a slave stays in INIT.
  StateResult r = master.request_state(s, AlState::kPreOp);
  EXPECT_FALSE(r.reached);
  EXPECT_EQ(r.state, AlState::kInit);
  EXPECT_EQ(r.code, al_code::kInvalidMailboxConfiguration);
  EXPECT_EQ(r.describe(), "INIT, refused: 0x0016 invalid mailbox configuration");
  // A mailbox of the wrong size is refused too.
  master.configure_sync_manager(s, 0, 0x1000, 64, kSmControlMailboxWrite);
  master.configure_sync_manager(s, 1, 0x1080, 128, kSmControlMailboxRead);
  EXPECT_EQ(master.request_state(s, AlState::kPreOp).code, al_code::kInvalidMailboxConfiguration);
  master.configure_sync_manager(s, 0, 0x1000, 128, kSmControlMailboxWrite);
  r = master.request_state(s, AlState::kPreOp);
  EXPECT_TRUE(r.reached) << r.describe();
  EXPECT_EQ(bus.slaves[0]->al_state(), AlState::kPreOp);
  // OP straight from PREOP: an invalid change.
  EXPECT_EQ(master.request_state(s, AlState::kOp).code, al_code::kInvalidStateChange);
  // SAFEOP needs the process data's sync managers at the mapping's lengths: outputs, then inputs.
  EXPECT_EQ(master.request_state(s, AlState::kSafeOp).code, al_code::kInvalidOutputConfiguration);
  master.configure_sync_manager(s, 2, 0x1100, 4, kSmControlOutputs);
  EXPECT_EQ(master.request_state(s, AlState::kSafeOp).code, al_code::kInvalidInputConfiguration);
  master.configure_sync_manager(s, 3, 0x1180, 6, kSmControlInputs);
  EXPECT_TRUE(master.request_state(s, AlState::kSafeOp).reached);
  EXPECT_TRUE(master.request_state(s, AlState::kOp).reached);
  EXPECT_EQ(bus.slaves[0]->al_state(), AlState::kOp);
  EXPECT_EQ(bus.slaves[0]->al_status_code(), 0) << "every refusal was acknowledged";
  EXPECT_EQ(master.request_state(s, AlState::kBoot).code, al_code::kBootstrapNotSupported);
  EXPECT_TRUE(master.request_state(s, AlState::kInit).reached);
  // The other slaves were not touched.
  EXPECT_EQ(bus.slaves[1]->al_state(), AlState::kInit);
  EXPECT_STREQ(al_status_code_name(0x001B), "sync manager watchdog");
  EXPECT_STREQ(al_status_code_name(0x7777), "unknown AL status code");
}

TEST(EtherCatMaster, ProcessDataCrossesTheFmmusWithTheWorkingCounterOfEverySlave) {
  Bus bus;
  Master master(*bus.link);
  master.assign_station_addresses(3);
  // One logical image: each slave's 4 output bytes at 0x10000 + 10 i, its 6 input bytes after them.
  for (std::uint16_t i = 0; i < 3; ++i) {
    const auto station = static_cast<std::uint16_t>(0x1001 + i);
    master.configure_fmmu(station, 0, 0x10000U + 10U * i, 4, 0x1100, true);
    master.configure_fmmu(station, 1, 0x10000U + 10U * i + 4, 6, 0x1180, false);
    const std::array<std::uint8_t, 6> inputs{static_cast<std::uint8_t>(0xA0 + i), 1, 2, 3, 4, 5};
    bus.slaves[i]->write_memory(0x1180, inputs.data(), inputs.size());
  }
  std::array<std::uint8_t, 30> image{};
  for (std::size_t i = 0; i < 3; ++i) image[10 * i] = static_cast<std::uint8_t>(0x10 + i);
  const Reply r = master.exchange(Command::kLrw, 0x10000, image.data(), image.size());
  ASSERT_TRUE(r.answered);
  EXPECT_EQ(r.working_counter, expected_working_counter(Command::kLrw, 3));
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(bus.slaves[i]->byte_at(0x1100), 0x10 + i) << "slave " << i << "'s outputs";
    EXPECT_EQ(image[10 * i + 4], 0xA0 + i) << "slave " << i << "'s inputs";
    EXPECT_EQ(image[10 * i + 9], 5);
  }
  // A logical read of outputs only: nobody maps a read there.
  std::array<std::uint8_t, 4> outputs{};
  EXPECT_EQ(master.exchange(Command::kLrd, 0x10000, outputs.data(), 4).working_counter, 0);
  // A slave past the bus: no answer, no throw from exchange; the set-up step names it.
  EXPECT_EQ(master.count_slaves(), 3);
  EXPECT_THROW(master.read_state(0x1009), std::runtime_error);
}

TEST(EtherCatMaster, ReadsAndWritesTheCia402DictionaryOverCoeAsCanopenServesIt) {
  EscParams p;
  p.sii = sii_image(0x0000006A, 0x00414B44, 77);
  Esc slave(p);
  canopen::Cia402DictionaryConfig config;
  config.vendor_id = 0x0000006A;
  canopen::ObjectDictionary dictionary = canopen::make_cia402_dictionary(canopen::NodeId(1), config);
  CoeSdoServer coe(dictionary, canopen::NodeId(1));
  slave.set_mailbox_handler(&coe);
  VirtualSegment segment({&slave});
  VirtualSegmentLink link(segment);
  Master master(link);
  master.assign_station_addresses(1);
  const SlaveInfo info = master.read_slave_info(0x1001);
  master.configure_mailbox(info);
  ASSERT_TRUE(master.request_state(0x1001, AlState::kPreOp).reached);
  // An empty send mailbox is not read: working counter 0.
  std::array<std::uint8_t, 128> empty{};
  EXPECT_EQ(master.exchange(Command::kFprd, physical_address(0x1001, 0x1080), empty.data(), 128).working_counter, 0);

  SdoResult r = master.sdo_upload(info, canopen::kObjectDeviceType, 0);
  ASSERT_TRUE(r.done) << r.describe();
  EXPECT_EQ(r.value, canopen::kDeviceTypeCia402Servo);
  EXPECT_EQ(r.describe(), "0x00020192");
  r = master.sdo_upload(info, canopen::kObjectIdentity, 1);
  EXPECT_EQ(r.value, 0x0000006AU);
  // Cyclic synchronous torque chosen over CoE, read back, and seen by the drive's own dictionary.
  r = master.sdo_download(info, 0x6060, 0, static_cast<std::uint8_t>(canopen::kModeCyclicSynchronousTorque), 1);
  ASSERT_TRUE(r.done) << r.describe();
  EXPECT_EQ(master.sdo_upload(info, 0x6060, 0).value, 10u);
  // CiA 301's aborts, named.
  r = master.sdo_upload(info, 0x7777, 0);
  EXPECT_FALSE(r.done);
  EXPECT_EQ(r.abort_code, 0x06020000u);
  EXPECT_NE(r.describe().find("aborted: 0x06020000"), std::string::npos) << r.describe();
  r = master.sdo_download(info, canopen::kObjectDeviceType, 0, 1, 4);
  EXPECT_EQ(r.abort_code, 0x06010002u) << r.describe();  // read only
  EXPECT_EQ(coe.requests(), 6u);
  EXPECT_THROW(master.sdo_download(info, 0x6060, 0, 1, 5), std::invalid_argument);
  // A slave without a mailbox has no CoE, and no mailbox to set.
  SlaveInfo no_mailbox = info;
  no_mailbox.mailbox_receive_size = 0;
  EXPECT_THROW(master.sdo_upload(no_mailbox, 0x1000, 0), std::runtime_error);
  EXPECT_THROW(master.configure_mailbox(no_mailbox), std::runtime_error);
}

TEST(EtherCatMaster, MapsTheCia402PdosFromCoeAndExchangesThemWithTheSlavesDictionary) {
  VirtualCia402Slave drive;
  canopen::ObjectDictionary& dictionary = drive.dictionary();
  ASSERT_EQ(drive.process().output_bytes(), 4);  // controlword, target torque
  ASSERT_EQ(drive.process().input_bytes(), 8);   // statusword, torque actual, position actual
  VirtualSegment segment({&drive.esc()});
  VirtualSegmentLink link(segment);
  Master master(link);
  master.assign_station_addresses(1);
  const SlaveInfo info = master.read_slave_info(0x1001);
  EXPECT_EQ(info.name, "PMLSM virtual drive");
  EXPECT_EQ(info.product_code, VirtualCia402Slave::kProductCode);
  master.configure_mailbox(info);
  ASSERT_TRUE(master.request_state(0x1001, AlState::kPreOp).reached);
  // SAFEOP before the process data is mapped: refused for its outputs.
  EXPECT_EQ(master.request_state(0x1001, AlState::kSafeOp).code, al_code::kInvalidOutputConfiguration);
  const ProcessDataLayout layout = master.map_process_data(info, 0x20000);
  EXPECT_EQ(layout.output_bytes, 4);
  EXPECT_EQ(layout.input_bytes, 8);
  EXPECT_EQ(layout.inputs_logical, 0x20004U);
  ASSERT_TRUE(master.request_state(0x1001, AlState::kSafeOp).reached);
  ASSERT_TRUE(master.request_state(0x1001, AlState::kOp).reached);
  // One cycle: the outputs in, the slave's application between frames, the inputs out.
  ASSERT_TRUE(dictionary.set(0x6041, 0, 0x0237));  // statusword: operation enabled
  ASSERT_TRUE(dictionary.set(0x6064, 0, -123456));
  std::array<std::uint8_t, 12> image{0x0F, 0x00, 0x2C, 0x01};  // controlword 0x000F, 300 per mille
  Reply r = master.exchange(Command::kLrw, 0x20000, image.data(), image.size());
  EXPECT_EQ(r.working_counter, 3);
  drive.exchange();
  EXPECT_EQ(dictionary.get_or(0x6040, 0, -1), 0x000F);
  EXPECT_EQ(dictionary.get_or(0x6071, 0, -1), 300);
  r = master.exchange(Command::kLrw, 0x20000, image.data(), image.size());
  EXPECT_EQ(r.working_counter, 3);
  EXPECT_EQ(image[4] | (image[5] << 8), 0x0237) << "statusword";
  const auto position = static_cast<std::int32_t>(static_cast<std::uint32_t>(image[8]) | (image[9] << 8) |
                                                  (image[10] << 16) | (static_cast<std::uint32_t>(image[11]) << 24));
  EXPECT_EQ(position, -123456);
  EXPECT_EQ(drive.process().refused_outputs(), 0u);
}

TEST(EtherCatSii, AnImageBuiltIsReadBackAndAMalformedOneIsRefusedByName) {
  SiiInfo info;
  info.vendor_id = 0x6A;
  info.product_code = 0x414B44;
  info.serial = 9;
  info.mailbox_receive_offset = 0x1000;
  info.mailbox_receive_size = 128;
  info.mailbox_protocols = 0x0004;
  info.name = "a drive";
  info.order = "D-1";
  info.group = "Drive";
  info.sync_managers = {{0x1000, 128, 0x26, 1, 1}, {0x1100, 4, 0x64, 1, 3}};
  std::vector<std::uint16_t> image = build_sii(info);
  const SiiInfo back = parse_sii(image);
  EXPECT_EQ(back.vendor_id, 0x6AU);
  EXPECT_EQ(back.product_code, 0x414B44U);
  EXPECT_EQ(back.serial, 9U);
  EXPECT_EQ(back.name, "a drive");
  EXPECT_EQ(back.order, "D-1");
  EXPECT_EQ(back.group, "Drive");
  EXPECT_EQ(back.sync_managers, info.sync_managers);
  // A category longer than the image.
  std::vector<std::uint16_t> cut(image.begin(), image.begin() + sii::kFirstCategory + 4);
  try {
    parse_sii(cut);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("category 10 at word 0x0040"), std::string::npos) << e.what();
  }
  // A name pointing past the strings.
  image[sii::kFirstCategory + 2] = 1;  // one string left of three
  EXPECT_THROW(parse_sii(image), std::invalid_argument);
  EXPECT_THROW(parse_sii(std::vector<std::uint16_t>(10, 0)), std::invalid_argument);
}

TEST(EtherCatMaster, ReadsARealAkdsSiiImageAsTheDriveReportsItself) {
  const std::filesystem::path image =
      std::filesystem::path(PMLSM_SOURCE_DIR) / ".." / "shared" / "ethercat" / "captures" / "akd.hex";
  if (!std::filesystem::exists(image)) GTEST_SKIP() << "no " << image << " (the shared EtherCAT captures)";
  EscParams p;
  p.sii = read_sii_image(image.string());
  Esc akd(p);
  VirtualSegment segment({&akd});
  VirtualSegmentLink link(segment);
  Master master(link);
  ASSERT_EQ(master.count_slaves(), 1);
  master.assign_station_addresses(1);
  const SlaveInfo info = master.read_slave_info(0x1001);
  // Kollmorgen's vendor ID and the AKD's product code ("AKD" in ASCII), as its SII holds them.
  EXPECT_EQ(info.vendor_id, 0x0000006AU);
  EXPECT_EQ(info.product_code, 0x00414B44U);
  EXPECT_EQ(info.revision, 2U);
  EXPECT_EQ(info.mailbox_receive_offset, 0x1800);
  EXPECT_EQ(info.mailbox_receive_size, 0x0400);
  EXPECT_EQ(info.mailbox_send_offset, 0x1C00);
  EXPECT_EQ(info.mailbox_protocols & 0x0004, 0x0004) << "CoE";
  // Its categories: the name its general category points to, and its four sync managers.
  EXPECT_EQ(info.name, "AKD EtherCAT Drive (CoE)");
  EXPECT_EQ(info.order, "AKD");
  EXPECT_EQ(info.group, "Drive");
  ASSERT_EQ(info.sync_managers.size(), 4u);
  EXPECT_EQ(info.sync_managers[0], (SiiSyncManager{0x1800, 0x0400, 0x26, 1, 1}));
  EXPECT_EQ(info.sync_managers[1], (SiiSyncManager{0x1C00, 0x0400, 0x22, 1, 2}));
  EXPECT_EQ(info.sync_managers[2].start, 0x1100);
  EXPECT_EQ(info.sync_managers[3].type, 4);
}

}  // namespace
}  // namespace pmlsm::ethercat

// PDO mapping, validation against the dictionary, pack/unpack round trips and errors.
#include <gtest/gtest.h>

#include "pmlsm/canopen/bytes.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/pdo.hpp"

namespace {

using namespace pmlsm::canopen;

const NodeId kPdoNode(3);

PdoMap map_of(std::initializer_list<PdoMapEntry> entries) {
  PdoMap map;
  for (const PdoMapEntry& e : entries) EXPECT_EQ(map.add(e), kAbortNone);
  return map;
}

TEST(PdoMapTest, MappingEntryCoding) {
  EXPECT_EQ(encode_pdo_mapping({0x6041, 0, 16}), 0x60410010u);
  EXPECT_EQ(encode_pdo_mapping({0x1018, 4, 32}), 0x10180420u);
  EXPECT_EQ(decode_pdo_mapping(0x60640020u), (PdoMapEntry{0x6064, 0, 32}));
  EXPECT_EQ(kPdoCobIdInvalid, 0x80000000u);
}

TEST(PdoMapTest, AtMostEightEntriesAnd64Bits) {
  PdoMap map;
  for (int i = 0; i < 8; ++i) EXPECT_EQ(map.add({0x2000, static_cast<std::uint8_t>(i), 8}), kAbortNone);
  EXPECT_EQ(map.total_bits(), 64u);
  EXPECT_EQ(map.byte_length(), 8);
  EXPECT_EQ(map.add({0x2000, 9, 8}), kAbortPdoLength);
  map.clear();
  EXPECT_TRUE(map.empty());
  EXPECT_EQ(map.add({0x6064, 0, 32}), kAbortNone);
  EXPECT_EQ(map.add({0x6064, 0, 32}), kAbortNone);
  EXPECT_EQ(map.add({0x6041, 0, 16}), kAbortPdoLength);
  EXPECT_EQ(map.size(), 2u);
  EXPECT_EQ(map.add({0x6041, 0, 12}), kAbortNotMappable);
  EXPECT_EQ(map.add({0x6041, 0, 0}), kAbortNotMappable);
}

TEST(PdoMapTest, ValidationAgainstTheDictionary) {
  const ObjectDictionary od = make_cia402_dictionary(kPdoNode);
  EXPECT_TRUE(validate_pdo_map(map_of({{0x6040, 0, 16}, {0x6071, 0, 16}}), od, PdoDirection::kReceive).ok());
  EXPECT_TRUE(validate_pdo_map(map_of({{0x6041, 0, 16}, {0x6064, 0, 32}}), od, PdoDirection::kTransmit).ok());
  struct Row {
    PdoMapEntry entry;
    PdoDirection direction;
    std::uint32_t abort;
  };
  const Row rows[] = {
      {{0x7000, 0, 16}, PdoDirection::kTransmit, kAbortObjectMissing},
      {{0x6041, 1, 16}, PdoDirection::kTransmit, kAbortSubindexMissing},
      {{0x6060, 0, 8}, PdoDirection::kReceive, kAbortNotMappable},    // not mappable
      {{0x6041, 0, 16}, PdoDirection::kReceive, kAbortNotMappable},   // read-only into an RPDO
      {{0x6041, 0, 32}, PdoDirection::kTransmit, kAbortNotMappable},  // wrong length
      {{0x6064, 0, 16}, PdoDirection::kTransmit, kAbortNotMappable},  // part of an object
  };
  for (const Row& row : rows) {
    const Status s = validate_pdo_map(map_of({row.entry}), od, row.direction);
    EXPECT_EQ(s.error, Error::kPdoMapping) << std::hex << row.entry.index;
    EXPECT_EQ(s.abort_code, row.abort) << std::hex << row.entry.index;
    EXPECT_STRNE(s.detail, "");
  }
}

TEST(PdoMapTest, ReadFromTheMappingObjects) {
  const ObjectDictionary od = make_cia402_dictionary(kPdoNode);
  const auto rpdo = read_pdo_map(od, 0x1600);
  ASSERT_TRUE(rpdo.ok()) << rpdo.detail;
  EXPECT_EQ(rpdo.value.size(), 2u);
  EXPECT_EQ(rpdo.value[0], (PdoMapEntry{0x6040, 0, 16}));
  EXPECT_EQ(rpdo.value[1], (PdoMapEntry{0x6071, 0, 16}));
  const auto tpdo = read_pdo_map(od, 0x1A00);
  ASSERT_TRUE(tpdo.ok());
  EXPECT_EQ(tpdo.value.byte_length(), 8);
  EXPECT_EQ(read_pdo_map(od, 0x1400).error, Error::kInvalidValue);
  EXPECT_EQ(read_pdo_map(od, 0x1601).error, Error::kAccessRefused);

  const auto comm = read_pdo_communication(od, 0x1800);
  ASSERT_TRUE(comm.ok());
  EXPECT_EQ(comm.value.cob_id, 0x183u);
  EXPECT_TRUE(comm.value.valid);
  EXPECT_EQ(comm.value.transmission_type, 1);
  EXPECT_EQ(read_pdo_communication(od, 0x1A00).error, Error::kInvalidValue);
  EXPECT_EQ(pdo_direction_of(0x1400).value, PdoDirection::kReceive);
  EXPECT_EQ(pdo_direction_of(0x1A00).value, PdoDirection::kTransmit);
  EXPECT_FALSE(pdo_direction_of(0x2000).ok());
}

TEST(PdoPackTest, PackLittleEndianInMappingOrder) {
  ObjectDictionary od = make_cia402_dictionary(kPdoNode);
  ASSERT_TRUE(od.set(0x6041, 0, 0x0237).ok());
  ASSERT_TRUE(od.set(0x6077, 0, -2).ok());
  ASSERT_TRUE(od.set(0x6064, 0, 0x12345678).ok());
  const PdoMap map = read_pdo_map(od, 0x1A00).value;
  const auto frame = pack_pdo(map, od, tpdo_cob_id(1, kPdoNode));
  ASSERT_TRUE(frame.ok()) << frame.detail;
  EXPECT_EQ(frame.value.id, 0x183u);
  EXPECT_EQ(frame.value.dlc, 8);
  EXPECT_EQ(frame.value.data, (std::array<std::uint8_t, 8>{0x37, 0x02, 0xFE, 0xFF, 0x78, 0x56, 0x34, 0x12}));
  EXPECT_EQ(pack_pdo(map, od, 0).error, Error::kWrongCobId);
  EXPECT_EQ(pack_pdo(map, od, 0x800).error, Error::kWrongCobId);
  const auto bad = pack_pdo(map_of({{0x7000, 0, 16}}), od, 0x183);
  EXPECT_EQ(bad.error, Error::kPdoMapping);
  EXPECT_EQ(bad.abort_code, kAbortObjectMissing);
}

TEST(PdoPackTest, RoundTripBetweenTwoDictionaries) {
  // The master's copy and the drive's: pack on one side, unpack on the other.
  ObjectDictionary drive = make_cia402_dictionary(kPdoNode);
  ObjectDictionary master = make_cia402_dictionary(kPdoNode);
  const PdoMap rpdo = read_pdo_map(drive, 0x1600).value;
  for (std::int64_t torque : {-32768LL, -1LL, 0LL, 1LL, 999LL, 32767LL}) {
    ASSERT_TRUE(master.set(0x6040, 0, 0x000F).ok());
    ASSERT_TRUE(master.set(0x6071, 0, torque).ok());
    const auto frame = pack_pdo(rpdo, master, rpdo_cob_id(1, kPdoNode));
    ASSERT_TRUE(frame.ok());
    EXPECT_EQ(frame.value.dlc, 4);
    ASSERT_TRUE(unpack_pdo(rpdo, drive, frame.value).ok());
    EXPECT_EQ(drive.get(0x6040, 0), 0x000F);
    EXPECT_EQ(drive.get(0x6071, 0), torque);
  }
}

TEST(PdoPackTest, WrongLengthWritesNothing) {
  ObjectDictionary od = make_cia402_dictionary(kPdoNode);
  const PdoMap rpdo = read_pdo_map(od, 0x1600).value;
  CanFrame frame = make_frame(0x203, 3);
  frame.data = {0x0F, 0x00, 0x64, 0x00, 0, 0, 0, 0};
  Status s = unpack_pdo(rpdo, od, frame);
  EXPECT_EQ(s.error, Error::kWrongDlc);
  EXPECT_STREQ(s.detail, "PDO unpack: DLC shorter than the mapping");
  frame.dlc = 5;
  s = unpack_pdo(rpdo, od, frame);
  EXPECT_EQ(s.error, Error::kWrongDlc);
  EXPECT_STREQ(s.detail, "PDO unpack: DLC longer than the mapping");
  EXPECT_EQ(od.get(0x6040, 0), 0);
  EXPECT_EQ(od.get(0x6071, 0), 0);
  frame.dlc = 4;
  frame.rtr = true;
  EXPECT_EQ(unpack_pdo(rpdo, od, frame).error, Error::kRemoteFrame);
  frame.rtr = false;
  EXPECT_TRUE(unpack_pdo(rpdo, od, frame).ok());
  EXPECT_EQ(od.get(0x6040, 0), 0x000F);
  EXPECT_EQ(od.get(0x6071, 0), 100);
}

TEST(PdoPackTest, OutOfRangeValueWritesNothing) {
  ObjectDictionary od(4);
  Entry a;
  a.index = 0x2000;
  a.name = "first";
  a.type = DataType::kU16;
  a.access = Access::kRw;
  a.pdo_mappable = true;
  od.add(a);
  Entry b = a;
  b.index = 0x2001;
  b.name = "limited";
  b.type = DataType::kI16;
  b.min = -10;
  b.max = 10;
  od.add(b);
  const PdoMap map = map_of({{0x2000, 0, 16}, {0x2001, 0, 16}});
  ASSERT_TRUE(validate_pdo_map(map, od, PdoDirection::kReceive).ok());
  CanFrame frame = make_frame(0x201, 4);
  frame.data = {0x34, 0x12, 11, 0, 0, 0, 0, 0};
  const Status s = unpack_pdo(map, od, frame);
  EXPECT_EQ(s.error, Error::kAccessRefused);
  EXPECT_EQ(s.abort_code, kAbortValueTooHigh);
  EXPECT_EQ(od.get(0x2000, 0), 0);  // the first value was not written either
  frame.data[2] = 10;
  EXPECT_TRUE(unpack_pdo(map, od, frame).ok());
  EXPECT_EQ(od.get(0x2000, 0), 0x1234);
  EXPECT_EQ(od.get(0x2001, 0), 10);
}

TEST(PdoPackTest, UnpackRefusesAMapOfReadOnlyEntries) {
  ObjectDictionary od = make_cia402_dictionary(kPdoNode);
  const PdoMap tpdo = read_pdo_map(od, 0x1A00).value;
  CanFrame frame = make_frame(0x183, 8);
  const Status s = unpack_pdo(tpdo, od, frame);
  EXPECT_EQ(s.error, Error::kPdoMapping);
  EXPECT_EQ(s.abort_code, kAbortNotMappable);
}

}  // namespace

// The object dictionary, its SDO server (each abort code) and the CiA 402 drive's dictionary.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "pmlsm/canopen/bytes.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/nmt.hpp"
#include "pmlsm/canopen/pdo.hpp"
#include "pmlsm/canopen/sdo_server.hpp"

namespace {

using namespace pmlsm::canopen;

const NodeId kDictionaryNode(3);

Entry entry(std::uint16_t index, std::uint8_t sub, const char* name, DataType type, Access access,
            std::int64_t value = 0) {
  Entry e;
  e.index = index;
  e.subindex = sub;
  e.name = name;
  e.type = type;
  e.access = access;
  e.value = value;
  return e;
}

CanFrame raw_request(std::array<std::uint8_t, 8> data, std::uint8_t dlc = 8) {
  CanFrame f = make_frame(sdo_rx_cob_id(kDictionaryNode), dlc);
  f.data = data;
  return f;
}

// Sends `request` to a server over `od` and returns the abort code of its answer (0 for a
// non-abort response).
std::uint32_t abort_of(const SdoServerResult& result) {
  EXPECT_TRUE(result.respond);
  EXPECT_EQ(result.response.id, 0x583u);
  EXPECT_EQ(result.response.dlc, 8);
  return result.response.data[0] == kSdoAbort ? get_u32_le(result.response.data, 4) : 0;
}

// ---- ObjectDictionary --------------------------------------------------------------------------

TEST(ObjectDictionaryTest, TypeHelpers) {
  EXPECT_EQ(size_of(DataType::kU8), 1);
  EXPECT_EQ(size_of(DataType::kI16), 2);
  EXPECT_EQ(size_of(DataType::kU32), 4);
  EXPECT_EQ(type_min(DataType::kI8), -128);
  EXPECT_EQ(type_max(DataType::kI8), 127);
  EXPECT_EQ(type_max(DataType::kU32), 4294967295LL);
  EXPECT_EQ(type_min(DataType::kI32), -2147483648LL);
  EXPECT_EQ(to_raw(DataType::kI16, -2), 0xFFFEu);
  EXPECT_EQ(from_raw(DataType::kI16, 0xFFFE), -2);
  EXPECT_EQ(from_raw(DataType::kI8, 0x80), -128);
  EXPECT_EQ(from_raw(DataType::kU16, 0xFFFF), 65535);
  EXPECT_EQ(from_raw(DataType::kI32, 0x80000000u), -2147483648LL);
  EXPECT_STREQ(to_string(DataType::kI32), "INTEGER32");
  EXPECT_STREQ(to_string(Access::kConst), "const");
}

TEST(ObjectDictionaryTest, AddValidatesWithTheEntryInTheMessage) {
  ObjectDictionary od(4);
  od.add(entry(0x2000, 0, "a", DataType::kU8, Access::kRw));
  try {
    od.add(entry(0x2000, 0, "again", DataType::kU8, Access::kRw));
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "object 0x2000 sub 0 (again): already in the dictionary");
  }
  EXPECT_THROW(od.add(entry(0x2001, 0, "", DataType::kU8, Access::kRw)), std::invalid_argument);
  Entry too_big = entry(0x2002, 0, "too big", DataType::kU8, Access::kRw, 256);
  try {
    od.add(too_big);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "object 0x2002 sub 0 (too big): value must be in [0, 255], got 256");
  }
  Entry inverted = entry(0x2003, 0, "inverted", DataType::kI16, Access::kRw);
  inverted.min = 5;
  inverted.max = 4;
  EXPECT_THROW(od.add(inverted), std::invalid_argument);
  Entry wide = entry(0x2004, 0, "wide", DataType::kI8, Access::kRw);
  wide.max = 1000;
  EXPECT_THROW(od.add(wide), std::invalid_argument);
  od.add(entry(0x2005, 0, "b", DataType::kU8, Access::kRw));
  od.add(entry(0x2006, 0, "c", DataType::kU8, Access::kRw));
  od.add(entry(0x2007, 0, "d", DataType::kU8, Access::kRw));
  EXPECT_THROW(od.add(entry(0x2008, 0, "full", DataType::kU8, Access::kRw)), std::invalid_argument);
  EXPECT_THROW(ObjectDictionary(0), std::invalid_argument);
}

TEST(ObjectDictionaryTest, KeptSortedAndFound) {
  ObjectDictionary od(8);
  od.add(entry(0x6041, 0, "statusword", DataType::kU16, Access::kRo));
  od.add(entry(0x1018, 2, "product", DataType::kU32, Access::kRo));
  od.add(entry(0x1018, 1, "vendor", DataType::kU32, Access::kRo));
  od.add(entry(0x1000, 0, "device type", DataType::kU32, Access::kConst));
  std::uint32_t last = 0;
  for (const Entry& e : od) {
    const std::uint32_t key = (std::uint32_t{e.index} << 8) | e.subindex;
    EXPECT_GT(key, last);
    last = key;
  }
  ASSERT_NE(od.find(0x1018, 1), nullptr);
  EXPECT_STREQ(od.find(0x1018, 1)->name, "vendor");
  EXPECT_EQ(od.find(0x1018, 3), nullptr);
  EXPECT_EQ(od.locate(0x1018, 3), kAbortSubindexMissing);
  EXPECT_EQ(od.locate(0x1019, 0), kAbortObjectMissing);
  EXPECT_EQ(od.locate(0x6041, 0), kAbortNone);
  EXPECT_TRUE(od.contains(0x1018));
  EXPECT_FALSE(od.contains(0x1017));
}

TEST(ObjectDictionaryTest, ApplicationSetIgnoresAccessButNotTheTypeRange) {
  ObjectDictionary od(4);
  Entry limited = entry(0x6071, 0, "target", DataType::kI16, Access::kRw);
  limited.min = -100;
  limited.max = 100;
  od.add(limited);
  od.add(entry(0x6041, 0, "statusword", DataType::kU16, Access::kRo));
  EXPECT_TRUE(od.set(0x6041, 0, 0x0237).ok());
  EXPECT_EQ(od.get(0x6041, 0), 0x0237);
  EXPECT_TRUE(od.set(0x6071, 0, 1000).ok());  // min/max are for the master's writes
  EXPECT_EQ(od.set(0x6041, 0, 65536).abort_code, kAbortValueTooHigh);
  EXPECT_EQ(od.set(0x6041, 0, -1).abort_code, kAbortValueTooLow);
  EXPECT_EQ(od.set(0x6042, 0, 1).abort_code, kAbortObjectMissing);
  EXPECT_EQ(od.set(0x6041, 1, 1).abort_code, kAbortSubindexMissing);
  EXPECT_FALSE(od.get(0x6042, 0).has_value());
  EXPECT_EQ(od.get_or(0x6042, 0, -7), -7);
}

// ---- SDO server: every abort code ----------------------------------------------------------------

class SdoServerTest : public ::testing::Test {
 protected:
  SdoServerTest() : od(16), server(od, kDictionaryNode) {
    od.add(entry(0x1000, 0, "device type", DataType::kU32, Access::kConst, 0x00020192));
    od.add(entry(0x1018, 0, "identity: highest sub", DataType::kU8, Access::kConst, 1));
    od.add(entry(0x1018, 1, "vendor", DataType::kU32, Access::kRo, 0x1234));
    od.add(entry(0x2000, 0, "password", DataType::kU16, Access::kWo));
    Entry ranged = entry(0x2001, 0, "ranged", DataType::kI16, Access::kRw, 0);
    ranged.min = -500;
    ranged.max = 500;
    od.add(ranged);
    od.add(entry(0x2002, 0, "byte", DataType::kU8, Access::kRw, 7));
    od.add(entry(0x2003, 0, "signed byte", DataType::kI8, Access::kRw, -5));
    Entry checked = entry(0x2004, 0, "only ten", DataType::kI8, Access::kRw, 10);
    checked.check = [](const ObjectDictionary&, const Entry&, std::int64_t v) noexcept -> std::uint32_t {
      return v == 10 ? kAbortNone : kAbortValueRange;
    };
    od.add(checked);
  }

  SdoServerResult upload(std::uint16_t index, std::uint8_t sub) {
    return server.handle(sdo_upload_request(kDictionaryNode, index, sub));
  }
  SdoServerResult download(std::uint16_t index, std::uint8_t sub, std::uint32_t data, std::uint8_t size) {
    return server.handle(sdo_download_request(kDictionaryNode, index, sub, data, size).value);
  }

  ObjectDictionary od;
  SdoServer server;
};

TEST_F(SdoServerTest, UploadAnswersWithTheValueAndItsSize) {
  SdoServerResult r = upload(0x1000, 0);
  EXPECT_EQ(abort_of(r), 0u);
  EXPECT_TRUE(r.status.ok());
  EXPECT_EQ(r.response.data, (std::array<std::uint8_t, 8>{0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00}));
  r = upload(0x2002, 0);
  EXPECT_EQ(r.response.data, (std::array<std::uint8_t, 8>{0x4F, 0x02, 0x20, 0x00, 0x07, 0, 0, 0}));
  r = upload(0x2001, 0);
  EXPECT_EQ(r.response.data[0], 0x4B);
  r = upload(0x2003, 0);
  EXPECT_EQ(r.response.data, (std::array<std::uint8_t, 8>{0x4F, 0x03, 0x20, 0x00, 0xFB, 0, 0, 0}));
}

TEST_F(SdoServerTest, UploadAbortCodes) {
  EXPECT_EQ(abort_of(upload(0x3000, 0)), kAbortObjectMissing);
  EXPECT_EQ(abort_of(upload(0x1018, 2)), kAbortSubindexMissing);
  const SdoServerResult wo = upload(0x2000, 0);
  EXPECT_EQ(abort_of(wo), kAbortReadWriteOnly);
  EXPECT_EQ(wo.status.error, Error::kAccessRefused);
  EXPECT_EQ(wo.status.abort_code, kAbortReadWriteOnly);
  // The abort names the request's multiplexer.
  EXPECT_EQ(wo.response.data[1], 0x00);
  EXPECT_EQ(wo.response.data[2], 0x20);
  EXPECT_EQ(wo.response.data[3], 0x00);
}

TEST_F(SdoServerTest, DownloadWritesAndAnswers0x60) {
  SdoServerResult r = download(0x2001, 0, 0xFE0C, 2);  // -500
  EXPECT_EQ(abort_of(r), 0u);
  EXPECT_EQ(r.response.data, (std::array<std::uint8_t, 8>{0x60, 0x01, 0x20, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(od.get(0x2001, 0), -500);
  EXPECT_EQ(abort_of(download(0x2000, 0, 0xBEEF, 2)), 0u);
  EXPECT_EQ(od.get(0x2000, 0), 0xBEEF);
  // e = 1, s = 0: the object's size applies.
  r = server.handle(raw_request({0x22, 0x02, 0x20, 0x00, 0x2A, 0x00, 0x00, 0x00}));
  EXPECT_EQ(abort_of(r), 0u);
  EXPECT_EQ(od.get(0x2002, 0), 0x2A);
}

TEST_F(SdoServerTest, DownloadAbortCodes) {
  EXPECT_EQ(abort_of(download(0x3000, 0, 1, 1)), kAbortObjectMissing);
  EXPECT_EQ(abort_of(download(0x1018, 9, 1, 1)), kAbortSubindexMissing);
  EXPECT_EQ(abort_of(download(0x1018, 1, 1, 4)), kAbortWriteReadOnly);
  EXPECT_EQ(abort_of(download(0x1000, 0, 1, 4)), kAbortWriteReadOnly);  // const
  EXPECT_EQ(abort_of(download(0x2001, 0, 1, 4)), kAbortLengthMismatch);
  EXPECT_EQ(abort_of(download(0x2001, 0, 1, 1)), kAbortLengthMismatch);
  EXPECT_EQ(abort_of(download(0x2001, 0, 501, 2)), kAbortValueTooHigh);
  EXPECT_EQ(abort_of(download(0x2001, 0, 0xFE0B, 2)), kAbortValueTooLow);  // -501
  EXPECT_EQ(abort_of(download(0x2004, 0, 9, 1)), kAbortValueRange);
  EXPECT_EQ(abort_of(download(0x2004, 0, 10, 1)), 0u);
  // Nothing was written by the refused requests.
  EXPECT_EQ(od.get(0x2001, 0), 0);
  EXPECT_EQ(od.get(0x1018, 1), 0x1234);
}

TEST_F(SdoServerTest, UnsupportedOrMalformedRequestsAreAbortedWith0x05040001) {
  for (std::uint8_t command : {0x21, 0x00, 0x60, 0xA0, 0xC0, 0xE0}) {
    const SdoServerResult r = server.handle(raw_request({command, 0x02, 0x20, 0x00, 0, 0, 0, 0}));
    EXPECT_EQ(abort_of(r), kAbortCommandSpecifier) << std::hex << int(command);
    EXPECT_FALSE(r.status.ok());
    EXPECT_EQ(r.response.data[1], 0x02);
    EXPECT_EQ(r.response.data[2], 0x20);
  }
  const SdoServerResult short_frame = server.handle(raw_request({0x40, 0x02, 0x20, 0x00, 0, 0, 0, 0}, 4));
  EXPECT_EQ(abort_of(short_frame), kAbortCommandSpecifier);
  EXPECT_EQ(short_frame.status.error, Error::kWrongDlc);
  const SdoServerResult tiny = server.handle(raw_request({0x40, 0, 0, 0, 0, 0, 0, 0}, 0));
  EXPECT_EQ(abort_of(tiny), kAbortCommandSpecifier);
  EXPECT_EQ(od.get(0x2002, 0), 7);
}

TEST_F(SdoServerTest, OtherNodesFramesAndClientAbortsGetNoAnswer) {
  SdoServerResult r = server.handle(sdo_upload_request(NodeId(4), 0x1000, 0));
  EXPECT_FALSE(r.respond);
  EXPECT_EQ(r.status.error, Error::kWrongCobId);
  CanFrame rtr = sdo_upload_request(kDictionaryNode, 0x1000, 0);
  rtr.rtr = true;
  r = server.handle(rtr);
  EXPECT_FALSE(r.respond);
  EXPECT_EQ(r.status.error, Error::kRemoteFrame);
  r = server.handle(sdo_abort_request(kDictionaryNode, 0x1000, 0, kAbortTimeout));
  EXPECT_FALSE(r.respond);
  EXPECT_TRUE(r.status.ok());
  EXPECT_EQ(r.request.kind, SdoRequestKind::kAbort);
  EXPECT_EQ(r.request.abort_code, kAbortTimeout);
}

TEST_F(SdoServerTest, ClientAndServerRoundTrip) {
  SdoClient client(kDictionaryNode, 50);
  auto request = client.download(0x2001, 0, SdoData{to_raw(DataType::kI16, -123), 2}, 0);
  ASSERT_TRUE(request.ok());
  SdoServerResult answer = server.handle(request.value);
  EXPECT_EQ(client.on_frame(answer.response).kind, SdoClientEventKind::kDownloaded);
  request = client.upload(0x2001, 0, 1);
  answer = server.handle(request.value);
  const SdoClientEvent e = client.on_frame(answer.response);
  ASSERT_EQ(e.kind, SdoClientEventKind::kUploaded);
  EXPECT_EQ(from_raw(DataType::kI16, e.data.data), -123);
  request = client.upload(0x2000, 0, 2);
  EXPECT_EQ(client.on_frame(server.handle(request.value).response).abort_code, kAbortReadWriteOnly);
}

// ---- the CiA 402 drive's dictionary ---------------------------------------------------------------

class Cia402DictionaryTest : public ::testing::Test {
 protected:
  Cia402DictionaryTest() : od(make_cia402_dictionary(kDictionaryNode, config())), server(od, kDictionaryNode) {}

  static Cia402DictionaryConfig config() {
    Cia402DictionaryConfig c;
    c.rated_torque = 250000;  // 250 N in mN
    c.producer_heartbeat_ms = 50;
    c.vendor_id = 0xCAFE;
    return c;
  }

  std::uint32_t write(std::uint16_t index, std::uint8_t sub, std::uint32_t data, std::uint8_t size) {
    const SdoServerResult r = server.handle(sdo_download_request(kDictionaryNode, index, sub, data, size).value);
    return r.response.data[0] == kSdoAbort ? get_u32_le(r.response.data, 4) : 0;
  }

  ObjectDictionary od;
  SdoServer server;
};

TEST_F(Cia402DictionaryTest, HoldsTheObjectsWithTheirTypesAccessAndMapping) {
  struct Row {
    std::uint16_t index;
    std::uint8_t sub;
    DataType type;
    Access access;
    bool mappable;
  };
  const Row rows[] = {
      {0x1000, 0, DataType::kU32, Access::kConst, false}, {0x1001, 0, DataType::kU8, Access::kRo, false},
      {0x1016, 1, DataType::kU32, Access::kRw, false},    {0x1017, 0, DataType::kU16, Access::kRw, false},
      {0x1018, 1, DataType::kU32, Access::kRo, false},    {0x1018, 4, DataType::kU32, Access::kRo, false},
      {0x1400, 1, DataType::kU32, Access::kRw, false},    {0x1400, 2, DataType::kU8, Access::kRw, false},
      {0x1600, 0, DataType::kU8, Access::kRw, false},     {0x1600, 8, DataType::kU32, Access::kRw, false},
      {0x1800, 1, DataType::kU32, Access::kRw, false},    {0x1A00, 1, DataType::kU32, Access::kRw, false},
      {0x603F, 0, DataType::kU16, Access::kRo, false},    {0x6040, 0, DataType::kU16, Access::kRw, true},
      {0x6041, 0, DataType::kU16, Access::kRo, true},     {0x6060, 0, DataType::kI8, Access::kRw, false},
      {0x6061, 0, DataType::kI8, Access::kRo, false},     {0x6064, 0, DataType::kI32, Access::kRo, true},
      {0x606C, 0, DataType::kI32, Access::kRo, true},     {0x6071, 0, DataType::kI16, Access::kRw, true},
      {0x6076, 0, DataType::kU32, Access::kRo, false},    {0x6077, 0, DataType::kI16, Access::kRo, true},
      {0x60C2, 1, DataType::kU8, Access::kRw, false},     {0x60C2, 2, DataType::kI8, Access::kRw, false},
  };
  for (const Row& row : rows) {
    const Entry* e = od.find(row.index, row.sub);
    ASSERT_NE(e, nullptr) << std::hex << row.index << " " << int(row.sub);
    EXPECT_EQ(e->type, row.type) << std::hex << row.index;
    EXPECT_EQ(e->access, row.access) << std::hex << row.index;
    EXPECT_EQ(e->pdo_mappable, row.mappable) << std::hex << row.index;
  }
  EXPECT_EQ(od.get(0x1000, 0), 0x00020192);
  EXPECT_EQ(od.get(0x1017, 0), 50);
  EXPECT_EQ(od.get(0x1018, 1), 0xCAFE);
  EXPECT_EQ(od.get(0x6076, 0), 250000);
  EXPECT_EQ(od.get(0x60C2, 1), 1);
  EXPECT_EQ(od.get(0x60C2, 2), -3);
  EXPECT_EQ(od.get(0x1400, 1), 0x203);
  EXPECT_EQ(od.get(0x1400, 2), 1);
  EXPECT_EQ(od.get(0x1800, 1), 0x183);
  EXPECT_EQ(od.get(0x1600, 1), 0x60400010);
  EXPECT_EQ(od.get(0x1600, 2), 0x60710010);
  EXPECT_EQ(od.get(0x1A00, 3), 0x60640020);
  EXPECT_LE(od.size(), od.capacity());
  EXPECT_EQ(od.capacity(), kCia402DictionaryCapacity);
}

TEST_F(Cia402DictionaryTest, OnlyCyclicSynchronousTorqueModeIsAccepted) {
  EXPECT_EQ(write(0x6060, 0, 10, 1), 0u);
  EXPECT_EQ(od.get(0x6060, 0), 10);
  EXPECT_EQ(write(0x6060, 0, 8, 1), kAbortValueRange);  // cyclic synchronous position
  EXPECT_EQ(write(0x6060, 0, 9, 1), kAbortValueRange);  // cyclic synchronous velocity
  EXPECT_EQ(write(0x6060, 0, 0xFF, 1), kAbortValueRange);
  EXPECT_EQ(write(0x6061, 0, 10, 1), kAbortWriteReadOnly);
  EXPECT_EQ(write(0x6041, 0, 0, 2), kAbortWriteReadOnly);
  EXPECT_EQ(write(0x6076, 0, 1, 4), kAbortWriteReadOnly);
  EXPECT_EQ(write(0x6071, 0, 0x01F4, 2), 0u);
  EXPECT_EQ(od.get(0x6071, 0), 500);
  EXPECT_EQ(write(0x6071, 0, 1, 4), kAbortLengthMismatch);
  EXPECT_EQ(write(0x60C2, 2, 0xF9, 1), kAbortValueTooLow);  // -7
  EXPECT_EQ(write(0x60C2, 1, 0, 1), kAbortValueTooLow);
}

TEST_F(Cia402DictionaryTest, HeartbeatObjects) {
  EXPECT_EQ(write(0x1017, 0, 100, 2), 0u);
  EXPECT_EQ(write(0x1016, 1, consumer_heartbeat_entry(1, 200), 4), 0u);
  EXPECT_EQ(write(0x1016, 1, 0x01000000u | consumer_heartbeat_entry(1, 200), 4), kAbortValueRange);
  EXPECT_EQ(write(0x1016, 1, consumer_heartbeat_entry(200, 200), 4), kAbortValueRange);
  EXPECT_EQ(write(0x1016, 2, 0, 4), kAbortSubindexMissing);
}

TEST_F(Cia402DictionaryTest, PdoCommunicationChecks) {
  EXPECT_EQ(write(0x1400, 1, 0x204, 4), kAbortValueRange);  // a valid PDO's id may not change
  EXPECT_EQ(write(0x1400, 1, kPdoCobIdInvalid | 0x203, 4), 0u);
  EXPECT_EQ(write(0x1400, 1, 0x204, 4), 0u);  // from invalid to valid with a new id
  EXPECT_EQ(write(0x1400, 1, kPdoCobIdInvalid | 0x204, 4), 0u);
  EXPECT_EQ(write(0x1400, 1, 0x605, 4), kAbortValueRange);  // restricted (SDO rx)
  EXPECT_EQ(write(0x1400, 1, 0x005, 4), kAbortValueRange);  // restricted (NMT range)
  EXPECT_EQ(write(0x1400, 1, kPdoCobIdExtended | 0x203, 4), kAbortValueRange);
  EXPECT_EQ(write(0x1400, 2, 241, 1), kAbortValueRange);
  EXPECT_EQ(write(0x1400, 2, 0, 1), 0u);
  EXPECT_EQ(write(0x1800, 2, 0, 1), kAbortValueRange);
  EXPECT_EQ(write(0x1800, 2, 255, 1), kAbortValueRange);
  EXPECT_EQ(write(0x1800, 2, 2, 1), 0u);
  EXPECT_EQ(write(0x1800, 0, 5, 1), kAbortWriteReadOnly);
}

TEST_F(Cia402DictionaryTest, PdoMappingFollowsTheCia301Procedure) {
  // While the PDO is valid, the mapping cannot change.
  EXPECT_EQ(write(0x1A00, 0, 0, 1), kAbortDeviceState);
  EXPECT_EQ(write(0x1A00, 4, 0x606C0020, 4), kAbortDeviceState);
  // 1. invalidate, 2. sub 0 = 0, 3. entries, 4. sub 0 = n, 5. valid again.
  EXPECT_EQ(write(0x1800, 1, kPdoCobIdInvalid | 0x183, 4), 0u);
  EXPECT_EQ(write(0x1A00, 4, 0x606C0020, 4), kAbortDeviceState);  // sub 0 still 3
  EXPECT_EQ(write(0x1A00, 0, 0, 1), 0u);
  EXPECT_EQ(write(0x1A00, 1, 0x60410010, 4), 0u);
  EXPECT_EQ(write(0x1A00, 2, 0x606C0020, 4), 0u);
  EXPECT_EQ(write(0x1A00, 3, 0x60770010, 4), 0u);
  EXPECT_EQ(write(0x1A00, 0, 3, 1), 0u);
  EXPECT_EQ(write(0x1800, 1, 0x183, 4), 0u);
  const auto map = read_pdo_map(od, 0x1A00);
  ASSERT_TRUE(map.ok()) << map.detail;
  EXPECT_EQ(map.value.size(), 3u);
  EXPECT_EQ(map.value[1], (PdoMapEntry{0x606C, 0, 32}));
}

TEST_F(Cia402DictionaryTest, InvalidMappingsAreRefusedWithTheirAbortCode) {
  EXPECT_EQ(write(0x1A00 - 0x200, 1, kPdoCobIdInvalid | 0x183, 4), 0u);
  EXPECT_EQ(write(0x1A00, 0, 0, 1), 0u);
  EXPECT_EQ(write(0x1A00, 1, 0x60600008, 4), 0u);  // modes of operation: not mappable
  EXPECT_EQ(write(0x1A00, 0, 1, 1), kAbortNotMappable);
  EXPECT_EQ(write(0x1A00, 1, 0x70000010, 4), 0u);
  EXPECT_EQ(write(0x1A00, 0, 1, 1), kAbortObjectMissing);
  EXPECT_EQ(write(0x1A00, 1, 0x60410110, 4), 0u);
  EXPECT_EQ(write(0x1A00, 0, 1, 1), kAbortSubindexMissing);
  EXPECT_EQ(write(0x1A00, 1, 0x60410020, 4), 0u);  // 32 bits of a 16-bit object
  EXPECT_EQ(write(0x1A00, 0, 1, 1), kAbortNotMappable);
  for (std::uint8_t sub = 1; sub <= 3; ++sub) EXPECT_EQ(write(0x1A00, sub, 0x60640020, 4), 0u);
  EXPECT_EQ(write(0x1A00, 0, 3, 1), kAbortPdoLength);  // 96 bits
  EXPECT_EQ(write(0x1A00, 0, 9, 1), kAbortValueTooHigh);
  EXPECT_EQ(od.get(0x1A00, 0), 0);
  // RPDO: a read-only object cannot be received.
  EXPECT_EQ(write(0x1400, 1, kPdoCobIdInvalid | 0x203, 4), 0u);
  EXPECT_EQ(write(0x1600, 0, 0, 1), 0u);
  EXPECT_EQ(write(0x1600, 1, 0x60410010, 4), 0u);
  EXPECT_EQ(write(0x1600, 0, 1, 1), kAbortNotMappable);
}

TEST(Cia402DictionaryConfigTest, BadValuesThrowNamingTheField) {
  Cia402DictionaryConfig c;
  c.rated_torque = 0;
  try {
    make_cia402_dictionary(NodeId(1), c);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "rated_torque: must be >= 1, got 0");
  }
  c.rated_torque = 1;
  c.interpolation_period_ms = 0;
  EXPECT_THROW(make_cia402_dictionary(NodeId(1), c), std::invalid_argument);
}

}  // namespace

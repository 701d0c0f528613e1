// SYNC (with and without counter) and EMCY coding.
#include <gtest/gtest.h>

#include <stdexcept>

#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/canopen/sync.hpp"

namespace {

using namespace pmlsm::canopen;

TEST(SyncTest, WithoutCounterIsDlc0) {
  const CanFrame f = encode_sync();
  EXPECT_EQ(f.id, 0x080u);
  EXPECT_EQ(f.dlc, 0);
  const auto r = decode_sync(f);
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r.value.counter.has_value());
}

TEST(SyncTest, CounterOneTo240) {
  for (int c = 1; c <= 240; ++c) {
    const auto f = encode_sync(static_cast<std::uint8_t>(c));
    ASSERT_TRUE(f.ok());
    EXPECT_EQ(f.value.dlc, 1);
    EXPECT_EQ(f.value.data[0], c);
    const auto r = decode_sync(f.value);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(*r.value.counter, c);
  }
  EXPECT_EQ(encode_sync(std::uint8_t{0}).error, Error::kInvalidValue);
  EXPECT_EQ(encode_sync(std::uint8_t{241}).error, Error::kInvalidValue);
}

TEST(SyncTest, MalformedFramesGiveErrors) {
  CanFrame f = encode_sync(std::uint8_t{3}).value;
  f.data[0] = 0;
  EXPECT_EQ(decode_sync(f).error, Error::kInvalidValue);
  f.data[0] = 241;
  EXPECT_EQ(decode_sync(f).error, Error::kInvalidValue);
  f.data[0] = 1;
  f.dlc = 2;
  EXPECT_EQ(decode_sync(f).error, Error::kWrongDlc);
  EXPECT_STREQ(decode_sync(f).detail, "SYNC: DLC must be 0 or 1");
  f.dlc = 1;
  f.id = 0x081;
  EXPECT_EQ(decode_sync(f).error, Error::kWrongCobId);
}

TEST(SyncTest, ProducerWrapsAtTheOverflowValue) {
  SyncProducer plain;
  EXPECT_EQ(plain.next().dlc, 0);
  SyncProducer counted(3);
  const int expected[] = {1, 2, 3, 1, 2, 3, 1};
  for (int e : expected) {
    const CanFrame f = counted.next();
    EXPECT_EQ(f.dlc, 1);
    EXPECT_EQ(f.data[0], e);
  }
  counted.reset();
  EXPECT_EQ(counted.next().data[0], 1);
  SyncProducer full(240);
  for (int i = 1; i <= 240; ++i) EXPECT_EQ(full.next().data[0], i);
  EXPECT_EQ(full.next().data[0], 1);
  EXPECT_THROW(SyncProducer(1), std::invalid_argument);
  EXPECT_THROW(SyncProducer(241), std::invalid_argument);
}

TEST(EmcyTest, LayoutIsCodeLeRegisterManufacturer) {
  EmcyMessage m;
  m.error_code = kEmcyContinuousOverCurrent;
  m.error_register = kErrorRegisterGeneric | kErrorRegisterCurrent;
  m.manufacturer = {0xA1, 0xA2, 0xA3, 0xA4, 0xA5};
  const CanFrame f = encode_emcy(NodeId(0x12), m);
  EXPECT_EQ(f.id, 0x092u);
  EXPECT_EQ(f.dlc, 8);
  const std::array<std::uint8_t, 8> expected{0x10, 0x23, 0x03, 0xA1, 0xA2, 0xA3, 0xA4, 0xA5};
  EXPECT_EQ(f.data, expected);
  const auto r = decode_emcy(f);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.value.node_id, 0x12);
  EXPECT_EQ(r.value.error_code, 0x2310);
  EXPECT_EQ(r.value.error_register, 0x03);
  EXPECT_EQ(r.value.manufacturer, m.manufacturer);
}

TEST(EmcyTest, StandardCodes) {
  EXPECT_EQ(kEmcyNoError, 0x0000);
  EXPECT_EQ(kEmcyGeneric, 0x1000);
  EXPECT_EQ(kEmcyContinuousOverCurrent, 0x2310);
  EXPECT_EQ(kEmcyDcLinkOverVoltage, 0x3210);
  EXPECT_EQ(kEmcyExcessTemperature, 0x4210);
  EXPECT_EQ(kEmcyDeviceHardware, 0x5000);
  EXPECT_EQ(kEmcyParameterError, 0x6320);
  EXPECT_EQ(kEmcyCanOverrun, 0x8110);
  EXPECT_EQ(kEmcyHeartbeatError, 0x8130);
  EXPECT_EQ(kEmcyFollowingError, 0x8611);
  EXPECT_EQ(kEmcyManufacturerFirst, 0xFF00);
  EXPECT_STREQ(describe_emcy(0x0000), "error reset or no error");
  EXPECT_STREQ(describe_emcy(0x8130), "life guard error or heartbeat error");
  EXPECT_STREQ(describe_emcy(0x2311), "current");
  EXPECT_STREQ(describe_emcy(0xFF42), "device specific");
  EXPECT_STREQ(describe_emcy(0xF001), "additional functions");
  EXPECT_STREQ(describe_emcy(0xA000), "unknown error code");
}

TEST(EmcyTest, MalformedFramesGiveErrors) {
  CanFrame f = encode_emcy(NodeId(1), EmcyMessage{});
  f.dlc = 7;
  EXPECT_EQ(decode_emcy(f).error, Error::kWrongDlc);
  f.dlc = 8;
  f.id = 0x080;  // SYNC
  EXPECT_EQ(decode_emcy(f).error, Error::kWrongCobId);
  f.id = 0x181;
  EXPECT_EQ(decode_emcy(f).error, Error::kWrongCobId);
}

}  // namespace

// EtherCAT frames and datagrams (pmlsm/ethercat/frame.hpp) against ETG.1000.4's layout: the bytes
// of a known frame, every command through the builder and the parser, the working counter's
// rules, a full frame, and every malformed frame refused by name.
#include "pmlsm/ethercat/frame.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace pmlsm::ethercat {
namespace {

std::vector<std::uint8_t> as_vector(Bytes b) { return {b.data, b.data + b.size}; }

TEST(EtherCatFrame, ABroadcastReadIsTheBytesTheStandardLaysOut) {
  FrameBuilder frame(MacAddress{0x02, 0x11, 0x22, 0x33, 0x44, 0x55});
  ASSERT_TRUE(frame.add(Command::kBrd, 0x2A, physical_address(0x0000, 0x0130), nullptr, 2));
  const std::vector<std::uint8_t> bytes = as_vector(frame.ethernet());
  ASSERT_EQ(bytes.size(), kMinEthernetFrameBytes);                             // 14 + 2 + 10 + 2 + 2 = 30, padded
  const std::vector<std::uint8_t> head = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF,  // to everyone
                                          0x02, 0x11, 0x22, 0x33, 0x44, 0x55,  // from the master
                                          0x88, 0xA4,                          // EtherType, big-endian
                                          0x0E, 0x10,                          // 14 bytes of datagrams, type 1
                                          0x07, 0x2A,                          // BRD, index
                                          0x00, 0x00, 0x30, 0x01,              // ADP 0, ADO 0x0130 (AL status)
                                          0x02, 0x00,                          // 2 bytes, last datagram
                                          0x00, 0x00,                          // IRQ
                                          0x00, 0x00,                          // data
                                          0x00, 0x00};                         // working counter
  EXPECT_EQ(std::vector<std::uint8_t>(bytes.begin(), bytes.begin() + 30), head);
  for (std::size_t i = 30; i < bytes.size(); ++i) EXPECT_EQ(bytes[i], 0) << "padding at " << i;
  const Bytes udp = frame.udp_payload();
  EXPECT_EQ(std::vector<std::uint8_t>(udp.data, udp.data + udp.size),
            std::vector<std::uint8_t>(head.begin() + 14, head.end()));
}

TEST(EtherCatFrame, EveryCommandCrossesTheBuilderAndTheParserFieldByField) {
  FrameBuilder frame;
  std::vector<std::uint8_t> data(40);
  for (std::uint8_t c = 0; c < kCommandCount; ++c) {
    for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<std::uint8_t>(c * 7 + i);
    const auto command = static_cast<Command>(c);
    const std::uint32_t address =
        is_logical(command) ? 0x00010000U + c * 0x100U : physical_address(auto_increment_adp(c), 0x0900 + c);
    ASSERT_TRUE(frame.add(command, c, address, data.data(), static_cast<std::uint16_t>(c + 1),
                          static_cast<std::uint16_t>(c * 3), static_cast<std::uint16_t>(c)));
  }
  ParsedFrame parsed;
  const Bytes bytes = frame.ethernet();
  ASSERT_EQ(parse_ethernet_frame(bytes.data, bytes.size, parsed), FrameError::kNone);
  EXPECT_EQ(parsed.source, kDefaultMasterMac);
  EXPECT_EQ(parsed.destination, kBroadcastMac);
  ASSERT_EQ(parsed.count, kCommandCount);
  for (std::uint8_t c = 0; c < kCommandCount; ++c) {
    const DatagramView& d = parsed.datagrams[c];
    EXPECT_EQ(d.header.command, static_cast<Command>(c));
    EXPECT_EQ(d.header.index, c);
    EXPECT_EQ(d.header.length, c + 1);
    EXPECT_EQ(d.header.more, c + 1 < kCommandCount) << "the more bit on all but the last";
    EXPECT_EQ(d.header.irq, c);
    EXPECT_EQ(d.working_counter, c * 3);
    if (!is_logical(d.header.command)) {
      EXPECT_EQ(d.header.adp(), auto_increment_adp(c));
      EXPECT_EQ(d.header.ado(), 0x0900 + c);
    }
    for (std::uint16_t i = 0; i < d.header.length; ++i) EXPECT_EQ(d.data[i], static_cast<std::uint8_t>(c * 7 + i));
  }
  // The UDP payload parses to the same datagrams.
  ParsedFrame from_udp;
  const Bytes udp = frame.udp_payload();
  ASSERT_EQ(parse_ethercat_frame(udp.data, udp.size, from_udp), FrameError::kNone);
  EXPECT_EQ(from_udp.count, parsed.count);
}

TEST(EtherCatFrame, WorkingCountersCountReadsAndWritesAsTheStandardDoes) {
  EXPECT_EQ(expected_working_counter(Command::kBrd, 5), 5);
  EXPECT_EQ(expected_working_counter(Command::kFpwr, 1), 1);
  EXPECT_EQ(expected_working_counter(Command::kLrw, 2), 6);  // each slave: 1 read + 2 written
  EXPECT_EQ(expected_working_counter(Command::kAprw, 1), 3);
  EXPECT_EQ(expected_working_counter(Command::kFrmw, 4), 4);
  EXPECT_EQ(expected_working_counter(Command::kNop, 4), 0);
  EXPECT_STREQ(to_string(Command::kArmw), "ARMW");
  EXPECT_STREQ(to_string(static_cast<Command>(15)), "?");
  EXPECT_TRUE(is_auto_increment(Command::kArmw));
  EXPECT_FALSE(is_auto_increment(Command::kFrmw));
  EXPECT_EQ(auto_increment_adp(0), 0);
  EXPECT_EQ(auto_increment_adp(1), 0xFFFF);
}

TEST(EtherCatFrame, AFullFrameTakesWhatFitsAndRefusesTheRest) {
  FrameBuilder frame;
  ASSERT_TRUE(frame.add(Command::kLrw, 0, 0, nullptr, static_cast<std::uint16_t>(kMaxDatagramDataBytes)));
  EXPECT_EQ(frame.ethernet().size, kMaxEthernetFrameBytes);
  EXPECT_FALSE(frame.add(Command::kNop, 1, 0, nullptr, 0));
  EXPECT_EQ(frame.datagram_count(), 1u);
  frame.clear();
  EXPECT_FALSE(frame.add(Command::kLrw, 0, 0, nullptr, static_cast<std::uint16_t>(kMaxDatagramDataBytes + 1)));
  EXPECT_EQ(frame.datagram_count(), 0u);
  for (std::size_t i = 0; i < kMaxDatagramsPerFrame; ++i) ASSERT_TRUE(frame.add(Command::kNop, 0, 0, nullptr, 0));
  EXPECT_FALSE(frame.add(Command::kNop, 0, 0, nullptr, 0));
  // Cleared, a short frame's padding is zero again.
  frame.clear();
  ASSERT_TRUE(frame.add(Command::kBrd, 0, 0, nullptr, 1));
  const Bytes b = frame.ethernet();
  for (std::size_t i = kEthernetHeaderBytes + 2 + 13; i < b.size; ++i) EXPECT_EQ(b.data[i], 0) << i;
}

/// A two-datagram frame to break.
std::vector<std::uint8_t> two_datagrams() {
  FrameBuilder frame;
  const std::uint8_t data[4] = {1, 2, 3, 4};
  frame.add(Command::kFprd, 1, physical_address(0x1001, 0x0130), data, 2);
  frame.add(Command::kLrw, 2, 0x10000, data, 4);
  return as_vector(frame.ethernet());
}

FrameError parse(const std::vector<std::uint8_t>& bytes) {
  ParsedFrame parsed;
  return parse_ethernet_frame(bytes.data(), bytes.size(), parsed);
}

TEST(EtherCatFrame, EveryMalformedFrameIsRefusedByName) {
  std::vector<std::uint8_t> f = two_datagrams();
  ASSERT_EQ(parse(f), FrameError::kNone);
  EXPECT_EQ(parse({f.begin(), f.begin() + 15}), FrameError::kShort);
  f = two_datagrams();
  f[13] = 0x00;  // IPv4's 0x0800 would be 0x08 0x00
  EXPECT_EQ(parse(f), FrameError::kNotEtherCat);
  f = two_datagrams();
  f[15] = 0x50;  // type 5
  EXPECT_EQ(parse(f), FrameError::kNotDatagrams);
  f = two_datagrams();
  f[14] = 0xFF, f[15] = 0x17;  // 2047 bytes of datagrams in a 60-byte frame
  EXPECT_EQ(parse(f), FrameError::kLengthBeyondFrame);
  f = two_datagrams();
  f[14] = 0x00, f[15] = 0x10;
  EXPECT_EQ(parse(f), FrameError::kNoDatagram);
  f = two_datagrams();
  f[16] = 15;  // the first datagram's command
  EXPECT_EQ(parse(f), FrameError::kUnknownCommand);
  f = two_datagrams();
  f[22] = 0x40;  // the first datagram's length: 64 bytes, past the frame's 32
  EXPECT_EQ(parse(f), FrameError::kDatagramBeyondFrame);
  f = two_datagrams();
  f[23] &= 0x7F;  // the first datagram says it is the last; the second follows
  EXPECT_EQ(parse(f), FrameError::kBytesAfterLast);
  {
    // One odd datagram (BWR of 1 byte: 13 bytes) in a length rounded up to 14, as TwinCAT sends:
    // read, the pad byte ignored; rounded to 15 or 16 it is refused.
    FrameBuilder b;
    const std::uint8_t one = 0;
    b.add(Command::kBwr, 0x40, physical_address(0, 0x0101), &one, 1);
    std::vector<std::uint8_t> odd = as_vector(b.ethernet());  // padded to 60 bytes
    ASSERT_EQ(odd[14], 13);
    odd[14] = 14;
    EXPECT_EQ(parse(odd), FrameError::kNone);
    odd[14] = 16;
    EXPECT_EQ(parse(odd), FrameError::kBytesAfterLast);
  }
  f = two_datagrams();
  f[14] = 14;  // the length ends after the first datagram, whose more bit is set
  EXPECT_EQ(parse(f), FrameError::kMoreWithoutNext);
  for (FrameError e : {FrameError::kShort, FrameError::kTooManyDatagrams, FrameError::kBytesAfterLast}) {
    EXPECT_STRNE(to_string(e), "?");
  }
}

}  // namespace
}  // namespace pmlsm::ethercat

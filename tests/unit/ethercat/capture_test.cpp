// pcapng read back (what --capture writes, either byte order, several interfaces and their
// timestamp resolutions; every malformed block named) and a capture decoded: the CoE SDO
// messages in a session of our master with the virtual slave, as the master saw them.
#include <gtest/gtest.h>

#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "coe_slave.hpp"
#include "pmlsm/ethercat/capture.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/ethercat/master.hpp"
#include "pmlsm/ethercat/pcapng.hpp"
#include "pmlsm/ethercat/sii.hpp"

namespace pmlsm::ethercat {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("pmlsm_capture_" + std::to_string(getpid()));
  fs::create_directories(dir);
  return dir / name;
}

void write_bytes(const fs::path& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

std::vector<std::uint8_t> read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Appends `value` in big-endian order (a capture written on a big-endian host).
void be32(std::vector<std::uint8_t>& out, std::uint32_t value) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<std::uint8_t>(value >> shift));
}
void be16(std::vector<std::uint8_t>& out, std::uint16_t value) {
  out.push_back(static_cast<std::uint8_t>(value >> 8));
  out.push_back(static_cast<std::uint8_t>(value));
}

TEST(Pcapng, WhatTheWriterWritesIsReadBackFrameByFrame) {
  const fs::path path = scratch("round_trip.pcapng");
  std::vector<std::vector<std::uint8_t>> sent;
  {
    PcapngWriter writer(path.string());
    for (int i = 0; i < 3; ++i) {
      FrameBuilder frame;
      const std::uint8_t data[3] = {static_cast<std::uint8_t>(i), 2, 3};
      frame.add(Command::kFprd, static_cast<std::uint8_t>(i), physical_address(0x1001, 0x0130), data,
                static_cast<std::uint16_t>(1 + i));
      const Bytes bytes = frame.ethernet();
      sent.emplace_back(bytes.data, bytes.data + bytes.size);
      writer.write(bytes, 1'700'000'000'123'456'789LL + i * 1000);
    }
    writer.flush();
  }
  PcapngReader reader(path.string());
  CapturedFrame frame;
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(reader.next(frame)) << i;
    EXPECT_EQ(frame.number, static_cast<std::uint64_t>(i + 1));
    EXPECT_EQ(frame.link_type, kLinkTypeEthernet);
    EXPECT_EQ(frame.time_ns, 1'700'000'000'123'456'789LL + i * 1000) << "nanoseconds kept";
    EXPECT_EQ(std::vector<std::uint8_t>(frame.data.data, frame.data.data + frame.data.size), sent[i]);
    EXPECT_EQ(frame.original_bytes, sent[i].size());
  }
  EXPECT_FALSE(reader.next(frame));
  EXPECT_FALSE(reader.next(frame)) << "the end stays the end";
  fs::remove_all(path.parent_path());
}

TEST(Pcapng, ABigEndianSectionWithMicrosecondTimestampsIsRead) {
  // Section header, an interface without if_tsresol (microseconds), one enhanced packet.
  std::vector<std::uint8_t> file;
  be32(file, 0x0A0D0D0A), be32(file, 28), be32(file, 0x1A2B3C4D), be16(file, 1), be16(file, 0);
  be32(file, 0xFFFFFFFF), be32(file, 0xFFFFFFFF), be32(file, 28);
  be32(file, 1), be32(file, 20), be16(file, kLinkTypeEthernet), be16(file, 0), be32(file, 0), be32(file, 20);
  const std::uint64_t micros = 1'700'000'000'000'001ULL;
  be32(file, 6), be32(file, 36), be32(file, 0), be32(file, static_cast<std::uint32_t>(micros >> 32));
  be32(file, static_cast<std::uint32_t>(micros)), be32(file, 3), be32(file, 60);
  file.insert(file.end(), {0xAA, 0xBB, 0xCC, 0x00});
  be32(file, 36);
  const fs::path path = scratch("big_endian.pcapng");
  write_bytes(path, file);
  PcapngReader reader(path.string());
  CapturedFrame frame;
  ASSERT_TRUE(reader.next(frame));
  EXPECT_EQ(frame.time_ns, static_cast<std::int64_t>(micros * 1000));
  EXPECT_EQ(frame.data.size, 3u);
  EXPECT_EQ(frame.original_bytes, 60u) << "cut at capture: what was on the wire is kept apart";
  EXPECT_EQ(frame.data.data[0], 0xAA);
  EXPECT_FALSE(reader.next(frame));
  fs::remove_all(path.parent_path());
}

TEST(Pcapng, EveryMalformedFileIsRefusedNamingWhereAndWhy) {
  const fs::path good = scratch("good.pcapng");
  {
    PcapngWriter writer(good.string());
    FrameBuilder frame;
    frame.add(Command::kBrd, 0, 0, nullptr, 2);
    writer.write(frame.ethernet(), 0);
  }
  const std::vector<std::uint8_t> bytes = read_bytes(good);
  const auto refused = [&](std::vector<std::uint8_t> variant, const std::string& expected) {
    const fs::path path = scratch("bad.pcapng");
    write_bytes(path, variant);
    try {
      PcapngReader reader(path.string());
      CapturedFrame frame;
      while (reader.next(frame)) {
      }
      ADD_FAILURE() << "read without complaint; expected: " << expected;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
    }
  };
  refused({'n', 'o', 't', ' ', 'a', ' ', 'c', 'a', 'p', 't', 'u', 'r', 'e'}, "not a pcapng capture");
  std::vector<std::uint8_t> cut(bytes.begin(), bytes.end() - 10);
  refused(cut, "malformed block at byte 60: a block length of");  // the packet block after 28 + 32 bytes
  std::vector<std::uint8_t> trailing = bytes;
  trailing[bytes.size() - 4] ^= 0x04;
  refused(trailing, "its trailing length differs");
  std::vector<std::uint8_t> no_interface = bytes;
  no_interface[68] = 7;  // the packet's interface id
  refused(no_interface, "a packet on interface 7, which no block described");
  std::vector<std::uint8_t> no_magic = bytes;
  no_magic[8] = 0;
  refused(no_magic, "without the byte-order magic");
  std::vector<std::uint8_t> half_header = bytes;
  half_header.insert(half_header.end(), {6, 0, 0, 0, 40, 0});
  refused(half_header, "the file ends inside a block header");
  fs::remove_all(good.parent_path());
}

TEST(CaptureDecode, OurMastersSdoSessionIsDecodedAsTheMasterSawIt) {
  // The master reads and writes objects of the virtual CiA 402 slave through its mailboxes, with
  // a capture on; the capture, decoded, holds each request and each answer in turn.
  test::CoeSlave slave;
  VirtualSegment segment({&slave.esc});
  VirtualSegmentLink link(segment);
  const fs::path path = scratch("session.pcapng");
  {
    PcapngWriter writer(path.string());
    Master master(link);
    master.capture_to(&writer);
    master.assign_station_addresses(1);
    const SlaveInfo info = master.read_slave_info(0x1001);
    master.configure_mailbox(info);
    ASSERT_TRUE(master.request_state(0x1001, AlState::kPreOp).reached);
    ASSERT_TRUE(master.sdo_upload(info, 0x1000, 0).done);
    ASSERT_TRUE(master.sdo_download(info, 0x6060, 0, 10, 1).done);
    ASSERT_FALSE(master.sdo_upload(info, 0x2FFF, 0).done);  // no such object: an abort
    writer.flush();
  }
  PcapngReader reader(path.string());
  const CaptureDecode d = decode_capture(reader);
  EXPECT_EQ(d.malformed_frames, 0u);
  EXPECT_EQ(d.other_frames, 0u);
  EXPECT_EQ(d.ethercat_frames, d.frames);
  ASSERT_EQ(d.sdos.size(), 6u);
  EXPECT_EQ(describe(d.sdos[0].seen), "upload request 0x1000:00");
  EXPECT_EQ(describe(d.sdos[1].seen), "upload response 0x1000:00 = 0x20192 (4 bytes)");
  EXPECT_EQ(describe(d.sdos[2].seen), "download request 0x6060:00 = 0xA (1 byte)");
  EXPECT_EQ(describe(d.sdos[3].seen), "download response 0x6060:00");
  EXPECT_EQ(describe(d.sdos[4].seen), "upload request 0x2FFF:00");
  EXPECT_NE(describe(d.sdos[5].seen).find("abort 0x2FFF:00: 0x06020000"), std::string::npos)
      << describe(d.sdos[5].seen);
  for (const auto& s : d.sdos) EXPECT_EQ(s.seen.station, 0x1001);
  std::uint16_t index = 0;
  std::uint8_t subindex = 0;
  std::uint32_t value = 0;
  std::uint8_t size = 0;
  ASSERT_TRUE(upload_value(d.sdos[1].seen, index, subindex, value, size));
  EXPECT_EQ(index, 0x1000);
  EXPECT_EQ(value, 0x00020192U);
  EXPECT_EQ(size, 4);
  EXPECT_FALSE(upload_value(d.sdos[0].seen, index, subindex, value, size)) << "a request holds no value";
  fs::remove_all(path.parent_path());
}

TEST(CaptureReplay, SoemsSiiReadsOfARealAkdAreAnsweredAsTheAkdAnsweredThem) {
  // SOEM's frames to a Kollmorgen AKD, as captured, sent again to a virtual slave holding the
  // AKD's SII image: every EEPROM read the AKD answered (its data register, 0x0508, counted) is
  // answered with the same bytes and working counter, and the drive ends in the AL status the AKD
  // reported last.
  const fs::path dir = fs::path(PMLSM_SOURCE_DIR) / ".." / "shared" / "ethercat" / "captures";
  if (!fs::exists(dir / "akd.hex")) GTEST_SKIP() << "no " << dir << " (the shared EtherCAT captures)";
  VirtualCia402Slave drive(read_sii_image((dir / "akd.hex").string()));
  Esc& akd = drive.esc();
  VirtualSegment segment({&akd});
  VirtualSegmentLink link(segment);
  PcapngReader reader((dir / "soem-sdinfo-akd.pcapng").string());
  CapturedFrame frame;
  std::array<std::uint8_t, kMaxEthernetFrameBytes> ours{};
  std::size_t ours_size = 0;
  ParsedFrame theirs_parsed;
  ParsedFrame ours_parsed;
  int compared = 0;
  std::uint8_t last_al_status = 0;
  std::uint8_t our_last_al_status = 0;
  while (reader.next(frame)) {
    if (parse_ethernet_frame(frame.data.data, frame.data.size, theirs_parsed) != FrameError::kNone) continue;
    // The slaves set bit 1 of the source address on a frame's way back (SOEM sends from 01:01:...).
    if ((frame.data.data[6] & 0x02U) == 0) {
      ASSERT_TRUE(link.send(frame.data));
      ours_size = link.receive(ours.data(), 0);
      continue;
    }
    ASSERT_EQ(parse_ethernet_frame(ours.data(), ours_size, ours_parsed), FrameError::kNone) << "frame " << frame.number;
    ASSERT_EQ(ours_parsed.count, theirs_parsed.count) << "frame " << frame.number;
    for (std::size_t i = 0; i < theirs_parsed.count; ++i) {
      const DatagramView& theirs = theirs_parsed.datagrams[i];
      const DatagramView& mine = ours_parsed.datagrams[i];
      if (theirs.header.ado() == reg::kAlStatus && theirs.header.command == Command::kFprd &&
          theirs.working_counter == 1) {
        // The drive's own pace (it takes a while for PREOP): compared at the end.
        last_al_status = theirs.data[0];
        our_last_al_status = mine.data[0];
      }
      if (theirs.header.ado() != reg::kSiiData || theirs.working_counter != 1) continue;
      ++compared;
      EXPECT_EQ(mine.working_counter, theirs.working_counter) << "frame " << frame.number;
      EXPECT_EQ(std::vector<std::uint8_t>(mine.data, mine.data + mine.header.length),
                std::vector<std::uint8_t>(theirs.data, theirs.data + theirs.header.length))
          << "frame " << frame.number;
    }
  }
  EXPECT_GT(compared, 20) << "SOEM read the AKD's SII: its identity, mailboxes and categories";
  // SOEM's set-up replayed takes the virtual drive where it took the AKD: PREOP, SAFEOP refused
  // (the error indicator set: no process data was configured).
  EXPECT_EQ(our_last_al_status, last_al_status);
  EXPECT_EQ(last_al_status, static_cast<int>(AlState::kPreOp) | 0x10);
}

}  // namespace
}  // namespace pmlsm::ethercat

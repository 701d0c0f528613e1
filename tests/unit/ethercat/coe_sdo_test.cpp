// SDO over CoE beyond 4 bytes (mailbox.hpp): our master reads texts by normal upload, and by
// upload segments where the send mailbox does not hold them, at every boundary of the segmenting;
// the server answers the protocol's misuses (a segment without an upload, the wrong toggle, a
// segmented or over-long download) with CiA 301's abort codes; a record longer than the receive
// mailbox goes in download segments, each misuse of them aborted; the capture decoder names each
// message of such a transfer.
#include <gtest/gtest.h>

#include <unistd.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "coe_slave.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/pdo.hpp"
#include "pmlsm/ethercat/capture.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/ethercat/master.hpp"
#include "pmlsm/ethercat/pcapng.hpp"
#include "pmlsm/ethercat/sii.hpp"
#include "pmlsm/util/little_endian.hpp"

namespace pmlsm::ethercat {
namespace coe_sdo_test {

namespace fs = std::filesystem;

/// A master with one CoE slave in PREOP, its mailbox set.
struct Session {
  test::CoeSlave slave;
  VirtualSegment segment{{&slave.esc}};
  VirtualSegmentLink link{segment};
  Master master{link};
  SlaveInfo info;
  Session() : info(test::to_preop(master)) {}
};

/// `n` printable bytes that differ along the text (a shifted or dropped segment shows).
std::string text_of(std::size_t n) {
  std::string text;
  for (std::size_t i = 0; i < n; ++i) text.push_back(static_cast<char>('!' + (i * 7 + i / 94) % 94));
  return text;
}

TEST(CoeSdo, TheDeviceNameIsReadByANormalUploadInOneMessage) {
  Session s;
  const SdoResult r = s.master.sdo_upload(s.info, canopen::kObjectDeviceName, 0);
  ASSERT_TRUE(r.done) << r.describe();
  EXPECT_EQ(std::string(r.bytes.begin(), r.bytes.end()), "PMLSM CiA 402 drive");
  EXPECT_EQ(r.describe(), "\"PMLSM CiA 402 drive\" (19 bytes)");
  EXPECT_EQ(s.slave.coe.segments(), 0u);
  // The virtual drive names itself as its SII does.
  VirtualCia402Slave drive;
  const canopen::TextEntry* name = drive.dictionary().find_text(canopen::kObjectDeviceName, 0);
  ASSERT_NE(name, nullptr);
  EXPECT_EQ(name->text, "PMLSM virtual drive");
}

TEST(CoeSdo, ALongTextComesInSegmentsAtEveryBoundaryOfTheMailbox) {
  // A 128-byte send mailbox holds 112 bytes after a normal upload response's 16 and 119 in a
  // segment after its 9: each length on either side of those steps, and under 7 in the last.
  const std::size_t first = 128 - 16;
  const std::size_t segment = 128 - 9;
  for (const std::size_t length : {std::size_t{0}, std::size_t{4}, std::size_t{5}, first, first + 1, first + 7,
                                   first + 8, first + segment, first + segment + 3, std::size_t{1000}}) {
    Session s;
    s.slave.dictionary.add_text({0x2100, 1, "a long text", text_of(length)});
    const SdoResult r = s.master.sdo_upload(s.info, 0x2100, 1);
    ASSERT_TRUE(r.done) << length << ": " << r.describe();
    EXPECT_EQ(std::string(r.bytes.begin(), r.bytes.end()), text_of(length)) << length;
    const std::size_t segments = length <= first ? 0 : (length - first + segment - 1) / segment;
    EXPECT_EQ(s.slave.coe.segments(), segments) << length;
    // The next transfer starts clean: an expedited read after it.
    EXPECT_EQ(s.master.sdo_upload(s.info, canopen::kObjectDeviceType, 0).value, canopen::kDeviceTypeCia402Servo);
  }
}

TEST(CoeSdo, ATextIsReadOnlyUnmappableAndRefusedByTheExpeditedPath) {
  Session s;
  SdoResult r = s.master.sdo_download(s.info, canopen::kObjectDeviceName, 0, 0x41, 1);
  EXPECT_EQ(r.abort_code, canopen::kAbortWriteReadOnly) << r.describe();
  canopen::ObjectDictionary& d = s.slave.dictionary;
  EXPECT_EQ(d.locate(canopen::kObjectDeviceName, 0), canopen::kAbortNone);
  EXPECT_EQ(d.locate(canopen::kObjectDeviceName, 1), canopen::kAbortSubindexMissing);
  EXPECT_EQ(d.read(canopen::kObjectDeviceName, 0).abort_code, canopen::kAbortUnsupportedAccess);
  EXPECT_EQ(d.set(canopen::kObjectDeviceName, 0, 1).abort_code, canopen::kAbortWriteReadOnly);
  EXPECT_THROW(d.add_text({canopen::kObjectDeviceName, 0, "again", "x"}), std::invalid_argument);
  EXPECT_THROW(d.add_text({canopen::kObjectDeviceType, 0, "over an entry", "x"}), std::invalid_argument);
  EXPECT_THROW(d.add_text({0x2100, 0, "", "no name"}), std::invalid_argument);
  canopen::Entry over_text;
  over_text.index = canopen::kObjectDeviceName;
  over_text.name = "over a text";
  EXPECT_THROW(d.add(over_text), std::invalid_argument);
  canopen::PdoMap map;
  ASSERT_EQ(map.add({canopen::kObjectDeviceName, 0, 32}), 0u);
  EXPECT_EQ(canopen::validate_pdo_map(map, d, canopen::PdoDirection::kTransmit).abort_code, canopen::kAbortNotMappable);
}

/// A CoE SDO request straight into the server, its answer's 8 SDO bytes and what follows.
struct Answer {
  std::size_t size = 0;
  SdoBytes sdo{};
  std::vector<std::uint8_t> more;
};
Answer ask(CoeSdoServer& server, const SdoBytes& request, const std::vector<std::uint8_t>& more = {}) {
  std::array<std::uint8_t, 128> in{};
  std::array<std::uint8_t, 128> out{};
  write_coe_sdo(in.data(), 1, kCoeServiceSdoRequest, request, more.data(), more.size());
  Answer a;
  a.size = server.handle(in.data(), in.size(), out.data(), out.size());
  MailboxHeader header;
  std::uint8_t service = 0;
  if (a.size == 0 || parse_coe_sdo(out.data(), a.size, header, service, a.sdo) != MailboxError::kNone) return a;
  a.more.assign(out.begin() + kCoeSdoMoreAt, out.begin() + kCoeSdoMoreAt + coe_sdo_more_bytes(header));
  return a;
}
std::uint32_t abort_code_of(const Answer& a) { return a.sdo[0] == 0x80 ? get_le32(a.sdo.data() + 4) : 0; }

TEST(CoeSdo, TheServerAbortsEachMisuseOfTheProtocolWithItsCode) {
  test::CoeSlave slave;
  slave.dictionary.add_text({0x2100, 1, "a long text", text_of(300)});
  CoeSdoServer& coe = slave.coe;
  // A segment asked for with no upload under way.
  EXPECT_EQ(abort_code_of(ask(coe, {0x60, 0, 0, 0, 0, 0, 0, 0})), canopen::kAbortCommandSpecifier);
  // An upload started (112 bytes of 300 and the complete size), then a segment with toggle 1 first.
  const Answer start = ask(coe, {0x40, 0x00, 0x21, 1, 0, 0, 0, 0});
  EXPECT_EQ(start.sdo[0], 0x41);
  EXPECT_EQ(get_le32(start.sdo.data() + 4), 300u);
  EXPECT_EQ(start.more.size(), 112u);
  EXPECT_EQ(abort_code_of(ask(coe, {0x70, 0, 0, 0, 0, 0, 0, 0})), canopen::kAbortToggleBit);
  // The abort ended it: toggle 0 is no longer an upload's segment.
  EXPECT_EQ(abort_code_of(ask(coe, {0x60, 0, 0, 0, 0, 0, 0, 0})), canopen::kAbortCommandSpecifier);
  // A normal download of 1 byte (0x6060 = 10), and refusals of what is longer or segmented.
  EXPECT_EQ(ask(coe, {0x21, 0x60, 0x60, 0, 1, 0, 0, 0}, {10}).sdo[0], 0x60);
  EXPECT_EQ(slave.dictionary.get_or(0x6060, 0, 0), 10);
  EXPECT_EQ(abort_code_of(ask(coe, {0x21, 0x60, 0x60, 0, 8, 0, 0, 0}, {1, 2, 3, 4, 5, 6, 7, 8})),
            canopen::kAbortLengthTooHigh);
  EXPECT_EQ(abort_code_of(ask(coe, {0x21, 0x08, 0x10, 0, 8, 0, 0, 0}, {1, 2, 3, 4, 5, 6, 7, 8})),
            canopen::kAbortWriteReadOnly);
  EXPECT_EQ(abort_code_of(ask(coe, {0x21, 0x77, 0x77, 0, 8, 0, 0, 0}, {1, 2, 3, 4, 5, 6, 7, 8})),
            canopen::kAbortObjectMissing);
  EXPECT_EQ(abort_code_of(ask(coe, {0x21, 0x60, 0x60, 0, 2, 0, 0, 0}, {10})), canopen::kAbortCommandSpecifier)
      << "2 bytes announced, 1 sent: a segment would follow";
  EXPECT_EQ(abort_code_of(ask(coe, {0x00, 1, 2, 3, 4, 5, 6, 7})), canopen::kAbortCommandSpecifier);
  // Over CANopen's expedited server the text is refused, not cut to 4 bytes.
  EXPECT_EQ(abort_code_of(ask(coe, {0x40, 0x08, 0x10, 0, 0, 0, 0, 0})), 0u) << "CoE serves it";
  EXPECT_EQ(slave.dictionary.read(0x1008, 0).abort_code, canopen::kAbortUnsupportedAccess);
}

TEST(CoeSdo, CompleteAccessReadsAndWritesARecordWholeAsTheSiiOffersIt) {
  VirtualCia402Slave slave;
  VirtualSegment segment({&slave.esc()});
  VirtualSegmentLink link(segment);
  Master master(link);
  const SlaveInfo info = test::to_preop(master);
  EXPECT_EQ(info.coe_details & kCoeDetailsCompleteAccess, kCoeDetailsCompleteAccess)
      << "its SII offers complete access";
  const auto read = [&](std::uint16_t index, std::uint8_t sub) {
    const SdoResult r = master.sdo_upload(info, index, sub, true);
    EXPECT_TRUE(r.done) << r.describe();
    return r.describe();
  };
  // Sub-index 0 as 16 bits, then each entry in its size (ETG.1000.6), as SOEM reads them.
  EXPECT_EQ(read(kObjectSyncManagerTypes, 0), "04 00 01 02 03 04 (6 bytes)");
  EXPECT_EQ(read(kObjectSyncManagerTypes, 1), "01 02 03 04 (4 bytes)");
  EXPECT_EQ(read(kObjectRxPdoAssign, 0), "01 00 00 16 (4 bytes)");
  EXPECT_EQ(read(kRxPdoMapping, 0), "02 00 10 00 40 60 10 00 71 60 (10 bytes)");
  EXPECT_EQ(master.sdo_upload(info, 0x6041, 0, true).abort_code, canopen::kAbortUnsupportedAccess) << "a variable";
  EXPECT_EQ(master.sdo_upload(info, 0x1008, 0, true).abort_code, canopen::kAbortUnsupportedAccess) << "a text";
  EXPECT_EQ(master.sdo_upload(info, kRxPdoMapping, 2, true).abort_code, canopen::kAbortUnsupportedAccess);
  // Written whole: the mapping in the other order (count 0, the entries, the count, each checked).
  CoeSdoServer server(slave.dictionary(), canopen::NodeId(1));
  const std::vector<std::uint8_t> swapped{2, 0, 0x10, 0, 0x71, 0x60, 0x10, 0, 0x40, 0x60};
  const auto write = [&](const std::vector<std::uint8_t>& record) {
    return ask(server, {0x31, 0x00, 0x16, 0, static_cast<std::uint8_t>(record.size()), 0, 0, 0}, record);
  };
  EXPECT_EQ(write(swapped).sdo[0], 0x60);
  EXPECT_EQ(read(kRxPdoMapping, 0), "02 00 10 00 71 60 10 00 40 60 (10 bytes)");
  // The wrong length: aborted before anything is written. An entry the dictionary refuses: aborted
  // after the count went to 0, so the mapping is empty until it is written again.
  std::vector<std::uint8_t> short_one(swapped.begin(), swapped.end() - 1);
  EXPECT_EQ(abort_code_of(write(short_one)), canopen::kAbortLengthTooLow);
  std::vector<std::uint8_t> absent = swapped;
  absent[5] = 0x77;  // 0x7771: no such object
  EXPECT_EQ(abort_code_of(write(absent)), canopen::kAbortObjectMissing);
  EXPECT_EQ(read(kRxPdoMapping, 0).substr(0, 5), "00 00") << "count 0 first: a mapping is rebuilt from nothing";
  EXPECT_EQ(write(swapped).sdo[0], 0x60);
  EXPECT_EQ(read(kRxPdoMapping, 0), "02 00 10 00 71 60 10 00 40 60 (10 bytes)");
}

TEST(CoeSdo, OurMasterWritesAPdoAssignmentWholeWhereTheSlaveOffersCompleteAccess) {
  // Three SDOs for one PDO (the assignment emptied, the mapping, the assignment) instead of seven,
  // the dictionary left as the entry-by-entry procedure leaves it.
  const std::vector<canopen::PdoMapEntry> entries{{0x6071, 0, 16}, {0x6040, 0, 16}};
  std::vector<std::string> records;
  for (const bool whole : {true, false}) {
    VirtualCia402Slave slave;
    VirtualSegment segment({&slave.esc()});
    VirtualSegmentLink link(segment);
    Master master(link);
    SlaveInfo info = test::to_preop(master);
    if (!whole) info.coe_details = 0x01;  // as a slave without complete access
    const std::uint64_t before = slave.coe().requests();
    master.write_pdo_assignment(info, kObjectRxPdoAssign, kRxPdoMapping, entries);
    EXPECT_EQ(slave.coe().requests() - before, whole ? 3u : 7u);
    info.coe_details = 0x21;
    records.push_back(master.sdo_upload(info, kRxPdoMapping, 0, true).describe() + " / " +
                      master.sdo_upload(info, kObjectRxPdoAssign, 0, true).describe());
  }
  EXPECT_EQ(records[0], "02 00 10 00 71 60 10 00 40 60 (10 bytes) / 01 00 00 16 (4 bytes)");
  EXPECT_EQ(records[0], records[1]);
}

/// Each SDO message of the capture at `path` as our decoder names it (none malformed).
std::vector<std::string> named_sdo_messages(const fs::path& path) {
  PcapngReader reader(path.string());
  const CaptureDecode d = decode_capture(reader);
  EXPECT_EQ(d.malformed_frames, 0u);
  std::vector<std::string> seen;
  for (const CaptureDecode::Sdo& sdo : d.sdos) seen.push_back(describe(sdo.seen));
  return seen;
}

TEST(CoeSdo, ARecordLongerThanTheReceiveMailboxGoesInDownloadSegments) {
  // Mailboxes of 16 bytes: the initiate carries none of the record, each segment 7 bytes.
  const std::vector<std::uint16_t> sii = test::sii_with_mailboxes(16);
  VirtualCia402Slave slave(VirtualCia402Slave::make_dictionary(sii, canopen::kSupportedModesCyclicSynchronous), sii);
  VirtualSegment segment({&slave.esc()});
  VirtualSegmentLink link(segment);
  Master master(link);
  const fs::path path = fs::temp_directory_path() / ("pmlsm_coe_sdo_" + std::to_string(::getpid())) / "d.pcapng";
  fs::create_directories(path.parent_path());
  {
    const SlaveInfo info = test::to_preop(master);
    ASSERT_EQ(info.mailbox_receive_size, 16);
    PcapngWriter writer(path.string());
    master.capture_to(&writer);
    // TxPDO 0x1A01 with four 16-bit entries (statusword, torque actual, torque demand,
    // controlword): 18 bytes, in segments of 7, 7 and 4.
    const std::vector<std::uint8_t> record{4,    0,    0x10, 0,    0x41, 0x60, 0x10, 0,    0x77,
                                           0x60, 0x10, 0,    0x74, 0x60, 0x10, 0,    0x40, 0x60};
    const std::uint64_t before = slave.coe().segments();
    const SdoResult r = master.sdo_download_record(info, 0x1A01, record);
    ASSERT_TRUE(r.done) << r.describe();
    EXPECT_EQ(slave.coe().segments() - before, 3u);
    master.capture_to(nullptr);
    writer.flush();
    EXPECT_EQ(master.sdo_upload(info, 0x1A01, 0, true).describe(),
              "04 00 10 00 41 60 10 00 77 60 10 00 74 60 10 00 40 60 (18 bytes)")
        << "read back whole (by upload segments through the same small mailbox)";
    // The slave's checks hold at the end: an entry it refuses aborts the last segment's answer.
    std::vector<std::uint8_t> absent = record;
    absent[17] = 0x77;  // 0x7740: no such object
    EXPECT_EQ(master.sdo_download_record(info, 0x1A01, absent).abort_code, canopen::kAbortObjectMissing);
    // And our master maps the velocity and position modes' outputs through it, record by record.
    master.write_pdo_assignment(info, kObjectRxPdoAssign, kRxPdoMapping,
                                {{0x6040, 0, 16}, {0x60FF, 0, 32}, {0x60B2, 0, 16}, {0x607A, 0, 32}});
    EXPECT_EQ(master.sdo_upload(info, kObjectRxPdoAssign, 0, true).describe(), "02 00 00 16 01 16 (6 bytes)");
  }
  const std::vector<std::string> expected{
      "download request 0x1A01:00, normal: 18 bytes, 0 here", "download response 0x1A01:00",
      "download segment request (toggle 0, 7 bytes)",         "download segment response (toggle 0)",
      "download segment request (toggle 1, 7 bytes)",         "download segment response (toggle 1)",
      "download segment request (toggle 0, 4 bytes, last)",   "download segment response (toggle 0)"};
  EXPECT_EQ(named_sdo_messages(path), expected);
  fs::remove_all(path.parent_path());
}

TEST(CoeSdo, TheServerAbortsADownloadSegmentOutOfTurnOrPastTheSize) {
  VirtualCia402Slave slave;
  CoeSdoServer server(slave.dictionary(), canopen::NodeId(1));
  const auto start = [&](std::uint8_t size, const std::vector<std::uint8_t>& first) {
    return ask(server, {0x31, 0x01, 0x16, 0, size, 0, 0, 0}, first).sdo[0];
  };
  // A record of 10 bytes announced, 2 in the initiate: the rest must follow in turn.
  EXPECT_EQ(start(10, {2, 0}), 0x60);
  EXPECT_EQ(abort_code_of(ask(server, {0x10, 0x10, 0, 0x40, 0x60, 0x10, 0, 0x71})), canopen::kAbortToggleBit)
      << "toggle 1 first";
  EXPECT_EQ(abort_code_of(ask(server, {0x00, 0x10, 0, 0x40, 0x60, 0x10, 0, 0x71})), canopen::kAbortCommandSpecifier)
      << "the abort ended the transfer";
  EXPECT_EQ(start(10, {2, 0}), 0x60);
  EXPECT_EQ(abort_code_of(ask(server, {0x00, 1, 2, 3, 4, 5, 6, 7}, {8, 9})), canopen::kAbortLengthTooHigh)
      << "9 bytes where 8 were left";
  EXPECT_EQ(start(10, {2, 0}), 0x60);
  EXPECT_EQ(abort_code_of(ask(server, {0x03, 0x10, 0, 0x40, 0x60, 0x10, 0, 0})), canopen::kAbortLengthTooLow)
      << "the last segment with 6 bytes where 8 were left";
  EXPECT_EQ(start(10, {2, 0}), 0x60);
  EXPECT_EQ(ask(server, {0x00, 0x10, 0, 0x71, 0x60, 0x10, 0, 0x40}).sdo[0], 0x20);
  EXPECT_EQ(ask(server, {0x1D, 0x60, 0, 0, 0, 0, 0, 0}).sdo[0], 0x30) << "the last, 1 byte (n = 6), toggle 1";
  EXPECT_EQ(slave.dictionary().get_or(0x1601, 2, 0), 0x60400010) << "written whole when the last came";
}

TEST(CoeSdo, ACaptureOfASegmentedUploadNamesEachMessage) {
  const fs::path path = fs::temp_directory_path() / ("pmlsm_coe_sdo_" + std::to_string(::getpid())) / "s.pcapng";
  fs::create_directories(path.parent_path());
  {
    Session s;
    s.slave.dictionary.add_text({0x2100, 1, "a long text", text_of(112 + 119 + 3)});
    PcapngWriter writer(path.string());
    s.master.capture_to(&writer);
    ASSERT_TRUE(s.master.sdo_upload(s.info, 0x2100, 1).done);
    writer.flush();
  }
  const std::vector<std::string> expected{
      "upload request 0x2100:01",          "upload response 0x2100:01, normal: 234 bytes, 112 here",
      "upload segment request (toggle 0)", "upload segment response (toggle 0, 119 bytes)",
      "upload segment request (toggle 1)", "upload segment response (toggle 1, 3 bytes, last)"};
  EXPECT_EQ(named_sdo_messages(path), expected);
  fs::remove_all(path.parent_path());
}

}  // namespace coe_sdo_test
}  // namespace pmlsm::ethercat

// Wireshark's EtherCAT dissectors (tshark) judge our frames: every command, several datagrams a
// frame, raw Ethernet and EtherCAT over UDP, written as a pcapng capture (PcapngWriter). tshark
// must read the capture, find every datagram as we built it (command, index, working counter) and
// call nothing malformed. Skipped, saying so, where tshark is not installed
// (scripts/install_deps.sh installs it).
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "coe_slave.hpp"
#include "pmlsm/ethercat/capture.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/ethercat/mailbox.hpp"
#include "pmlsm/ethercat/frame.hpp"
#include "pmlsm/ethercat/master.hpp"
#include "pmlsm/ethercat/pcapng.hpp"

namespace pmlsm::ethercat {
namespace {

namespace fs = std::filesystem;

/// A capture's path in a fresh directory of this test's own (pmlsm_ethercat_<what>_<pid>).
fs::path scratch_capture(const std::string& what, const std::string& file) {
  const fs::path dir = fs::temp_directory_path() / ("pmlsm_ethercat_" + what + "_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / (file + ".pcapng");
}

bool have_tshark() { return std::system("tshark --version >/dev/null 2>&1") == 0; }

/// Our master with `esc` alone on its segment, the slave taken to PREOP, then every frame of
/// `session(master, info)` into `capture`.
template <typename Session>
void capture_session(Esc& esc, const fs::path& capture, Session session) {
  VirtualSegment segment({&esc});
  VirtualSegmentLink link(segment);
  PcapngWriter writer(capture.string());
  Master master(link);
  const SlaveInfo info = test::to_preop(master);
  master.capture_to(&writer);
  session(master, info);
  writer.flush();
}

/// What tshark prints for `fields` of every packet of `capture` matching `filter`, a line a
/// packet, the fields comma-separated (a field with several values: those joined by ';').
std::string tshark(const fs::path& capture, const std::string& filter, const std::string& fields) {
  std::string command = "tshark -n -r '" + capture.string() + "' -T fields -E separator=, -E aggregator=';'";
  std::istringstream names(fields);
  for (std::string f; names >> f;) command += " -e " + f;
  if (!filter.empty()) command += " -Y '" + filter + "'";
  command += " 2>/dev/null";
  std::string out;
  if (FILE* pipe = ::popen(command.c_str(), "r")) {
    std::array<char, 4096> chunk{};
    for (std::size_t n; (n = std::fread(chunk.data(), 1, chunk.size(), pipe)) > 0;) out.append(chunk.data(), n);
    ::pclose(pipe);
  }
  return out;
}

/// IPv4 + UDP headers around an EtherCAT over UDP payload, in an Ethernet frame (the IPv4
/// header's checksum computed; UDP's 0: none, as IPv4 allows).
std::vector<std::uint8_t> udp_ethernet_frame(Bytes payload) {
  const std::array<std::uint8_t, 14> ethernet = {0x02, 0, 0, 0, 0, 2, 0x02, 0, 0, 0, 0, 1, 0x08, 0x00};
  const auto ip_length = static_cast<std::uint16_t>(20 + 8 + payload.size);
  std::array<std::uint8_t, 20> ip = {0x45,
                                     0,
                                     static_cast<std::uint8_t>(ip_length >> 8),
                                     static_cast<std::uint8_t>(ip_length & 0xFF),
                                     0,
                                     0,
                                     0x40,
                                     0,
                                     64,
                                     17,
                                     0,
                                     0,
                                     127,
                                     0,
                                     0,
                                     1,
                                     127,
                                     0,
                                     0,
                                     1};
  std::uint32_t sum = 0;
  for (std::size_t i = 0; i < ip.size(); i += 2) sum += static_cast<std::uint32_t>((ip[i] << 8) | ip[i + 1]);
  while ((sum >> 16) != 0) sum = (sum & 0xFFFF) + (sum >> 16);
  const auto checksum = static_cast<std::uint16_t>(~sum);
  ip[10] = static_cast<std::uint8_t>(checksum >> 8);
  ip[11] = static_cast<std::uint8_t>(checksum & 0xFF);
  const auto udp_length = static_cast<std::uint16_t>(8 + payload.size);
  const std::array<std::uint8_t, 8> udp = {0x88,
                                           0xA4,
                                           0x88,
                                           0xA4,  // port 34980 to port 34980
                                           static_cast<std::uint8_t>(udp_length >> 8),
                                           static_cast<std::uint8_t>(udp_length & 0xFF),
                                           0,
                                           0};
  std::vector<std::uint8_t> f(ethernet.size() + ip.size() + udp.size() + payload.size);
  auto at = std::copy(ethernet.begin(), ethernet.end(), f.begin());
  at = std::copy(ip.begin(), ip.end(), at);
  at = std::copy(udp.begin(), udp.end(), at);
  std::copy(payload.data, payload.data + payload.size, at);
  return f;
}

struct Expected {
  std::string commands, indices, working_counters;
};

/// Each frame's datagrams as tshark writes the fields ecat.cmd, ecat.idx and ecat.cnt.
void append(Expected& e, const FrameBuilder& frame) {
  ParsedFrame parsed;
  const Bytes b = frame.ethernet();
  ASSERT_EQ(parse_ethernet_frame(b.data, b.size, parsed), FrameError::kNone);
  std::string cmd, idx, cnt;
  for (std::size_t i = 0; i < parsed.count; ++i) {
    const DatagramView& d = parsed.datagrams[i];
    const char* sep = i == 0 ? "" : ";";
    char command[8], index[8];
    std::snprintf(command, sizeof command, "0x%02x", static_cast<unsigned>(d.header.command));
    std::snprintf(index, sizeof index, "0x%02x", d.header.index);
    cmd += sep + std::string(command);
    idx += sep + std::string(index);
    cnt += sep + std::to_string(d.working_counter);
  }
  e.commands += cmd + "\n";
  e.indices += idx + "\n";
  e.working_counters += cnt + "\n";
}

std::string column(const std::string& table, std::size_t n) {
  std::istringstream lines(table);
  std::string out;
  for (std::string line; std::getline(lines, line);) {
    std::istringstream cells(line);
    std::string cell;
    for (std::size_t i = 0; i <= n; ++i) std::getline(cells, cell, ',');
    out += cell + "\n";
  }
  return out;
}

TEST(EtherCatTshark, DecodesEveryDatagramAsBuiltOnEthernetAndOverUdp) {
  if (!have_tshark()) GTEST_SKIP() << "tshark is not installed (scripts/install_deps.sh installs it)";
  const fs::path capture = scratch_capture("tshark", "frames");
  const fs::path dir = capture.parent_path();
  Expected raw, over_udp;
  {
    PcapngWriter writer(capture.string());
    std::int64_t t = 1'700'000'000'000'000'000;
    std::array<std::uint8_t, 64> data{};
    for (std::uint8_t c = 0; c < kCommandCount; ++c) {
      FrameBuilder frame;
      const auto command = static_cast<Command>(c);
      data.fill(static_cast<std::uint8_t>(c + 1));
      const std::uint32_t address = is_logical(command) ? 0x00010000U : physical_address(auto_increment_adp(c), 0x0130);
      ASSERT_TRUE(frame.add(command, static_cast<std::uint8_t>(0x80 + c), address, data.data(), 2,
                            expected_working_counter(command, 2)));
      // A second datagram: a configured-address read of the AL status.
      ASSERT_TRUE(frame.add(Command::kFprd, c, physical_address(0x1000 + c, 0x0130), nullptr, 2, 1));
      writer.write(frame.ethernet(), t += 1000);
      append(raw, frame);
      const std::vector<std::uint8_t> udp = udp_ethernet_frame(frame.udp_payload());
      writer.write({udp.data(), udp.size()}, t += 1000);
      append(over_udp, frame);
    }
    writer.flush();
  }
  const std::string fields = "ecat.cmd ecat.idx ecat.cnt";
  const std::string on_ethernet = tshark(capture, "eth.type == 0x88a4", fields);
  const std::string on_udp = tshark(capture, "udp.port == 34980 && ecat", fields);
  ASSERT_FALSE(on_ethernet.empty()) << "tshark read nothing from " << capture;
  EXPECT_EQ(column(on_ethernet, 0), raw.commands);
  EXPECT_EQ(column(on_ethernet, 1), raw.indices);
  EXPECT_EQ(column(on_ethernet, 2), raw.working_counters);
  EXPECT_EQ(column(on_udp, 0), over_udp.commands);
  EXPECT_EQ(column(on_udp, 1), over_udp.indices);
  EXPECT_EQ(column(on_udp, 2), over_udp.working_counters);
  // Nothing malformed, no warning from the EtherCAT dissectors.
  EXPECT_EQ(tshark(capture, "_ws.malformed || _ws.expert.severity >= warning", "frame.number"), "");
  if (!HasFailure()) fs::remove_all(dir);  // kept for a look when something failed
}

TEST(EtherCatTshark, AMasterSessionWithVirtualSlavesDecodesWithTheWorkingCountersTheMasterSaw) {
  if (!have_tshark()) GTEST_SKIP() << "tshark is not installed (scripts/install_deps.sh installs it)";
  const fs::path capture = scratch_capture("session", "session");
  const fs::path dir = capture.parent_path();
  std::vector<std::unique_ptr<Esc>> slaves;
  std::vector<Esc*> line;
  for (int i = 0; i < 2; ++i) {
    EscParams p;
    p.sii.assign(sii::kMinWords, 0);
    p.sii[sii::kVendorId] = static_cast<std::uint16_t>(0x6A + i);
    p.sii[sii::kFirstCategory] = 0xFFFF;
    slaves.push_back(std::make_unique<Esc>(p));
    line.push_back(slaves.back().get());
  }
  VirtualSegment segment(line);
  VirtualSegmentLink link(segment);
  std::string expected;  // the working counter of each reply, in order
  {
    PcapngWriter writer(capture.string());
    Master master(link);
    master.capture_to(&writer);
    const auto step = [&](Command c, std::uint32_t address, std::uint16_t length, std::uint16_t working_counter,
                          std::uint16_t value = 0) {
      std::array<std::uint8_t, 16> data{};
      data[0] = static_cast<std::uint8_t>(value & 0xFF);
      data[1] = static_cast<std::uint8_t>(value >> 8);
      const Reply r = master.exchange(c, address, data.data(), length);
      ASSERT_TRUE(r.answered) << to_string(c);
      ASSERT_EQ(r.working_counter, working_counter) << to_string(c);
      expected += "0\n" + std::to_string(working_counter) + "\n";  // sent with 0, back with it
    };
    step(Command::kBrd, physical_address(0, reg::kType), 2, 2);
    step(Command::kApwr, physical_address(auto_increment_adp(0), reg::kStationAddress), 2, 1, 0x1001);
    step(Command::kApwr, physical_address(auto_increment_adp(1), reg::kStationAddress), 2, 1, 0x1002);
    step(Command::kFprd, physical_address(0x1002, reg::kAlStatus), 6, 1);
    step(Command::kBrw, physical_address(0, reg::kAlControl), 2, 6, 0x0001);  // both: INIT again
    step(Command::kLrw, 0x10000, 8, 0);                                       // no FMMU mapped: nobody
    step(Command::kFprd, physical_address(0x7777, reg::kAlStatus), 2, 0);     // no such slave
    writer.flush();
  }
  EXPECT_EQ(tshark(capture, "ecat", "ecat.cnt"), expected);
  EXPECT_EQ(tshark(capture, "_ws.malformed || _ws.expert.severity >= warning", "frame.number"), "");
  // Wireshark reads the AL status register the slave answered with: INIT.
  EXPECT_NE(tshark(capture, "ecat.cmd == 4 && ecat.cnt == 1", "frame.number"), "");
  if (!HasFailure()) fs::remove_all(dir);  // kept for a look when something failed
}

TEST(EtherCatTshark, DecodesOurCoeSdoRequestsAndTheSlavesAnswers) {
  if (!have_tshark()) GTEST_SKIP() << "tshark is not installed (scripts/install_deps.sh installs it)";
  const fs::path capture = scratch_capture("coe", "coe");
  const fs::path dir = capture.parent_path();
  test::CoeSlave slave;
  capture_session(slave.esc, capture, [&](Master& master, const SlaveInfo& info) {
    ASSERT_TRUE(master.sdo_upload(info, 0x1000, 0).done);
    ASSERT_TRUE(master.sdo_download(info, 0x6060, 0, 10, 1).done);
    ASSERT_FALSE(master.sdo_upload(info, 0x7777, 0).done);
  });
  // Each transfer is seen three times: the request on its way to the receive mailbox and back
  // through the slave, then the answer read from the send mailbox, each with the object's index.
  // Wireshark 4.0 names an abort response's service (scs 4) but does not dissect its index.
  EXPECT_EQ(tshark(capture, "ecat_mailbox.coe", "ecat_mailbox.coe.sdoidx"),
            "0x1000\n0x1000\n0x1000\n0x6060\n0x6060\n0x6060\n0x7777\n0x7777\n\n");
  EXPECT_EQ(tshark(capture, "ecat_mailbox.coe.type == 3", "ecat_mailbox.counter"), "1\n2\n3\n")
      << "three SDO responses, the slave's mailbox counter counting 1, 2, 3";
  EXPECT_EQ(tshark(capture, "_ws.malformed || _ws.expert.severity >= warning", "frame.number"), "");
  if (!HasFailure()) fs::remove_all(dir);  // kept for a look when something failed
}

TEST(EtherCatTshark, DecodesOurNormalAndSegmentedUploadOfALongText) {
  if (!have_tshark()) GTEST_SKIP() << "tshark is not installed (scripts/install_deps.sh installs it)";
  const fs::path capture = scratch_capture("segments", "segments");
  const fs::path dir = capture.parent_path();
  test::CoeSlave slave;
  // 112 bytes in the normal upload response, 119 in a full segment, 3 in the last one.
  std::string text(112 + 119 + 3, '.');
  for (std::size_t i = 0; i < text.size(); ++i) text[i] = static_cast<char>('A' + i % 26);
  slave.dictionary.add_text({0x2100, 1, "a long text", text});
  capture_session(slave.esc, capture, [&](Master& master, const SlaveInfo& info) {
    const SdoResult r = master.sdo_upload(info, 0x2100, 1);
    ASSERT_TRUE(r.done) << r.describe();
    EXPECT_EQ(std::string(r.bytes.begin(), r.bytes.end()), text);
  });
  // The initiate response: not expedited, size indicated, the complete size 234.
  EXPECT_EQ(tshark(capture, "ecat_mailbox.coe.sdoscsiu && ecat.cnt == 1",
                   "ecat_mailbox.coe.sdoscsiu_expedited ecat_mailbox.coe.sdoscsiu_sizeind ecat_mailbox.coe.sdolength"),
            "0,1,0x000000ea\n");
  // The segment responses read from the send mailbox: toggle and last-segment bits as sent.
  EXPECT_EQ(tshark(capture, "ecat_mailbox.coe.sdoscsus && ecat.cnt == 1",
                   "ecat_mailbox.coe.sdoscsus_toggle ecat_mailbox.coe.sdoscsus_lastseg"),
            "0,0\n1,1\n");
  EXPECT_EQ(tshark(capture, "_ws.malformed || _ws.expert.severity >= warning", "frame.number"), "");
  if (!HasFailure()) fs::remove_all(dir);  // kept for a look when something failed
}

TEST(EtherCatTshark, DecodesOurSegmentedDownloadOfARecordThroughSmallMailboxes) {
  if (!have_tshark()) GTEST_SKIP() << "tshark is not installed (scripts/install_deps.sh installs it)";
  const fs::path capture = scratch_capture("download", "download");
  const fs::path dir = capture.parent_path();
  const std::vector<std::uint16_t> sii = test::sii_with_mailboxes(16);
  VirtualCia402Slave slave(VirtualCia402Slave::make_dictionary(sii), sii);
  capture_session(slave.esc(), capture, [&](Master& master, const SlaveInfo& info) {
    // TxPDO 0x1A01 with four 16-bit entries: 18 bytes in segments of 7, 7 and 4.
    const SdoResult r = master.sdo_download_record(
        info, 0x1A01, {4, 0, 0x10, 0, 0x41, 0x60, 0x10, 0, 0x77, 0x60, 0x10, 0, 0x74, 0x60, 0x10, 0, 0x60, 0x77});
    ASSERT_EQ(r.abort_code, canopen::kAbortObjectMissing) << "0x7760 does not exist: refused at the end";
  });
  // The initiate request: not expedited, size indicated, complete access; then the segments'
  // toggle, size and last bits as sent, each answered with its toggle (the last by the abort).
  EXPECT_EQ(tshark(capture, "ecat_mailbox.coe.sdoccsid && ecat.cnt == 0",
                   "ecat_mailbox.coe.sdoccsid.expedited ecat_mailbox.coe.sdoccsid.sizeind "
                   "ecat_mailbox.coe.sdoccsid.complete ecat_mailbox.coe.sdolength"),
            "0,1,1,0x00000012\n");
  EXPECT_EQ(tshark(capture, "ecat_mailbox.coe.sdoccsds && ecat.cnt == 0",
                   "ecat_mailbox.coe.sdoccsds.toggle ecat_mailbox.coe.sdoccsds.size ecat_mailbox.coe.sdoccsds.lastseg"),
            "0,0,0\n1,0,0\n0,3,1\n");
  EXPECT_EQ(tshark(capture, "ecat_mailbox.coe.sdoscsds && ecat.cnt == 1", "ecat_mailbox.coe.sdoscsds_toggle"),
            "0\n1\n");
  EXPECT_EQ(tshark(capture, "_ws.malformed || _ws.expert.severity >= warning", "frame.number"), "");
  if (!HasFailure()) fs::remove_all(dir);  // kept for a look when something failed
}

TEST(EtherCatTshark, DecodesTheVirtualDrivesCoeEmergenciesQueuedAheadOfAnSdoAnswer) {
  if (!have_tshark()) GTEST_SKIP() << "tshark is not installed (scripts/install_deps.sh installs it)";
  const fs::path capture = scratch_capture("emergency", "emergency");
  const fs::path dir = capture.parent_path();
  VirtualCia402Slave slave;
  capture_session(slave.esc(), capture, [&](Master& master, const SlaveInfo& info) {
    // A fault's emergency and its end, posted by the slave before the master asks anything.
    ASSERT_TRUE(slave.post_emergency(0x8700));
    ASSERT_TRUE(slave.post_emergency(0x0000));
    ASSERT_TRUE(master.sdo_upload(info, 0x1000, 0).done);
    EXPECT_EQ(master.emergencies(), 2u);
    EXPECT_EQ(master.last_emergency_code(), 0x0000);
  });
  // Wireshark reads two CoE messages of type 1 (emergency) read from the send mailbox, with the
  // slave's mailbox counter going on (the SDO response after them is 3), nothing malformed.
  EXPECT_EQ(tshark(capture, "ecat_mailbox.coe.type == 1", "ecat_mailbox.counter"), "1\n2\n");
  EXPECT_EQ(tshark(capture, "ecat_mailbox.coe.type == 3", "ecat_mailbox.counter"), "3\n");
  EXPECT_EQ(tshark(capture, "_ws.malformed || _ws.expert.severity >= warning", "frame.number"), "");
  if (!HasFailure()) fs::remove_all(dir);  // kept for a look when something failed
}

/// ../shared/ethercat/captures/NAME, or empty when the shared captures are not there.
fs::path shared_capture(const std::string& name) {
  const fs::path path = fs::path(PMLSM_SOURCE_DIR) / ".." / "shared" / "ethercat" / "captures" / name;
  return fs::exists(path) ? path : fs::path();
}

TEST(EtherCatTshark, ARealDrivesCapturesParseAsTsharkReadsThemAndTheAkdsSdoAnswersAreTsharks) {
  if (!have_tshark()) GTEST_SKIP() << "tshark is not installed (scripts/install_deps.sh installs it)";
  const fs::path akd = shared_capture("soem-sdinfo-akd.pcapng");
  if (akd.empty()) GTEST_SKIP() << "no ../shared/ethercat/captures (real devices' captures); not run";
  // Every EtherCAT frame of the four captures (SOEM with an AKD, an EK1100 and a LAN9252;
  // TwinCAT with the AKD) parsed without complaint, as many as tshark's EtherCAT frames.
  for (const char* name : {"soem-sdinfo-akd.pcapng", "soem-sdinfo-ek1100-el1004.pcapng", "soem-single-lan9252.pcapng",
                           "twincat-akd-nc-mode.pcapng"}) {
    PcapngReader reader(shared_capture(name).string());
    const CaptureDecode d = decode_capture(reader);
    EXPECT_EQ(d.malformed_frames, 0u) << name << ": frame " << d.first_malformed << ": " << to_string(d.first_error);
    const std::string tshark_frames = tshark(shared_capture(name), "ecatf", "frame.number");
    EXPECT_EQ(d.ethercat_frames,
              static_cast<std::uint64_t>(std::count(tshark_frames.begin(), tshark_frames.end(), '\n')))
        << name;
  }
  // The AKD's expedited SDO answers, as our parsers read them and as tshark does: frame, index,
  // sub-index and value, in order (the answers its slave counted, working counter 1).
  PcapngReader reader(akd.string());
  const CaptureDecode d = decode_capture(reader);
  std::ostringstream ours;
  for (const CaptureDecode::Sdo& s : d.sdos) {
    std::uint16_t index = 0;
    std::uint8_t subindex = 0;
    std::uint32_t value = 0;
    std::uint8_t size = 0;
    if (!upload_value(s.seen, index, subindex, value, size)) continue;
    char row[64];
    std::snprintf(row, sizeof row, "%llu,0x%04x,0x%02x,0x%0*x\n", static_cast<unsigned long long>(s.frame), index,
                  subindex, 2 * size, value);
    ours << row;
  }
  const std::string theirs =
      tshark(akd, "ecat_mailbox.coe.sdores && ecat.cmd == 4 && ecat.cnt == 1",
             "frame.number ecat_mailbox.coe.sdoidx ecat_mailbox.coe.sdosub ecat_mailbox.coe.sdodata");
  EXPECT_EQ(ours.str(), theirs);
  EXPECT_EQ(std::count(theirs.begin(), theirs.end(), '\n'), 35) << "SOEM's 35 reads of the AKD's PDO objects";
  EXPECT_NE(ours.str().find("0x1a03,0x02,0x606c0020"), std::string::npos)
      << "the AKD's TxPDO 4 maps velocity actual (0x606C, 32 bits)";
}

TEST(EtherCatTshark, TheNormalUploadsSoemReadFromALan9252AreReadAsTsharkReadsThem) {
  if (!have_tshark()) GTEST_SKIP() << "tshark is not installed (scripts/install_deps.sh installs it)";
  const fs::path lan9252 = shared_capture("soem-single-lan9252.pcapng");
  if (lan9252.empty()) GTEST_SKIP() << "no ../shared/ethercat/captures (real devices' captures); not run";
  // SOEM reads the sync manager and PDO objects whole (complete access): the slave answers each by
  // a normal upload, its complete size before the data. Frame, index and size as ours reads them.
  PcapngReader reader(lan9252.string());
  const CaptureDecode d = decode_capture(reader);
  std::ostringstream ours;
  for (const CaptureDecode::Sdo& s : d.sdos) {
    const std::string text = describe(s.seen);
    const std::size_t normal = text.find(", normal: ");
    if (s.seen.service != kCoeServiceSdoResponse || normal == std::string::npos) continue;
    const std::uint32_t size = std::stoul(text.substr(normal + 10));
    char row[64];
    std::snprintf(row, sizeof row, "%llu,%s,0x%08x\n", static_cast<unsigned long long>(s.frame),
                  text.substr(16, 6).c_str(), size);
    ours << row;
  }
  std::string theirs = tshark(lan9252, "ecat_mailbox.coe.sdoscsiu_expedited == 0 && ecat.cmd == 4 && ecat.cnt == 1",
                              "frame.number ecat_mailbox.coe.sdoidx ecat_mailbox.coe.sdolength");
  // Our index text is 0xIIII in capitals, tshark's in small letters.
  std::string ours_lower = ours.str();
  std::transform(ours_lower.begin(), ours_lower.end(), ours_lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  EXPECT_EQ(ours_lower, theirs);
  EXPECT_EQ(std::count(theirs.begin(), theirs.end(), '\n'), 5) << "0x1C00, 0x1C13, 0x1601, 0x1A00, 0x1A02 read whole";
}

}  // namespace
}  // namespace pmlsm::ethercat

// The reader on files that are not whole or not valid: cut at every byte, each byte corrupted,
// garbage, hand-made records it must skip or refuse, and the file of a writer killed by SIGKILL.
// It must never throw (except for a file it cannot open), never crash, and always say what it saw.

#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "mcap_test_support.hpp"
#include "pmlsm/mcap/mcap.hpp"

namespace pmlsm::mcap::test {
namespace {

bool has_problem(const ReadResult& result, const std::string& fragment) {
  for (const std::string& problem : result.report.problems) {
    if (problem.find(fragment) != std::string::npos) return true;
  }
  return false;
}

// Every delivered message is the one written with that sequence number: nothing half-read or
// garbled gets through.
void expect_only_true_messages(const ReadResult& result, const SampleFile& sample, const std::string& context) {
  for (const StoredMessage& message : result.messages) {
    ASSERT_LT(message.sequence, sample.messages.size()) << context;
    ASSERT_EQ(message, sample.messages[message.sequence]) << context;
  }
}

class McapDamagedFile : public ::testing::TestWithParam<Compression> {};

// A recording cut at every possible length: everything in the chunks wholly before the cut comes
// back in order, nothing after it, and the report says the file is not whole.
TEST_P(McapDamagedFile, TruncationAtEveryByteKeepsTheWholeChunks) {
  TempDir dir;
  const SampleFile sample = write_sample(dir.file("full.mcap"), GetParam(), 20, 4);  // 5 chunks
  const std::vector<std::uint8_t> bytes = read_bytes(dir.file("full.mcap"));
  ASSERT_EQ(sample.chunk_end_bytes.size(), 5U);
  const std::string cut_path = dir.file("cut.mcap");

  for (std::size_t cut = 0; cut <= bytes.size(); ++cut) {
    write_bytes(cut_path, bytes.data(), cut);
    ReadResult result;
    ASSERT_NO_THROW(result = read_all(cut_path)) << "cut at " << cut;
    const std::string context =
        "cut at " + std::to_string(cut) + " of " + std::to_string(bytes.size()) + "\n" + result.problems();

    std::size_t whole_chunks = 0;
    while (whole_chunks < sample.chunk_end_bytes.size() && sample.chunk_end_bytes[whole_chunks] <= cut) ++whole_chunks;
    const std::uint64_t at_least = whole_chunks == 0 ? 0 : sample.messages_at_chunk_end[whole_chunks - 1];
    const std::uint64_t at_most =
        whole_chunks < sample.chunk_end_bytes.size() ? sample.messages_at_chunk_end[whole_chunks] : 20;
    ASSERT_GE(result.messages.size(), at_least) << context;
    ASSERT_LE(result.messages.size(), at_most) << context;
    ASSERT_EQ(result.report.messages, result.messages.size()) << context;
    for (std::size_t i = 0; i < result.messages.size(); ++i)
      ASSERT_EQ(result.messages[i], sample.messages[i]) << context;
    ASSERT_FALSE(result.message_before_its_channel) << context;

    if (cut == bytes.size()) {
      EXPECT_TRUE(result.report.complete()) << context;
    } else {
      ASSERT_FALSE(result.report.problems.empty()) << context;
      ASSERT_FALSE(result.report.complete()) << context;
    }
    if (cut >= 8 && cut < bytes.size() - 8) {
      ASSERT_TRUE(has_problem(result, "no footer")) << context;
    }
  }
}

// Each byte of a small file inverted in turn: any change is detected (chunk CRC, data section CRC,
// summary CRC or structure), and whatever is delivered is still exactly what was written.
TEST_P(McapDamagedFile, EveryCorruptedByteIsReportedAndNoGarbageIsDelivered) {
  TempDir dir;
  const SampleFile sample = write_sample(dir.file("full.mcap"), GetParam(), 12, 4);
  const std::vector<std::uint8_t> bytes = read_bytes(dir.file("full.mcap"));
  const std::string bad_path = dir.file("bad.mcap");
  for (std::size_t at = 0; at < bytes.size(); ++at) {
    std::vector<std::uint8_t> damaged = bytes;
    damaged[at] = static_cast<std::uint8_t>(damaged[at] ^ 0xFF);
    write_bytes(bad_path, damaged);
    ReadResult result;
    ASSERT_NO_THROW(result = read_all(bad_path)) << "byte " << at;
    const std::string context = "byte " + std::to_string(at) + " inverted\n" + result.problems();
    ASSERT_FALSE(result.report.problems.empty()) << context;
    expect_only_true_messages(result, sample, context);
  }
}

INSTANTIATE_TEST_SUITE_P(AllCompressions, McapDamagedFile, ::testing::ValuesIn(kAllCompressions),
                         compression_test_name);

// Uncompressed chunks are checked by CRC alone: a changed payload byte must be caught by it, and
// only that chunk's messages are lost.
TEST(McapReader, CorruptChunkFailsItsCrcAndTheOtherChunksSurvive) {
  TempDir dir;
  const SampleFile sample = write_sample(dir.file("full.mcap"), Compression::none, 12, 4);
  std::vector<std::uint8_t> bytes = read_bytes(dir.file("full.mcap"));
  // The payload of message 5 (second chunk): find its bytes in the file.
  const std::vector<std::uint8_t>& payload = sample.messages[5].data;
  auto found = std::search(bytes.begin(), bytes.end(), payload.begin(), payload.end());
  ASSERT_NE(found, bytes.end());
  *(found + 7) ^= 0x01;
  write_bytes(dir.file("bad.mcap"), bytes);

  const ReadResult result = read_all(dir.file("bad.mcap"));
  EXPECT_TRUE(has_problem(result, "CRC mismatch")) << result.problems();
  EXPECT_TRUE(result.report.has_footer);
  ASSERT_EQ(result.messages.size(), 8U);
  for (std::size_t i = 0; i < 8; ++i) {
    EXPECT_EQ(result.messages[i].sequence, i < 4 ? i : i + 4);  // chunk 1 (messages 4..7) is gone
  }
  EXPECT_EQ(result.report.chunks, 2U);
}

TEST(McapReader, GarbageIsNotAnMcapFile) {
  TempDir dir;
  std::mt19937 random(12345);
  std::vector<std::uint8_t> garbage(4096);
  for (std::uint8_t& byte : garbage) byte = static_cast<std::uint8_t>(random());
  write_bytes(dir.file("garbage.bin"), garbage);
  const ReadResult result = read_all(dir.file("garbage.bin"));
  EXPECT_EQ(result.report.messages, 0U);
  EXPECT_FALSE(result.report.has_footer);
  EXPECT_TRUE(has_problem(result, "bad magic")) << result.problems();

  write_bytes(dir.file("empty.bin"), garbage.data(), 0);
  const ReadResult empty = read_all(dir.file("empty.bin"));
  EXPECT_EQ(empty.report.messages, 0U);
  EXPECT_FALSE(empty.report.problems.empty());

  // The right magic followed by garbage: records with absurd lengths, reported, not followed.
  for (std::uint32_t seed = 0; seed < 200; ++seed) {
    random.seed(seed);
    RawFile file;
    file.magic();
    std::vector<std::uint8_t> bytes = file.bytes();
    for (int i = 0; i < 512; ++i) bytes.push_back(static_cast<std::uint8_t>(random()));
    if (seed % 2 == 0) bytes[8] = static_cast<std::uint8_t>(seed % 16);  // a known opcode
    write_bytes(dir.file("magic_garbage.bin"), bytes);
    ReadResult result_garbage;
    ASSERT_NO_THROW(result_garbage = read_all(dir.file("magic_garbage.bin"))) << seed;
    EXPECT_FALSE(result_garbage.report.problems.empty()) << seed;
  }
}

TEST(McapReader, AFileThatCannotBeOpenedThrows) {
  EXPECT_THROW(read("/nonexistent-pmlsm-dir/none.mcap", {}), std::runtime_error);
  TempDir dir;
  EXPECT_THROW(read(dir.file(""), {}), std::runtime_error);  // a directory
}

// The spec requires readers to skip records they do not know; messages outside chunks are valid.
TEST(McapReader, UnknownOpcodesAreSkippedAndTopLevelMessagesRead) {
  TempDir dir;
  RawFile file;
  std::vector<std::uint8_t> inner;  // an uncompressed chunk's records, with an unknown one inside
  {
    RawFile records;
    records.record(0x05, RawFile::message_content(1, 3, {9, 9}));
    records.record(0x7A, {1, 2, 3});
    records.record(0x05, RawFile::message_content(1, 4, {}));
    inner = records.bytes();
  }
  file.magic()
      .record(0x01, RawFile::header_content())
      .record(0x80, {1, 2, 3, 4, 5})
      .record(0x03, RawFile::schema_content(1))
      .record(0x04, RawFile::channel_content(1, 1))
      .record(0x05, RawFile::message_content(1, 1, {0xAA, 0xBB}))
      .record(0xFF, {})
      .record(0x05, RawFile::message_content(1, 2, {0xCC}))
      .record(0x06, RawFile::chunk_content("", inner.size(), 0, inner))
      .finish();
  write_bytes(dir.file("raw.mcap"), file.bytes());
  const ReadResult result = read_all(dir.file("raw.mcap"));
  EXPECT_TRUE(result.report.complete()) << result.problems();
  ASSERT_EQ(result.messages.size(), 4U);
  EXPECT_EQ(result.messages[0].data, (std::vector<std::uint8_t>{0xAA, 0xBB}));
  EXPECT_EQ(result.messages[1].sequence, 2U);
  EXPECT_EQ(result.messages[1].log_time_ns, 1002U);
  EXPECT_EQ(result.messages[1].publish_time_ns, 2002U);
  EXPECT_EQ(result.messages[2].data, (std::vector<std::uint8_t>{9, 9}));
  EXPECT_TRUE(result.messages[3].data.empty());
  EXPECT_EQ(result.report.chunks, 1U);
}

// Chunks the reader cannot use are reported and skipped; the records after them are still read.
TEST(McapReader, UndecodableChunksAreReportedAndSkipped) {
  TempDir dir;
  const std::vector<std::uint8_t> junk = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16};
  struct Case {
    std::string compression;
    std::uint64_t uncompressed_size;
    std::string expected;
  };
  const Case cases[] = {
      {"brotli", 16, "unknown compression 'brotli'"},
      {"zstd", 100, "zstd"},
      {"lz4", 100, "lz4"},
      // A lying size must not make the reader allocate it: the data runs out first.
      {"zstd", std::uint64_t{1} << 50, "zstd"},
      {"lz4", std::uint64_t{1} << 50, "lz4"},
      {"", 17, "declared size"},
  };
  for (const Case& c : cases) {
    RawFile file;
    file.magic()
        .record(0x01, RawFile::header_content())
        .record(0x03, RawFile::schema_content(1))
        .record(0x04, RawFile::channel_content(0, 1))
        .record(0x06, RawFile::chunk_content(c.compression, c.uncompressed_size, 0, junk))
        .record(0x05, RawFile::message_content(0, 1, {1}))
        .finish();
    write_bytes(dir.file("chunk.mcap"), file.bytes());
    const ReadResult result = read_all(dir.file("chunk.mcap"));
    EXPECT_TRUE(has_problem(result, c.expected)) << c.compression << "\n" << result.problems();
    EXPECT_EQ(result.report.messages, 1U) << c.compression;
    EXPECT_EQ(result.report.chunks, 0U) << c.compression;
  }
}

TEST(McapReader, MessagesOfUndefinedChannelsAreDeliveredAndReportedOnce) {
  TempDir dir;
  RawFile file;
  file.magic()
      .record(0x01, RawFile::header_content())
      .record(0x05, RawFile::message_content(7, 1, {1}))
      .record(0x05, RawFile::message_content(7, 2, {2}))
      .finish();
  write_bytes(dir.file("undefined.mcap"), file.bytes());
  const ReadResult result = read_all(dir.file("undefined.mcap"));
  EXPECT_EQ(result.messages.size(), 2U);
  ASSERT_EQ(result.report.problems.size(), 1U) << result.problems();
  EXPECT_TRUE(has_problem(result, "channel 7")) << result.problems();
}

// A recorder killed by SIGKILL: the chunks it had flushed are in the file (written with write(),
// so in the page cache the moment flush_chunk() returns) and the reader returns all their
// messages; the open chunk is lost and the missing footer is reported.
TEST(McapCrash, ChunksFlushedBeforeSigkillAreReadable) {
  TempDir dir;
  const std::string path = dir.file("killed.mcap");
  constexpr std::uint32_t kFlushedChunks = 5;
  constexpr std::uint32_t kMessagesPerChunk = 10;
  constexpr std::uint32_t kReadyMarker = 0xFFFFFFFFU;

  int channel_fds[2];
  ASSERT_EQ(::pipe(channel_fds), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // The recorder: no gtest macros here, and it never returns into the test runner.
    ::close(channel_fds[0]);
    try {
      WriterOptions options;
      options.compression = Compression::zstd;
      Writer writer(path, options);
      const std::uint16_t channel = writer.add_channel(writer.add_schema("s", "omgidl", "x"), "/pmlsm/a", "cdr");
      std::uint32_t sequence = 0;
      const auto write_one = [&] {
        const std::vector<std::uint8_t> payload = sample_payload(sequence);
        writer.write(channel, sequence, 1000ULL * sequence, 1000ULL * sequence, payload.data(), payload.size());
        ++sequence;
      };
      for (std::uint32_t chunk = 1; chunk <= kFlushedChunks; ++chunk) {
        for (std::uint32_t i = 0; i < kMessagesPerChunk; ++i) write_one();
        writer.flush_chunk();
        if (::write(channel_fds[1], &chunk, sizeof chunk) != sizeof chunk) ::_exit(3);
      }
      for (std::uint32_t i = 0; i < 7; ++i) write_one();  // an open chunk, never flushed
      if (::write(channel_fds[1], &kReadyMarker, sizeof kReadyMarker) != sizeof kReadyMarker) ::_exit(3);
      for (;;) ::pause();  // until killed
    } catch (...) {
      ::_exit(2);
    }
  }
  ::close(channel_fds[1]);

  // Wait for the child's reports, with a deadline instead of sleeps.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  std::uint32_t last_report = 0;
  bool ready = false;
  while (!ready) {
    const auto left_ms =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()).count();
    if (left_ms <= 0) break;
    pollfd waiting{channel_fds[0], POLLIN, 0};
    if (::poll(&waiting, 1, static_cast<int>(left_ms)) <= 0) continue;
    std::uint32_t report = 0;
    if (::read(channel_fds[0], &report, sizeof report) != sizeof report) break;  // child died early
    if (report == kReadyMarker) {
      ready = true;
    } else {
      last_report = report;
    }
  }
  ::close(channel_fds[0]);
  ::kill(child, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(ready) << "the child reported " << last_report << " chunks, then stopped";
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "status " << status;

  const ReadResult result = read_all(path);
  EXPECT_FALSE(result.report.has_footer);
  EXPECT_TRUE(has_problem(result, "no footer")) << result.problems();
  EXPECT_EQ(result.report.chunks, kFlushedChunks);
  ASSERT_EQ(result.messages.size(), kFlushedChunks * kMessagesPerChunk);
  for (std::uint32_t i = 0; i < result.messages.size(); ++i) {
    EXPECT_EQ(result.messages[i].sequence, i);
    EXPECT_EQ(result.messages[i].data, sample_payload(i));
  }
  ASSERT_EQ(result.channels.size(), 1U);
  EXPECT_EQ(result.channels[0].topic, "/pmlsm/a");
}

}  // namespace
}  // namespace pmlsm::mcap::test

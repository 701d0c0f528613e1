// The MCAP writer and reader on whole files: what goes in comes out, with every compression; the
// summary an indexed reader relies on points where it says; compression really compresses; the
// writer's arguments are validated.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <iostream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "mcap_test_support.hpp"
#include "pmlsm/mcap/mcap.hpp"

namespace pmlsm::mcap::test {
namespace {

std::uint64_t le64(const std::vector<std::uint8_t>& bytes, std::size_t at) {
  std::uint64_t value = 0;
  for (std::size_t i = 0; i < 8; ++i) value |= static_cast<std::uint64_t>(bytes.at(at + i)) << (8 * i);
  return value;
}
std::uint32_t le32(const std::vector<std::uint8_t>& bytes, std::size_t at) {
  return static_cast<std::uint32_t>(le64(bytes, at) & 0xFFFFFFFFU);  // at() guards the 8-byte read
}
std::uint16_t le16(const std::vector<std::uint8_t>& bytes, std::size_t at) {
  return static_cast<std::uint16_t>(bytes.at(at) | (bytes.at(at + 1) << 8));
}

TEST(McapCompression, NamesRoundTripAndUnknownNamesAreRefused) {
  for (Compression compression : kAllCompressions) EXPECT_EQ(parse_compression(to_string(compression)), compression);
  try {
    parse_compression("brotli");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("brotli"), std::string::npos) << error.what();
  }
}

class McapRoundTrip : public ::testing::TestWithParam<Compression> {};

TEST_P(McapRoundTrip, SchemasChannelsAndMessagesComeBackExactly) {
  TempDir dir;
  const std::string path = dir.file("round_trip.mcap");
  WriterOptions options;
  options.compression = GetParam();
  options.chunk_size_bytes = 4096;  // many chunks
  options.profile = "ros2";

  std::vector<StoredMessage> written;
  WriterStatistics statistics;
  std::uint16_t schema_ids[2] = {};
  std::uint16_t channel_ids[3] = {};
  {
    Writer writer(path, options);
    schema_ids[0] = writer.add_schema("pmlsm_msgs::msg::A", "omgidl", "module pmlsm_msgs { struct A { double x; }; };");
    schema_ids[1] = writer.add_schema("pmlsm_msgs::msg::B", "omgidl", std::string("binary\0schema", 13));
    channel_ids[0] =
        writer.add_channel(schema_ids[0], "/pmlsm/a", "cdr", {{"offered_qos_profiles", "- reliable"}, {"k", ""}});
    channel_ids[1] = writer.add_channel(schema_ids[1], "/pmlsm/b", "cdr");
    channel_ids[2] = writer.add_channel(schema_ids[0], "/pmlsm/a2", "cdr", {{"note", "second channel, same schema"}});
    for (std::uint32_t i = 0; i < 2000; ++i) {
      // Log times mostly rising with a few stragglers, as from several publishers.
      const std::uint64_t log_time_ns = 1'000'000ULL * i + (i % 7 == 3 ? 0 : 500'000);
      StoredMessage message{channel_ids[i % 3], 10 * i, log_time_ns, log_time_ns - 1000,
                            i % 97 == 0 ? std::vector<std::uint8_t>{} : sample_payload(i)};
      writer.write(message.channel_id, message.sequence, message.log_time_ns, message.publish_time_ns,
                   message.data.empty() ? nullptr : message.data.data(), message.data.size());
      written.push_back(std::move(message));
    }
    writer.close();
    statistics = writer.statistics();
  }
  EXPECT_EQ(schema_ids[0], 1);
  EXPECT_EQ(schema_ids[1], 2);
  EXPECT_EQ(channel_ids[0], 0);
  EXPECT_EQ(channel_ids[2], 2);
  EXPECT_EQ(statistics.message_count, 2000U);
  EXPECT_GT(statistics.chunk_count, 5U);
  EXPECT_EQ(statistics.file_bytes, read_bytes(path).size());

  const ReadResult result = read_all(path);
  EXPECT_TRUE(result.report.complete()) << result.problems();
  EXPECT_TRUE(result.report.has_footer);
  EXPECT_EQ(result.report.messages, 2000U);
  EXPECT_EQ(result.report.chunks, statistics.chunk_count);
  EXPECT_FALSE(result.message_before_its_channel);

  ASSERT_EQ(result.schemas.size(), 2U);  // once each, although the summary repeats them
  EXPECT_EQ(result.schemas[0].id, 1);
  EXPECT_EQ(result.schemas[0].name, "pmlsm_msgs::msg::A");
  EXPECT_EQ(result.schemas[0].encoding, "omgidl");
  EXPECT_EQ(result.schemas[0].data, "module pmlsm_msgs { struct A { double x; }; };");
  EXPECT_EQ(result.schemas[1].data, std::string("binary\0schema", 13));

  ASSERT_EQ(result.channels.size(), 3U);
  EXPECT_EQ(result.channels[0].topic, "/pmlsm/a");
  EXPECT_EQ(result.channels[0].schema_id, 1);
  EXPECT_EQ(result.channels[0].message_encoding, "cdr");
  EXPECT_EQ(result.channels[0].metadata,
            (std::map<std::string, std::string>{{"offered_qos_profiles", "- reliable"}, {"k", ""}}));
  EXPECT_EQ(result.channels[1].schema_id, 2);
  EXPECT_TRUE(result.channels[1].metadata.empty());
  EXPECT_EQ(result.channels[2].metadata.at("note"), "second channel, same schema");

  ASSERT_EQ(result.messages.size(), written.size());
  for (std::size_t i = 0; i < written.size(); ++i) {
    ASSERT_EQ(result.messages[i], written[i]) << "message " << i;
  }
}

TEST_P(McapRoundTrip, ChunkPerMessageWhenTheChunkSizeIsTiny) {
  TempDir dir;
  const std::string path = dir.file("tiny_chunks.mcap");
  WriterOptions options;
  options.compression = GetParam();
  options.chunk_size_bytes = 1;  // every message fills a chunk
  Writer writer(path, options);
  const std::uint16_t channel = writer.add_channel(writer.add_schema("s", "omgidl", "x"), "/t", "cdr");
  for (std::uint32_t i = 0; i < 300; ++i) {
    const std::vector<std::uint8_t> payload = sample_payload(i);
    writer.write(channel, i, i, i, payload.data(), payload.size());
    ASSERT_EQ(writer.statistics().chunk_count, i + 1U);  // written at once, not held back
  }
  writer.close();
  const ReadResult result = read_all(path);
  EXPECT_TRUE(result.report.complete()) << result.problems();
  EXPECT_EQ(result.report.chunks, 300U);
  ASSERT_EQ(result.messages.size(), 300U);
  for (std::uint32_t i = 0; i < 300; ++i) EXPECT_EQ(result.messages[i].data, sample_payload(i));
}

TEST_P(McapRoundTrip, EmptyRecordingsAreCompleteFiles) {
  TempDir dir;
  WriterOptions options;
  options.compression = GetParam();
  {
    Writer writer(dir.file("nothing.mcap"), options);
    writer.flush_chunk();  // nothing open: no empty chunk
    writer.close();
    EXPECT_EQ(writer.statistics().chunk_count, 0U);
  }
  const ReadResult nothing = read_all(dir.file("nothing.mcap"));
  EXPECT_TRUE(nothing.report.complete()) << nothing.problems();
  EXPECT_EQ(nothing.report.messages, 0U);
  EXPECT_EQ(nothing.report.chunks, 0U);
  EXPECT_TRUE(nothing.schemas.empty());

  {
    Writer writer(dir.file("channels_only.mcap"), options);
    writer.add_channel(writer.add_schema("s", "omgidl", "struct S {};"), "/pmlsm/idle", "cdr");
  }  // closed by the destructor
  const ReadResult channels_only = read_all(dir.file("channels_only.mcap"));
  EXPECT_TRUE(channels_only.report.complete()) << channels_only.problems();
  EXPECT_EQ(channels_only.report.messages, 0U);
  EXPECT_EQ(channels_only.schemas.size(), 1U);
  ASSERT_EQ(channels_only.channels.size(), 1U);
  EXPECT_EQ(channels_only.channels[0].topic, "/pmlsm/idle");
}

TEST_P(McapRoundTrip, FlushChunkPutsTheOpenChunkInTheFileAtOnce) {
  TempDir dir;
  const std::string path = dir.file("flush.mcap");
  WriterOptions options;
  options.compression = GetParam();
  Writer writer(path, options);
  const std::uint16_t channel = writer.add_channel(writer.add_schema("s", "omgidl", "x"), "/t", "cdr");
  for (std::uint32_t i = 0; i < 3; ++i) {
    const std::vector<std::uint8_t> payload = sample_payload(i);
    writer.write(channel, i, i, i, payload.data(), payload.size());
  }
  EXPECT_EQ(read_all(path).report.messages, 0U);  // still in the open chunk
  writer.flush_chunk();
  EXPECT_EQ(writer.statistics().chunk_count, 1U);
  EXPECT_EQ(writer.statistics().file_bytes, read_bytes(path).size());  // nothing held in user space

  const ReadResult open_file = read_all(path);  // while the writer still has it open
  EXPECT_EQ(open_file.report.messages, 3U);
  EXPECT_FALSE(open_file.report.has_footer);
  ASSERT_EQ(open_file.report.problems.size(), 1U);
  EXPECT_NE(open_file.report.problems[0].find("no footer"), std::string::npos) << open_file.problems();

  writer.close();
  writer.close();  // idempotent
  EXPECT_TRUE(read_all(path).report.complete());
}

// The summary as an indexed reader (not ours: ours reads sequentially) uses it: each SummaryOffset
// names a group of records of its opcode; each ChunkIndex points at its Chunk and MessageIndex
// records; the Statistics agree with what was written; the footer CRC covers the summary.
TEST_P(McapRoundTrip, SummaryPointsAtTheRecordsItIndexes) {
  TempDir dir;
  const std::string path = dir.file("summary.mcap");
  const SampleFile sample = write_sample(path, GetParam(), 100, 16);
  const std::vector<std::uint8_t> bytes = read_bytes(path);
  ASSERT_EQ(bytes.size(), sample.file_bytes);

  const std::size_t footer = bytes.size() - 8 - (9 + 20);
  ASSERT_EQ(bytes[footer], 0x02);
  ASSERT_EQ(le64(bytes, footer + 1), 20U);
  const std::uint64_t summary_start = le64(bytes, footer + 9);
  const std::uint64_t summary_offset_start = le64(bytes, footer + 17);
  ASSERT_GT(summary_start, 13U);
  EXPECT_EQ(bytes[summary_start - 13], 0x0F) << "DataEnd right before the summary";
  ASSERT_LT(summary_start, summary_offset_start);
  ASSERT_LT(summary_offset_start, footer);

  std::map<std::uint8_t, std::pair<std::uint64_t, std::uint64_t>> groups;  // opcode -> start, length
  for (std::size_t at = summary_offset_start; at < footer;) {
    ASSERT_EQ(bytes[at], 0x0E);
    const std::uint64_t length = le64(bytes, at + 1);
    ASSERT_EQ(length, 17U);
    groups[bytes[at + 9]] = {le64(bytes, at + 10), le64(bytes, at + 18)};
    at += 9 + length;
  }
  for (std::uint8_t opcode : {0x03, 0x04, 0x0B, 0x08}) ASSERT_EQ(groups.count(opcode), 1U) << int(opcode);

  std::uint64_t summary_end = summary_start;
  std::size_t chunk_indexes = 0;
  std::uint64_t indexed_messages = 0;
  for (const auto& [opcode, group] : groups) {
    summary_end = std::max(summary_end, group.first + group.second);
    for (std::size_t at = group.first; at < group.first + group.second;) {
      ASSERT_EQ(bytes[at], opcode) << "record at " << at;
      const std::uint64_t length = le64(bytes, at + 1);
      const std::size_t c = at + 9;
      if (opcode == 0x08) {  // ChunkIndex
        ++chunk_indexes;
        const std::uint64_t chunk_start = le64(bytes, c + 16);
        const std::uint64_t chunk_length = le64(bytes, c + 24);
        EXPECT_EQ(bytes[chunk_start], 0x06);
        EXPECT_EQ(chunk_length, 9 + le64(bytes, chunk_start + 1));
        const std::uint32_t map_bytes = le32(bytes, c + 32);
        std::uint64_t first_index = UINT64_MAX;
        std::uint64_t index_bytes = 0;
        for (std::size_t e = c + 36; e < c + 36 + map_bytes; e += 10) {
          const std::uint16_t channel = le16(bytes, e);
          const std::uint64_t index_at = le64(bytes, e + 2);
          EXPECT_EQ(bytes[index_at], 0x07);
          EXPECT_EQ(le16(bytes, index_at + 9), channel);
          indexed_messages += le32(bytes, index_at + 11) / 16;
          first_index = std::min(first_index, index_at);
          index_bytes += 9 + le64(bytes, index_at + 1);
        }
        EXPECT_EQ(first_index, chunk_start + chunk_length) << "MessageIndex records follow their chunk";
        EXPECT_EQ(le64(bytes, c + 36 + map_bytes), index_bytes) << "message_index_length";
      } else if (opcode == 0x0B) {           // Statistics
        EXPECT_EQ(le64(bytes, c), 100U);     // message_count
        EXPECT_EQ(le16(bytes, c + 8), 1U);   // schema_count
        EXPECT_EQ(le32(bytes, c + 10), 3U);  // channel_count
        EXPECT_EQ(le32(bytes, c + 22), sample.statistics.chunk_count);
        EXPECT_EQ(le64(bytes, c + 26), 17U);                     // message_start_time
        EXPECT_EQ(le64(bytes, c + 34), 1'000'000ULL * 99 + 17);  // message_end_time
        EXPECT_EQ(le32(bytes, c + 42), 3U * 10);                 // channel_message_counts bytes
        EXPECT_EQ(le64(bytes, c + 46 + 2), 34U);                 // channel 0: messages 0, 3, ..., 99
      }
      at += 9 + length;
    }
  }
  EXPECT_EQ(summary_end, summary_offset_start);
  EXPECT_EQ(chunk_indexes, sample.statistics.chunk_count);
  EXPECT_EQ(indexed_messages, 100U);
}

// Compression on data that compresses (the ratio is a property of the data and the codec, not of
// timing). Two MotorFeedback-like streams of 92-byte messages at 1 kHz: "held", where the values
// change every 100 ticks and the counters step (a drive at standstill, status topics), and
// "moving", with full-precision doubles that change every tick, the hard case. The ratio is the
// uncompressed file's size over the compressed file's.
std::uint64_t telemetry_file_bytes(const std::string& path, Compression compression, bool moving) {
  WriterOptions options;
  options.compression = compression;
  Writer writer(path, options);
  const std::uint16_t channel = writer.add_channel(writer.add_schema("s", "omgidl", "x"), "/t", "cdr");
  std::vector<std::uint8_t> payload(4 + 3 * 8 + 6 * 8 + 8 + 4);
  payload[1] = 1;  // CDR encapsulation header: constant
  for (std::uint32_t tick = 0; tick < 20000; ++tick) {
    std::size_t at = 4;
    const auto put = [&](const void* value, std::size_t size) {
      std::memcpy(payload.data() + at, value, size);
      at += size;
    };
    const std::uint64_t stamp[3] = {tick, 1'000'000ULL * tick, 1'700'000'000'000'000'000ULL + 1'000'037ULL * tick};
    put(stamp, sizeof stamp);
    const double t_s = (moving ? tick : tick / 100 * 100) * 1e-3;
    const double values[6] = {std::round(0.05 * std::sin(t_s) * 1e6) * 1e-6,
                              0.05 * std::cos(t_s),
                              0.0,
                              1.5 * std::sin(2 * t_s),
                              20.0 * std::sin(2 * t_s),
                              20.0};
    put(values, sizeof values);
    const std::uint64_t applied = tick == 0 ? 0 : tick - 1;
    put(&applied, sizeof applied);
    const std::uint32_t status = 64;
    put(&status, sizeof status);
    writer.write(channel, tick, 1'000'000ULL * tick, 1'000'000ULL * tick, payload.data(), payload.size());
  }
  writer.close();
  EXPECT_TRUE(read_all(path).report.complete());
  return writer.statistics().file_bytes;
}

TEST(McapCompression, ZstdAndLz4ReallyCompressTelemetry) {
  TempDir dir;
  for (const bool moving : {false, true}) {
    const std::string kind = moving ? "moving" : "held";
    const auto bytes = [&](Compression compression) {
      return static_cast<double>(
          telemetry_file_bytes(dir.file(kind + to_string(compression) + ".mcap"), compression, moving));
    };
    const double none_bytes = bytes(Compression::none);
    const double zstd_ratio = none_bytes / bytes(Compression::zstd);
    const double lz4_ratio = none_bytes / bytes(Compression::lz4);
    std::cout << kind << " telemetry, uncompressed file / compressed file: zstd " << zstd_ratio << ", lz4 " << lz4_ratio
              << "\n";
    ::testing::Test::RecordProperty("ratio_zstd_" + kind, std::to_string(zstd_ratio));
    ::testing::Test::RecordProperty("ratio_lz4_" + kind, std::to_string(lz4_ratio));
    EXPECT_GT(zstd_ratio, moving ? 1.6 : 3.0) << kind;
    EXPECT_GT(lz4_ratio, moving ? 1.3 : 2.0) << kind;
    EXPECT_GT(zstd_ratio, lz4_ratio) << kind;
  }
}

TEST(McapWriter, ValidatesItsArguments) {
  TempDir dir;
  WriterOptions zero_chunk;
  zero_chunk.chunk_size_bytes = 0;
  EXPECT_THROW(Writer(dir.file("zero.mcap"), zero_chunk), std::invalid_argument);

  try {
    Writer writer("/nonexistent-pmlsm-dir/x.mcap", WriterOptions{});
    FAIL() << "no exception";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find("/nonexistent-pmlsm-dir/x.mcap"), std::string::npos) << error.what();
  }

  Writer writer(dir.file("w.mcap"), WriterOptions{});
  EXPECT_THROW(writer.add_channel(0, "/t", "cdr"), std::invalid_argument);  // 0 = "no schema": not ours
  EXPECT_THROW(writer.add_channel(1, "/t", "cdr"), std::invalid_argument);  // none added yet
  const std::uint16_t schema = writer.add_schema("s", "omgidl", "x");
  EXPECT_THROW(writer.add_channel(static_cast<std::uint16_t>(schema + 1), "/t", "cdr"), std::invalid_argument);
  const std::uint16_t channel = writer.add_channel(schema, "/t", "cdr");
  const std::uint8_t byte = 7;
  EXPECT_THROW(writer.write(static_cast<std::uint16_t>(channel + 1), 0, 0, 0, &byte, 1), std::invalid_argument);
  EXPECT_THROW(writer.write(channel, 0, 0, 0, nullptr, 1), std::invalid_argument);
  writer.write(channel, 0, 0, 0, &byte, 1);
  writer.close();
  EXPECT_THROW(writer.write(channel, 1, 1, 1, &byte, 1), std::runtime_error);
  EXPECT_THROW(writer.add_schema("s2", "omgidl", "x"), std::runtime_error);
  EXPECT_EQ(read_all(dir.file("w.mcap")).report.messages, 1U);
}

INSTANTIATE_TEST_SUITE_P(AllCompressions, McapRoundTrip, ::testing::ValuesIn(kAllCompressions), compression_test_name);

}  // namespace
}  // namespace pmlsm::mcap::test

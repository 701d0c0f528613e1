// Helpers of the MCAP tests: a scratch directory, a reader that keeps everything it was given, a
// deterministic sample recording, and a raw record builder for files our writer would not make.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "pmlsm/mcap/mcap.hpp"

namespace pmlsm::mcap::test {

/// A fresh directory under the system temp dir, removed with everything in it at scope end.
class TempDir {
 public:
  TempDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "pmlsm_mcap_test_XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed for " + pattern);
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

inline std::vector<std::uint8_t> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void write_bytes(const std::string& path, const std::uint8_t* data, std::size_t size) {
  // A new file rather than a truncated one: ext4 (auto_da_alloc) writes a file truncated and
  // rewritten back to disk on close, which makes the thousands of rewrites here I/O bound.
  std::error_code ignored;
  std::filesystem::remove(path, ignored);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!out) throw std::runtime_error("cannot write " + path);
}

inline void write_bytes(const std::string& path, const std::vector<std::uint8_t>& bytes) {
  write_bytes(path, bytes.data(), bytes.size());
}

/// A message as the reader delivered it, payload copied (the reader's pointer dies after the callback).
struct StoredMessage {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time_ns = 0;
  std::uint64_t publish_time_ns = 0;
  std::vector<std::uint8_t> data;

  bool operator==(const StoredMessage& other) const {
    return channel_id == other.channel_id && sequence == other.sequence && log_time_ns == other.log_time_ns &&
           publish_time_ns == other.publish_time_ns && data == other.data;
  }
};

struct ReadResult {
  ReadReport report;
  std::vector<Schema> schemas;
  std::vector<Channel> channels;
  std::vector<StoredMessage> messages;
  // Set when a message arrived on a channel whose Channel record had not been delivered yet.
  bool message_before_its_channel = false;

  std::string problems() const {
    std::string text;
    for (const std::string& problem : report.problems) text += "  " + problem + "\n";
    return text;
  }
};

inline ReadResult read_all(const std::string& path) {
  ReadResult result;
  std::map<std::uint16_t, bool> channel_seen;
  ReadCallbacks callbacks;
  callbacks.on_schema = [&](const Schema& schema) { result.schemas.push_back(schema); };
  callbacks.on_channel = [&](const Channel& channel) {
    result.channels.push_back(channel);
    channel_seen[channel.id] = true;
  };
  callbacks.on_message = [&](const Message& message) {
    if (!channel_seen[message.channel_id]) result.message_before_its_channel = true;
    result.messages.push_back({message.channel_id, message.sequence, message.log_time_ns, message.publish_time_ns,
                               std::vector<std::uint8_t>(message.data, message.data + message.size)});
  };
  result.report = read(path, callbacks);
  return result;
}

/// Payload of sample message `index`: telemetry-like (a counter, slowly changing values, constant
/// fields), so compressors see what a recording gives them. Sizes vary with the index.
inline std::vector<std::uint8_t> sample_payload(std::uint32_t index) {
  std::vector<std::uint8_t> payload(16 + (index % 5) * 8);
  for (std::size_t i = 0; i < payload.size(); ++i) {
    payload[i] = static_cast<std::uint8_t>(i < 4 ? (index >> (8 * i)) : (i * 7 + index / 16));
  }
  return payload;
}

/// A recording of `message_count` sample messages on three channels, with explicit flush_chunk()
/// every `messages_per_chunk` messages; the expected content and where each chunk ended.
struct SampleFile {
  std::vector<StoredMessage> messages;
  std::vector<std::uint64_t> chunk_end_bytes;        // file size after each flush_chunk()
  std::vector<std::uint64_t> messages_at_chunk_end;  // messages written by then
  WriterStatistics statistics;
  std::uint64_t file_bytes = 0;
};

inline SampleFile write_sample(const std::string& path, Compression compression, std::uint32_t message_count,
                               std::uint32_t messages_per_chunk) {
  SampleFile sample;
  WriterOptions options;
  options.compression = compression;
  options.chunk_size_bytes = 1U << 20;  // only the explicit flushes close chunks
  Writer writer(path, options);
  const std::uint16_t schema = writer.add_schema("test::Sample", "omgidl", "struct Sample { octet data[16]; };");
  const std::uint16_t channels[3] = {
      writer.add_channel(schema, "/pmlsm/a", "cdr"),
      writer.add_channel(schema, "/pmlsm/b", "cdr", {{"qos", "reliable"}}),
      writer.add_channel(schema, "/pmlsm/c", "cdr"),
  };
  for (std::uint32_t i = 0; i < message_count; ++i) {
    StoredMessage message{channels[i % 3], i, 1'000'000ULL * i + 17, 1'000'000ULL * i + 5, sample_payload(i)};
    writer.write(message.channel_id, message.sequence, message.log_time_ns, message.publish_time_ns,
                 message.data.data(), message.data.size());
    sample.messages.push_back(std::move(message));
    if ((i + 1) % messages_per_chunk == 0) {
      writer.flush_chunk();
      sample.chunk_end_bytes.push_back(writer.statistics().file_bytes);
      sample.messages_at_chunk_end.push_back(i + 1);
    }
  }
  writer.close();
  sample.statistics = writer.statistics();
  sample.file_bytes = writer.statistics().file_bytes;
  return sample;
}

/// Little-endian record building for hand-made files (unknown opcodes, bad chunks).
class RawFile {
 public:
  RawFile& magic() {
    for (const int byte : std::initializer_list<int>{0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'})
      bytes_.push_back(static_cast<std::uint8_t>(byte));
    return *this;
  }
  RawFile& record(std::uint8_t opcode, const std::vector<std::uint8_t>& content) {
    bytes_.push_back(opcode);
    u64(bytes_, content.size());
    // Not for an empty one: GCC 12 warns (-Wnonnull) about the null data pointer it would copy.
    if (!content.empty()) bytes_.insert(bytes_.end(), content.begin(), content.end());
    return *this;
  }
  const std::vector<std::uint8_t>& bytes() const { return bytes_; }

  static void u16(std::vector<std::uint8_t>& out, std::uint16_t v) { le(out, v, 2); }
  static void u32(std::vector<std::uint8_t>& out, std::uint32_t v) { le(out, v, 4); }
  static void u64(std::vector<std::uint8_t>& out, std::uint64_t v) { le(out, v, 8); }
  static void str(std::vector<std::uint8_t>& out, const std::string& s) {
    u32(out, static_cast<std::uint32_t>(s.size()));
    out.insert(out.end(), s.begin(), s.end());
  }

  static std::vector<std::uint8_t> header_content() {
    std::vector<std::uint8_t> c;
    str(c, "");
    str(c, "hand-made");
    return c;
  }
  static std::vector<std::uint8_t> schema_content(std::uint16_t id) {
    std::vector<std::uint8_t> c;
    u16(c, id);
    str(c, "test::Sample");
    str(c, "omgidl");
    str(c, "struct Sample {};");
    return c;
  }
  static std::vector<std::uint8_t> channel_content(std::uint16_t id, std::uint16_t schema_id) {
    std::vector<std::uint8_t> c;
    u16(c, id);
    u16(c, schema_id);
    str(c, "/pmlsm/raw");
    str(c, "cdr");
    u32(c, 0);  // empty metadata map
    return c;
  }
  static std::vector<std::uint8_t> message_content(std::uint16_t channel, std::uint32_t sequence,
                                                   const std::vector<std::uint8_t>& payload) {
    std::vector<std::uint8_t> c;
    u16(c, channel);
    u32(c, sequence);
    u64(c, 1000 + sequence);
    u64(c, 2000 + sequence);
    c.insert(c.end(), payload.begin(), payload.end());
    return c;
  }
  /// A Chunk with the given (already compressed, or not) records and header fields.
  static std::vector<std::uint8_t> chunk_content(const std::string& compression, std::uint64_t uncompressed_size,
                                                 std::uint32_t crc, const std::vector<std::uint8_t>& records) {
    std::vector<std::uint8_t> c;
    u64(c, 0);
    u64(c, 0);
    u64(c, uncompressed_size);
    u32(c, crc);
    str(c, compression);
    u64(c, records.size());
    c.insert(c.end(), records.begin(), records.end());
    return c;
  }
  /// DataEnd (no CRC), Footer without a summary, closing magic.
  RawFile& finish() {
    std::vector<std::uint8_t> data_end;
    u32(data_end, 0);
    record(0x0F, data_end);
    std::vector<std::uint8_t> footer;
    u64(footer, 0);
    u64(footer, 0);
    u32(footer, 0);
    record(0x02, footer);
    return magic();
  }

 private:
  static void le(std::vector<std::uint8_t>& out, std::uint64_t v, int bytes) {
    for (int i = 0; i < bytes; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  std::vector<std::uint8_t> bytes_;
};

inline const Compression kAllCompressions[] = {Compression::none, Compression::zstd, Compression::lz4};

inline std::string compression_test_name(const ::testing::TestParamInfo<Compression>& info) {
  return to_string(info.param);
}

}  // namespace pmlsm::mcap::test

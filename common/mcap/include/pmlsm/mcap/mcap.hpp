// MCAP files (https://mcap.dev/spec): the writer the recorder uses and the reader behind `play`
// and `plot`. Pure C++ (zstd, lz4), no DDS.
//
// Writer: Header, then Schema and Channel records in the data section as they are added, then
// messages in chunks (compressed zstd / lz4 / none, CRC of the uncompressed records), each chunk
// followed by its MessageIndex records; close() adds the summary (Schema, Channel, Statistics,
// ChunkIndex), SummaryOffset records and the Footer. Every finished chunk is written to the file
// at once, so a writer killed by SIGKILL leaves a file whose complete chunks are readable.
//
// Reader: reads the data section front to back and does not need the summary, so a truncated
// or unclosed file gives every whole chunk, and what is not whole is reported, never thrown.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace pmlsm::mcap {

enum class Compression { none, zstd, lz4 };

/// "none" | "zstd" | "lz4"; @throws std::invalid_argument naming the value otherwise.
Compression parse_compression(const std::string& name);
std::string to_string(Compression compression);

struct WriterOptions {
  Compression compression = Compression::zstd;
  std::size_t chunk_size_bytes = 1U << 20;  // uncompressed records per chunk before it is closed
  std::string profile;                      // Header.profile ("" = none; e.g. "ros2")
  std::string library = "pmlsm";            // Header.library
};

struct WriterStatistics {
  std::uint64_t message_count = 0;
  std::uint64_t chunk_count = 0;
  std::uint64_t uncompressed_message_bytes = 0;  // sum of message payload sizes
  std::uint64_t file_bytes = 0;                  // bytes written to the file so far
};

class Writer {
 public:
  /// Creates (truncates) the file and writes magic and Header.
  /// @throws std::runtime_error naming the path when it cannot be opened;
  ///         std::invalid_argument for a chunk size of 0.
  Writer(const std::string& path, WriterOptions options);
  /// Closes the file if close() was not called (errors are swallowed there).
  ~Writer();
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  /// @return the schema id (1, 2, ...). encoding e.g. "omgidl".
  std::uint16_t add_schema(const std::string& name, const std::string& encoding, const std::string& data);
  /// @return the channel id (0, 1, ...). schema_id must come from add_schema (else invalid_argument).
  std::uint16_t add_channel(std::uint16_t schema_id, const std::string& topic, const std::string& message_encoding,
                            const std::map<std::string, std::string>& metadata = {});
  /// Appends a message to the open chunk (closing it first when it is full).
  /// @throws std::invalid_argument for an unknown channel; std::runtime_error on a write error.
  void write(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time_ns, std::uint64_t publish_time_ns,
             const std::uint8_t* data, std::size_t size);
  /// Writes the open chunk now (e.g. on a timer, to bound what a crash can lose).
  void flush_chunk();
  /// Open chunk, summary, footer, closing magic; idempotent.
  void close();
  const WriterStatistics& statistics() const { return stats_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  WriterStatistics stats_;
};

struct Schema {
  std::uint16_t id = 0;
  std::string name;
  std::string encoding;
  std::string data;
};

struct Channel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;
  std::map<std::string, std::string> metadata;
};

struct Message {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time_ns = 0;
  std::uint64_t publish_time_ns = 0;
  const std::uint8_t* data = nullptr;  // valid only during the callback
  std::size_t size = 0;
};

struct ReadReport {
  std::uint64_t messages = 0;
  std::uint64_t chunks = 0;
  bool has_footer = false;            // the file was closed properly
  std::vector<std::string> problems;  // what was not whole or not valid, with byte offsets
  bool complete() const { return has_footer && problems.empty(); }
};

struct ReadCallbacks {
  std::function<void(const Schema&)> on_schema;  // each may be empty
  std::function<void(const Channel&)> on_channel;
  std::function<void(const Message&)> on_message;  // in file order (log-time order for our writer)
};

/// Reads the whole file. Never throws for bad content (it goes into problems); throws
/// std::runtime_error only when the file cannot be opened.
ReadReport read(const std::string& path, const ReadCallbacks& callbacks);

}  // namespace pmlsm::mcap

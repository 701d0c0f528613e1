// MCAP writer: Header, Schema/Channel records as they are added, messages in compressed chunks each
// followed by its MessageIndex records, and on close() the summary the indexed readers use.
//
// Durability: the file is written with POSIX write() and no user-space buffer, and each chunk with
// its MessageIndex records goes out in one write() call, so once a chunk is closed it sits in the
// OS page cache and a SIGKILL of the recorder cannot lose it (a power cut can; there is no fsync).

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <utility>

#include "pmlsm/mcap/mcap.hpp"
#include "wire.hpp"

namespace pmlsm::mcap {

using detail::begin_record;
using detail::end_record;
using detail::Opcode;
using detail::put_bytes;
using detail::put_string;
using detail::put_u16;
using detail::put_u32;
using detail::put_u64;
using detail::put_u8;

// One entry of a MessageIndex record. (Not in an anonymous namespace: Writer::Impl holds them,
// see -Wsubobject-linkage.)
struct IndexEntry {
  std::uint64_t log_time_ns;
  std::uint64_t offset_in_chunk_bytes;  // from the start of the chunk's uncompressed records
};

struct Writer::Impl {
  Impl(const std::string& path_in, WriterOptions options_in)
      : path(path_in),
        options(std::move(options_in)),
        compressor(options.compression),
        compression_name(options.compression == Compression::none ? "" : to_string(options.compression)) {}

  ~Impl() {
    if (fd >= 0) ::close(fd);
  }

  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  void open_file();
  void write_all(const std::vector<std::uint8_t>& bytes);
  void check_writable(const char* operation) const;
  void append_message(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time_ns,
                      std::uint64_t publish_time_ns, const std::uint8_t* data, std::size_t size);
  void write_chunk();
  void write_summary_and_footer();

  const std::string path;
  const WriterOptions options;
  int fd = -1;
  bool closed = false;
  bool failed = false;           // a write failed: the file's tail is undefined, write no more
  std::uint64_t file_bytes = 0;  // written so far = offset of the next record
  std::uint32_t data_crc = 0;    // CRC-32 of every byte written before the summary

  detail::Compressor compressor;
  const std::string compression_name;  // MCAP's name: "" for uncompressed chunks

  std::uint16_t schema_count = 0;
  std::vector<std::uint64_t> channel_message_counts;  // index = channel id
  std::uint64_t message_count = 0;
  std::uint64_t chunk_count = 0;
  std::uint64_t message_start_time_ns = 0;  // over the file; valid when message_count > 0
  std::uint64_t message_end_time_ns = 0;

  // The open chunk. All buffers are cleared, not freed, between chunks: once they have grown to
  // a chunk's size, writing a message allocates nothing.
  std::vector<std::uint8_t> chunk_records;
  std::uint64_t chunk_start_time_ns = 0;
  std::uint64_t chunk_end_time_ns = 0;
  std::vector<std::vector<IndexEntry>> chunk_index_entries;                    // index = channel id
  std::vector<std::pair<std::uint16_t, std::uint64_t>> message_index_offsets;  // of the chunk being written
  std::vector<std::uint8_t> output;  // a chunk record and its MessageIndex records, or the summary

  // Summary groups, kept as finished records (they are only ever appended to).
  std::vector<std::uint8_t> summary_schemas;
  std::vector<std::uint8_t> summary_channels;
  std::vector<std::uint8_t> summary_chunk_indexes;
};

void Writer::Impl::open_file() {
  fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    throw std::runtime_error("mcap: cannot create '" + path + "': " + std::strerror(errno));
  }
  output.clear();
  put_bytes(output, detail::kMagic.data(), detail::kMagic.size());
  const std::size_t header = begin_record(output, Opcode::header);
  put_string(output, options.profile);
  put_string(output, options.library);
  end_record(output, header);
  write_all(output);
}

void Writer::Impl::write_all(const std::vector<std::uint8_t>& bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t written = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (written < 0) {
      if (errno == EINTR) continue;
      failed = true;
      throw std::runtime_error("mcap: writing '" + path + "' at byte " + std::to_string(file_bytes + done) + ": " +
                               std::strerror(errno));
    }
    done += static_cast<std::size_t>(written);
  }
  data_crc = detail::crc32_update(data_crc, bytes.data(), bytes.size());
  file_bytes += bytes.size();
}

void Writer::Impl::check_writable(const char* operation) const {
  if (closed) throw std::runtime_error(std::string("mcap: ") + operation + " after close() of '" + path + "'");
  if (failed) {
    throw std::runtime_error(std::string("mcap: ") + operation + " on '" + path + "' after an earlier write error");
  }
}

void Writer::Impl::append_message(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time_ns,
                                  std::uint64_t publish_time_ns, const std::uint8_t* data, std::size_t size) {
  if (chunk_records.empty()) {
    chunk_start_time_ns = log_time_ns;
    chunk_end_time_ns = log_time_ns;
  } else {
    // Min and max, not first and last: messages from several publishers arrive slightly out of order.
    chunk_start_time_ns = std::min(chunk_start_time_ns, log_time_ns);
    chunk_end_time_ns = std::max(chunk_end_time_ns, log_time_ns);
  }
  chunk_index_entries[channel_id].push_back({log_time_ns, chunk_records.size()});

  const std::size_t record = begin_record(chunk_records, Opcode::message);
  put_u16(chunk_records, channel_id);
  put_u32(chunk_records, sequence);
  put_u64(chunk_records, log_time_ns);
  put_u64(chunk_records, publish_time_ns);
  put_bytes(chunk_records, data, size);
  end_record(chunk_records, record);

  if (message_count == 0) {
    message_start_time_ns = log_time_ns;
    message_end_time_ns = log_time_ns;
  } else {
    message_start_time_ns = std::min(message_start_time_ns, log_time_ns);
    message_end_time_ns = std::max(message_end_time_ns, log_time_ns);
  }
  ++message_count;
  ++channel_message_counts[channel_id];

  if (chunk_records.size() >= options.chunk_size_bytes) write_chunk();
}

void Writer::Impl::write_chunk() {
  if (chunk_records.empty()) return;
  const std::uint64_t chunk_start_offset = file_bytes;
  const std::uint32_t uncompressed_crc = detail::crc32_update(0, chunk_records.data(), chunk_records.size());

  output.clear();
  const std::size_t chunk = begin_record(output, Opcode::chunk);
  put_u64(output, chunk_start_time_ns);
  put_u64(output, chunk_end_time_ns);
  put_u64(output, chunk_records.size());
  put_u32(output, uncompressed_crc);
  put_string(output, compression_name);
  const std::size_t records_length_at = output.size();
  put_u64(output, 0);
  const std::size_t records_start = output.size();
  compressor.compress_append(chunk_records.data(), chunk_records.size(), output);
  const std::uint64_t compressed_bytes = output.size() - records_start;
  detail::patch_u64(output, records_length_at, compressed_bytes);
  end_record(output, chunk);
  const std::uint64_t chunk_length = output.size();

  // MessageIndex records right after the chunk (indexed readers read them as one block), one per
  // channel that has messages in it, in channel order.
  message_index_offsets.clear();
  for (std::size_t channel = 0; channel < chunk_index_entries.size(); ++channel) {
    const std::vector<IndexEntry>& entries = chunk_index_entries[channel];
    if (entries.empty()) continue;
    message_index_offsets.emplace_back(static_cast<std::uint16_t>(channel), chunk_start_offset + output.size());
    const std::size_t index = begin_record(output, Opcode::message_index);
    put_u16(output, static_cast<std::uint16_t>(channel));
    put_u32(output, static_cast<std::uint32_t>(entries.size() * 16));
    for (const IndexEntry& entry : entries) {
      put_u64(output, entry.log_time_ns);
      put_u64(output, entry.offset_in_chunk_bytes);
    }
    end_record(output, index);
  }
  const std::uint64_t message_index_length = output.size() - chunk_length;

  write_all(output);  // one write: the chunk is in the file whole or (on error) not usable at all

  const std::size_t chunk_index = begin_record(summary_chunk_indexes, Opcode::chunk_index);
  put_u64(summary_chunk_indexes, chunk_start_time_ns);
  put_u64(summary_chunk_indexes, chunk_end_time_ns);
  put_u64(summary_chunk_indexes, chunk_start_offset);
  put_u64(summary_chunk_indexes, chunk_length);
  put_u32(summary_chunk_indexes, static_cast<std::uint32_t>(message_index_offsets.size() * (2 + 8)));
  for (const auto& [channel, offset] : message_index_offsets) {
    put_u16(summary_chunk_indexes, channel);
    put_u64(summary_chunk_indexes, offset);
  }
  put_u64(summary_chunk_indexes, message_index_length);
  put_string(summary_chunk_indexes, compression_name);
  put_u64(summary_chunk_indexes, compressed_bytes);
  put_u64(summary_chunk_indexes, chunk_records.size());
  end_record(summary_chunk_indexes, chunk_index);

  ++chunk_count;
  chunk_records.clear();
  for (std::vector<IndexEntry>& entries : chunk_index_entries) entries.clear();
}

void Writer::Impl::write_summary_and_footer() {
  output.clear();
  // DataEnd closes the data section; its CRC covers every byte before it, magic included.
  const std::size_t data_end = begin_record(output, Opcode::data_end);
  put_u32(output, data_crc);
  end_record(output, data_end);

  const std::uint64_t summary_start = file_bytes + output.size();
  const std::size_t summary_start_in_output = output.size();

  // Each group's offset in the file and its length, for the SummaryOffset records.
  struct Group {
    Opcode opcode;
    std::uint64_t start;
    std::uint64_t length;
  };
  Group groups[4];
  std::size_t group_count = 0;
  const auto add_group = [&](Opcode opcode, const std::vector<std::uint8_t>& records) {
    if (records.empty()) return;
    groups[group_count++] = {opcode, file_bytes + output.size(), records.size()};
    put_bytes(output, records.data(), records.size());
  };
  add_group(Opcode::schema, summary_schemas);
  add_group(Opcode::channel, summary_channels);

  std::vector<std::uint8_t> statistics;
  const std::size_t record = begin_record(statistics, Opcode::statistics);
  put_u64(statistics, message_count);
  put_u16(statistics, schema_count);
  put_u32(statistics, static_cast<std::uint32_t>(channel_message_counts.size()));
  put_u32(statistics, 0);  // attachment_count
  put_u32(statistics, 0);  // metadata_count
  put_u32(statistics, static_cast<std::uint32_t>(chunk_count));
  put_u64(statistics, message_count > 0 ? message_start_time_ns : 0);
  put_u64(statistics, message_count > 0 ? message_end_time_ns : 0);
  // Every channel, those without messages too: a zero count is information, an absent one is not.
  put_u32(statistics, static_cast<std::uint32_t>(channel_message_counts.size() * (2 + 8)));
  for (std::size_t channel = 0; channel < channel_message_counts.size(); ++channel) {
    put_u16(statistics, static_cast<std::uint16_t>(channel));
    put_u64(statistics, channel_message_counts[channel]);
  }
  end_record(statistics, record);
  add_group(Opcode::statistics, statistics);
  add_group(Opcode::chunk_index, summary_chunk_indexes);

  const std::uint64_t summary_offset_start = file_bytes + output.size();
  for (std::size_t i = 0; i < group_count; ++i) {
    const std::size_t offset = begin_record(output, Opcode::summary_offset);
    put_u8(output, static_cast<std::uint8_t>(groups[i].opcode));
    put_u64(output, groups[i].start);
    put_u64(output, groups[i].length);
    end_record(output, offset);
  }

  // The footer's length goes in now, not patched at the end: the summary CRC covers it.
  put_u8(output, static_cast<std::uint8_t>(Opcode::footer));
  put_u64(output, detail::kFooterContentBytes);
  put_u64(output, summary_start);
  put_u64(output, summary_offset_start);
  // The summary CRC runs from the summary start through the footer's fields before the CRC.
  put_u32(output,
          detail::crc32_update(0, output.data() + summary_start_in_output, output.size() - summary_start_in_output));
  put_bytes(output, detail::kMagic.data(), detail::kMagic.size());
  write_all(output);
}

Writer::Writer(const std::string& path, WriterOptions options) {
  if (options.chunk_size_bytes == 0) {
    throw std::invalid_argument("mcap: chunk_size_bytes must be positive, got 0 (for '" + path + "')");
  }
  impl_ = std::make_unique<Impl>(path, std::move(options));
  impl_->open_file();
  stats_.file_bytes = impl_->file_bytes;
}

Writer::~Writer() {
  try {
    close();
  } catch (...) {
    // A destructor must not throw; whoever needs to know about write errors calls close().
  }
}

std::uint16_t Writer::add_schema(const std::string& name, const std::string& encoding, const std::string& data) {
  impl_->check_writable("add_schema");
  if (impl_->schema_count == std::numeric_limits<std::uint16_t>::max()) {
    throw std::length_error("mcap: '" + impl_->path + "' already has the maximum of 65535 schemas");
  }
  const auto id = static_cast<std::uint16_t>(impl_->schema_count + 1);  // 0 means "no schema" in MCAP
  std::vector<std::uint8_t>& output = impl_->output;
  output.clear();
  const std::size_t record = begin_record(output, Opcode::schema);
  put_u16(output, id);
  put_string(output, name);
  put_string(output, encoding);
  put_string(output, data);  // Schema data is uint32-length-prefixed bytes, the same layout
  end_record(output, record);
  // Into the data section now, so a file cut short still defines the schema before its messages.
  impl_->write_all(output);
  put_bytes(impl_->summary_schemas, output.data(), output.size());
  impl_->schema_count = id;
  stats_.file_bytes = impl_->file_bytes;
  return id;
}

std::uint16_t Writer::add_channel(std::uint16_t schema_id, const std::string& topic,
                                  const std::string& message_encoding,
                                  const std::map<std::string, std::string>& metadata) {
  impl_->check_writable("add_channel");
  if (schema_id == 0 || schema_id > impl_->schema_count) {
    throw std::invalid_argument("mcap: schema id " + std::to_string(schema_id) + " for topic '" + topic +
                                "' was not returned by add_schema (there are " + std::to_string(impl_->schema_count) +
                                " schemas)");
  }
  if (impl_->channel_message_counts.size() > std::numeric_limits<std::uint16_t>::max()) {
    throw std::length_error("mcap: '" + impl_->path + "' already has the maximum of 65536 channels");
  }
  const auto id = static_cast<std::uint16_t>(impl_->channel_message_counts.size());
  std::vector<std::uint8_t>& output = impl_->output;
  output.clear();
  const std::size_t record = begin_record(output, Opcode::channel);
  put_u16(output, id);
  put_u16(output, schema_id);
  put_string(output, topic);
  put_string(output, message_encoding);
  const std::size_t map_length_at = output.size();
  put_u32(output, 0);
  for (const auto& [key, value] : metadata) {
    put_string(output, key);
    put_string(output, value);
  }
  detail::patch_u32(output, map_length_at, static_cast<std::uint32_t>(output.size() - map_length_at - 4));
  end_record(output, record);
  impl_->write_all(output);
  put_bytes(impl_->summary_channels, output.data(), output.size());
  impl_->channel_message_counts.push_back(0);
  impl_->chunk_index_entries.emplace_back();
  stats_.file_bytes = impl_->file_bytes;
  return id;
}

void Writer::write(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time_ns,
                   std::uint64_t publish_time_ns, const std::uint8_t* data, std::size_t size) {
  impl_->check_writable("write");
  if (channel_id >= impl_->channel_message_counts.size()) {
    throw std::invalid_argument("mcap: unknown channel id " + std::to_string(channel_id) + " (there are " +
                                std::to_string(impl_->channel_message_counts.size()) + " channels in '" + impl_->path +
                                "')");
  }
  if (data == nullptr && size > 0) {
    throw std::invalid_argument("mcap: null data with size " + std::to_string(size) + " on channel " +
                                std::to_string(channel_id));
  }
  impl_->append_message(channel_id, sequence, log_time_ns, publish_time_ns, data, size);
  ++stats_.message_count;
  stats_.uncompressed_message_bytes += size;
  stats_.chunk_count = impl_->chunk_count;
  stats_.file_bytes = impl_->file_bytes;
}

void Writer::flush_chunk() {
  impl_->check_writable("flush_chunk");
  impl_->write_chunk();
  stats_.chunk_count = impl_->chunk_count;
  stats_.file_bytes = impl_->file_bytes;
}

void Writer::close() {
  if (!impl_ || impl_->closed) return;
  impl_->closed = true;  // even if what follows throws: a second attempt would only add garbage
  if (!impl_->failed) {
    impl_->write_chunk();
    impl_->write_summary_and_footer();
    stats_.chunk_count = impl_->chunk_count;
    stats_.file_bytes = impl_->file_bytes;
  }
  const int fd = std::exchange(impl_->fd, -1);
  if (::close(fd) != 0 && !impl_->failed) {
    throw std::runtime_error("mcap: closing '" + impl_->path + "': " + std::strerror(errno));
  }
}

}  // namespace pmlsm::mcap

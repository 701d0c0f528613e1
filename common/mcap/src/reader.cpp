// MCAP reader for `play` and `plot`: walks the data section front to back, inside chunks too, and
// needs neither summary nor footer, so a recording whose writer was killed gives every whole chunk.
// What is cut off, corrupt or unknown becomes a problem text with its byte offset: the reader never
// throws for file content, never reads outside what it has read from the file, and skips what the
// spec says to skip (unknown opcodes, indexes it does not need).
//
// The file is read with pread() into reused buffers rather than mapped: a file that shrinks while
// it is read (or sits on a flaky disk) then gives a short read to report instead of a SIGBUS.

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <map>
#include <new>
#include <stdexcept>
#include <utility>
#include <vector>

#include "pmlsm/mcap/mcap.hpp"
#include "wire.hpp"

namespace pmlsm::mcap {

namespace {

using detail::Cursor;
using detail::Opcode;

// Enough to see what went wrong; a file of garbage chunks must not give a million lines.
constexpr std::size_t kMaxListedProblems = 100;
// Records the reader does not interpret are still read for the data CRC, in pieces of this size.
constexpr std::size_t kSkipPieceBytes = std::size_t{1} << 20;

std::string hex32(std::uint32_t value) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%08x", static_cast<unsigned>(value));
  return text;
}

/// The open file, read at explicit offsets.
class File {
 public:
  explicit File(const std::string& path) : path_(path) {
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) throw std::runtime_error("mcap: cannot open '" + path + "': " + std::strerror(errno));
    struct stat status {};
    if (::fstat(fd_, &status) != 0) {
      const int error = errno;
      ::close(fd_);
      throw std::runtime_error("mcap: cannot stat '" + path + "': " + std::strerror(error));
    }
    if (S_ISDIR(status.st_mode)) {
      ::close(fd_);
      throw std::runtime_error("mcap: cannot read '" + path + "': it is a directory");
    }
    size_bytes_ = static_cast<std::uint64_t>(status.st_size);
  }
  ~File() { ::close(fd_); }
  File(const File&) = delete;
  File& operator=(const File&) = delete;

  /// Size when opened: bytes appended later by a live writer are not read.
  std::uint64_t size() const { return size_bytes_; }

  /// Reads [offset, offset + size) into out[0, size) (out only grows).
  /// @return "" or what failed (I/O error, file shrank, no memory).
  std::string read(std::uint64_t offset, std::size_t size, std::vector<std::uint8_t>& out) {
    if (out.size() < size) {
      try {
        out.resize(size);
      } catch (const std::bad_alloc&) {
        return "cannot allocate " + std::to_string(size) + " bytes to read it";
      }
    }
    std::size_t done = 0;
    while (done < size) {
      const ssize_t got = ::pread(fd_, out.data() + done, size - done, static_cast<off_t>(offset + done));
      if (got < 0) {
        if (errno == EINTR) continue;
        return "read error at byte " + std::to_string(offset + done) + ": " + std::strerror(errno);
      }
      if (got == 0) return "the file shrank to " + std::to_string(offset + done) + " bytes while it was read";
      done += static_cast<std::size_t>(got);
    }
    return "";
  }

 private:
  std::string path_;
  int fd_ = -1;
  std::uint64_t size_bytes_ = 0;
};

/// One pass over the file; the state is per call of read(), no globals.
class Walk {
 public:
  Walk(const std::string& path, const ReadCallbacks& callbacks) : file_(path), callbacks_(callbacks) {}

  ReadReport run();

 private:
  // Where a record sits, for problem texts: top-level ("Chunk at byte 812") or inside a chunk
  // ("Message at offset 40 of the chunk at byte 812").
  struct Where {
    std::uint64_t offset;
    std::uint64_t chunk_offset;  // the enclosing chunk's file offset, when in_chunk
    bool in_chunk;
  };
  static std::string describe(std::uint8_t opcode, const Where& where);

  void problem(std::string text);
  bool read_magic();
  void walk_records();
  bool skip_content(std::uint64_t offset, std::uint64_t length);
  void handle(std::uint8_t opcode, const std::uint8_t* content, std::size_t size, const Where& where);
  void handle_chunk(const std::uint8_t* content, std::size_t size, std::uint64_t offset);
  void handle_schema(const std::uint8_t* content, std::size_t size, const Where& where);
  void handle_channel(const std::uint8_t* content, std::size_t size, const Where& where);
  void handle_message(const std::uint8_t* content, std::size_t size, const Where& where);
  void handle_footer(const std::uint8_t* content, std::size_t size, std::uint64_t offset);
  void check_summary_crc(std::uint64_t summary_start, std::uint64_t footer_offset, std::uint32_t stored_crc);

  File file_;
  const ReadCallbacks& callbacks_;
  ReadReport report_;
  std::size_t unlisted_problems_ = 0;

  bool in_data_section_ = true;            // until DataEnd: what the data CRC covers
  std::uint64_t data_end_end_offset_ = 0;  // where the summary starts; 0 until DataEnd is seen
  std::uint32_t data_crc_ = 0;
  bool footer_seen_ = false;
  bool statistics_seen_ = false;
  std::uint64_t statistics_message_count_ = 0;

  std::map<std::uint16_t, Schema> schemas_;
  std::map<std::uint16_t, Channel> channels_;
  std::vector<bool> undefined_channel_reported_ = std::vector<bool>(65536, false);

  detail::Decompressor decompressor_;
  std::vector<std::uint8_t> record_;  // the current top-level record's content
  std::vector<std::uint8_t> chunk_;   // the current chunk's uncompressed records
  std::vector<std::uint8_t> piece_;   // skipped records and the summary, for their CRCs
};

std::string Walk::describe(std::uint8_t opcode, const Where& where) {
  if (where.in_chunk) {
    return detail::opcode_name(opcode) + " at offset " + std::to_string(where.offset) + " of the chunk at byte " +
           std::to_string(where.chunk_offset);
  }
  return detail::opcode_name(opcode) + " at byte " + std::to_string(where.offset);
}

void Walk::problem(std::string text) {
  if (report_.problems.size() < kMaxListedProblems) {
    report_.problems.push_back(std::move(text));
  } else {
    ++unlisted_problems_;
  }
}

ReadReport Walk::run() {
  if (read_magic()) walk_records();
  if (unlisted_problems_ > 0) {
    report_.problems.push_back("... and " + std::to_string(unlisted_problems_) + " further problems");
  }
  return std::move(report_);
}

bool Walk::read_magic() {
  const std::size_t magic_bytes = detail::kMagic.size();
  if (file_.size() < magic_bytes) {
    problem("not an MCAP file: " + std::to_string(file_.size()) + " bytes, fewer than the 8-byte magic");
    return false;
  }
  const std::string error = file_.read(0, magic_bytes, record_);
  if (!error.empty()) {
    problem("magic at byte 0: " + error);
    return false;
  }
  if (!std::equal(detail::kMagic.begin(), detail::kMagic.end(), record_.begin())) {
    char text[64];
    std::snprintf(text, sizeof text, "%02x %02x %02x %02x %02x %02x %02x %02x", record_[0], record_[1], record_[2],
                  record_[3], record_[4], record_[5], record_[6], record_[7]);
    problem(std::string("not an MCAP file: bad magic at byte 0 (") + text + ", expected 89 4d 43 41 50 30 0d 0a)");
    return false;
  }
  data_crc_ = detail::crc32_update(0, record_.data(), magic_bytes);
  return true;
}

bool Walk::skip_content(std::uint64_t offset, std::uint64_t length) {
  // Only the data CRC needs these bytes; past DataEnd nothing does.
  if (!in_data_section_) return true;
  while (length > 0) {
    const auto piece = static_cast<std::size_t>(std::min<std::uint64_t>(length, kSkipPieceBytes));
    const std::string error = file_.read(offset, piece, piece_);
    if (!error.empty()) {
      problem("record content at byte " + std::to_string(offset) + ": " + error);
      return false;
    }
    data_crc_ = detail::crc32_update(data_crc_, piece_.data(), piece);
    offset += piece;
    length -= piece;
  }
  return true;
}

// One loop over the file's records, a case per MCAP opcode (the specification's list), each
// case a few lines; kept whole so the record walk reads as the format does.
// NOLINTNEXTLINE(readability-function-size)
void Walk::walk_records() {
  std::uint64_t offset = detail::kMagic.size();
  const std::uint64_t end = file_.size();
  std::uint8_t header[detail::kRecordHeaderBytes];
  bool first = true;

  while (offset < end && !footer_seen_) {
    const std::uint64_t remaining = end - offset;
    const auto header_bytes = static_cast<std::size_t>(std::min<std::uint64_t>(remaining, sizeof header));
    std::string error = file_.read(offset, header_bytes, record_);
    if (!error.empty()) {
      problem("record at byte " + std::to_string(offset) + ": " + error);
      return;
    }
    const std::uint8_t opcode = record_[0];
    const Where where{offset, 0, false};
    if (header_bytes < sizeof header) {
      problem(describe(opcode, where) + ": file ends " + std::to_string(sizeof header - header_bytes) +
              " bytes short of the record header");
      break;
    }
    std::memcpy(header, record_.data(), sizeof header);
    Cursor length_field(header + 1, 8);
    const std::uint64_t length = length_field.u64();
    if (length > remaining - sizeof header) {
      problem(describe(opcode, where) + ": file ends " + std::to_string(length - (remaining - sizeof header)) +
              " bytes short (record of " + std::to_string(length) + " bytes)");
      break;
    }
    if (first && opcode != static_cast<std::uint8_t>(Opcode::header)) {
      problem("the first record (" + describe(opcode, where) + ") is not a Header");
    }
    first = false;

    const std::uint64_t content_offset = offset + sizeof header;
    // The data CRC covers everything before the DataEnd record, not DataEnd itself.
    if (in_data_section_ && opcode != static_cast<std::uint8_t>(Opcode::data_end)) {
      data_crc_ = detail::crc32_update(data_crc_, header, sizeof header);
    }

    switch (static_cast<Opcode>(opcode)) {
      case Opcode::header:
      case Opcode::schema:
      case Opcode::channel:
      case Opcode::message:
      case Opcode::chunk:
      case Opcode::statistics:
      case Opcode::data_end:
      case Opcode::footer: {
        // The records the reader interprets: read whole (length is within the file, checked above).
        const auto size = static_cast<std::size_t>(length);
        error = file_.read(content_offset, size, record_);
        if (!error.empty()) {
          problem(describe(opcode, where) + ": " + error);
          return;
        }
        if (opcode == static_cast<std::uint8_t>(Opcode::data_end) && !in_data_section_) {
          problem(describe(opcode, where) + ": a second DataEnd record; ignored");
        } else if (opcode == static_cast<std::uint8_t>(Opcode::data_end)) {
          Cursor fields(record_.data(), size);
          const std::uint32_t stored_crc = fields.u32();
          if (!fields.ok()) {
            problem(describe(opcode, where) + ": malformed (" + std::to_string(size) + " bytes)");
          } else if (stored_crc != 0 && stored_crc != data_crc_) {
            problem(describe(opcode, where) + ": data section CRC mismatch: stored " + hex32(stored_crc) +
                    ", computed " + hex32(data_crc_) + " (the data section is corrupt)");
          }
          in_data_section_ = false;
          data_end_end_offset_ = content_offset + length;
        } else if (in_data_section_) {
          data_crc_ = detail::crc32_update(data_crc_, record_.data(), size);
        }
        if (opcode == static_cast<std::uint8_t>(Opcode::footer)) {
          handle_footer(record_.data(), size, offset);
        } else if (opcode != static_cast<std::uint8_t>(Opcode::data_end)) {
          handle(opcode, record_.data(), size, where);
        }
        break;
      }
      default:
        // Indexes, attachments, metadata and opcodes this reader does not know: skipped (the spec
        // requires readers to skip unknown records), read only for the data CRC.
        if (!skip_content(content_offset, length)) return;
        break;
    }
    offset = content_offset + length;
  }

  if (!footer_seen_) {
    problem("no footer: the recording was not closed (the file ends at byte " + std::to_string(end) + " after " +
            std::to_string(report_.chunks) + " whole chunks; its writer was killed or is still writing)");
  }
}

void Walk::handle(std::uint8_t opcode, const std::uint8_t* content, std::size_t size, const Where& where) {
  switch (static_cast<Opcode>(opcode)) {
    case Opcode::schema: handle_schema(content, size, where); break;
    case Opcode::channel: handle_channel(content, size, where); break;
    case Opcode::message: handle_message(content, size, where); break;
    case Opcode::chunk:
      if (where.in_chunk) {
        problem(describe(opcode, where) + ": a chunk inside a chunk is not allowed; skipped");
      } else {
        handle_chunk(content, size, where.offset);
      }
      break;
    case Opcode::statistics: {
      Cursor fields(content, size);
      statistics_message_count_ = fields.u64();
      if (fields.ok()) {
        statistics_seen_ = true;
      } else {
        problem(describe(opcode, where) + ": malformed (" + std::to_string(size) + " bytes)");
      }
      break;
    }
    default: break;  // Header (nothing needed from it), and inside chunks whatever else: skipped
  }
}

void Walk::handle_chunk(const std::uint8_t* content, std::size_t size, std::uint64_t offset) {
  const std::string name = "chunk at byte " + std::to_string(offset);
  Cursor fields(content, size);
  fields.u64();  // message_start_time: not needed to read messages in file order
  fields.u64();  // message_end_time
  const std::uint64_t uncompressed_size = fields.u64();
  const std::uint32_t stored_crc = fields.u32();
  const std::string compression = fields.string();
  const std::uint64_t records_length = fields.u64();
  const std::uint8_t* records = fields.bytes(records_length);
  if (!fields.ok()) {
    problem(name + ": malformed (its fields run past its " + std::to_string(size) + " bytes); skipped");
    return;
  }

  const std::uint8_t* data = records;
  std::size_t data_size = static_cast<std::size_t>(records_length);
  if (compression.empty() || compression == "none") {
    // Uncompressed: the records are used in place.
    if (records_length != uncompressed_size) {
      problem(name + ": uncompressed records of " + std::to_string(records_length) + " bytes but a declared size of " +
              std::to_string(uncompressed_size) + "; skipped");
      return;
    }
  } else {
    const std::string error = decompressor_.decompress(compression, records, data_size, uncompressed_size, chunk_);
    if (!error.empty()) {
      problem(name + ": " + error + "; its messages are skipped");
      return;
    }
    data = chunk_.data();
    data_size = static_cast<std::size_t>(uncompressed_size);
  }
  if (stored_crc != 0) {
    const std::uint32_t computed_crc = detail::crc32_update(0, data, data_size);
    if (computed_crc != stored_crc) {
      problem(name + ": CRC mismatch of its uncompressed records: stored " + hex32(stored_crc) + ", computed " +
              hex32(computed_crc) + " (corrupt data); its messages are skipped");
      return;
    }
  }

  std::size_t position = 0;
  while (position < data_size) {
    const std::size_t remaining = data_size - position;
    const Where where{position, offset, true};
    if (remaining < detail::kRecordHeaderBytes) {
      problem(describe(data[position], where) + ": the chunk ends " +
              std::to_string(detail::kRecordHeaderBytes - remaining) + " bytes short of the record header");
      return;
    }
    Cursor header(data + position, detail::kRecordHeaderBytes);
    const std::uint8_t opcode = header.u8();
    const std::uint64_t length = header.u64();
    if (length > remaining - detail::kRecordHeaderBytes) {
      problem(describe(opcode, where) + ": runs " + std::to_string(length - (remaining - detail::kRecordHeaderBytes)) +
              " bytes past the end of the chunk");
      return;
    }
    handle(opcode, data + position + detail::kRecordHeaderBytes, static_cast<std::size_t>(length), where);
    position += detail::kRecordHeaderBytes + static_cast<std::size_t>(length);
  }
  ++report_.chunks;
}

void Walk::handle_schema(const std::uint8_t* content, std::size_t size, const Where& where) {
  Cursor fields(content, size);
  Schema schema;
  schema.id = fields.u16();
  schema.name = fields.string();
  schema.encoding = fields.string();
  schema.data = fields.string();
  if (!fields.ok()) {
    problem(describe(static_cast<std::uint8_t>(Opcode::schema), where) + ": malformed; skipped");
    return;
  }
  const auto known = schemas_.find(schema.id);
  if (known != schemas_.end()) {
    // Repeated in the summary and, by some writers, in every chunk: the same record again is normal.
    const Schema& first = known->second;
    if (first.name != schema.name || first.encoding != schema.encoding || first.data != schema.data) {
      problem(describe(static_cast<std::uint8_t>(Opcode::schema), where) + ": redefines schema " +
              std::to_string(schema.id) + " differently; the first definition is kept");
    }
    return;
  }
  const Schema& stored = schemas_.emplace(schema.id, std::move(schema)).first->second;
  if (callbacks_.on_schema) callbacks_.on_schema(stored);
}

void Walk::handle_channel(const std::uint8_t* content, std::size_t size, const Where& where) {
  Cursor fields(content, size);
  Channel channel;
  channel.id = fields.u16();
  channel.schema_id = fields.u16();
  channel.topic = fields.string();
  channel.message_encoding = fields.string();
  channel.metadata = fields.string_map();
  if (!fields.ok()) {
    problem(describe(static_cast<std::uint8_t>(Opcode::channel), where) + ": malformed; skipped");
    return;
  }
  const auto known = channels_.find(channel.id);
  if (known != channels_.end()) {
    const Channel& first = known->second;
    if (first.schema_id != channel.schema_id || first.topic != channel.topic ||
        first.message_encoding != channel.message_encoding || first.metadata != channel.metadata) {
      problem(describe(static_cast<std::uint8_t>(Opcode::channel), where) + ": redefines channel " +
              std::to_string(channel.id) + " differently; the first definition is kept");
    }
    return;
  }
  if (channel.schema_id != 0 && schemas_.count(channel.schema_id) == 0) {
    problem(describe(static_cast<std::uint8_t>(Opcode::channel), where) + ": channel " + std::to_string(channel.id) +
            " ('" + channel.topic + "') refers to schema " + std::to_string(channel.schema_id) +
            ", not defined before it");
  }
  const Channel& stored = channels_.emplace(channel.id, std::move(channel)).first->second;
  if (callbacks_.on_channel) callbacks_.on_channel(stored);
}

void Walk::handle_message(const std::uint8_t* content, std::size_t size, const Where& where) {
  if (size < detail::kMessagePrefixBytes) {
    problem(describe(static_cast<std::uint8_t>(Opcode::message), where) + ": malformed (" + std::to_string(size) +
            " bytes, fewer than its 22-byte fields); skipped");
    return;
  }
  Cursor fields(content, size);
  Message message;
  message.channel_id = fields.u16();
  message.sequence = fields.u32();
  message.log_time_ns = fields.u64();
  message.publish_time_ns = fields.u64();
  message.data = content + detail::kMessagePrefixBytes;
  message.size = size - detail::kMessagePrefixBytes;
  if (channels_.count(message.channel_id) == 0 && !undefined_channel_reported_[message.channel_id]) {
    // Delivered anyway (the payload is intact); reported once per channel, not once per message.
    undefined_channel_reported_[message.channel_id] = true;
    problem(describe(static_cast<std::uint8_t>(Opcode::message), where) + ": channel " +
            std::to_string(message.channel_id) + " was not defined before its first message");
  }
  ++report_.messages;
  if (callbacks_.on_message) callbacks_.on_message(message);
}

void Walk::handle_footer(const std::uint8_t* content, std::size_t size, std::uint64_t offset) {
  footer_seen_ = true;  // whatever follows, the walk ends here
  const std::string name = "Footer at byte " + std::to_string(offset);
  Cursor fields(content, size);
  const std::uint64_t summary_start = fields.u64();
  fields.u64();  // summary_offset_start: the sequential walk does not need it
  const std::uint32_t summary_crc = fields.u32();
  if (!fields.ok()) {
    problem(name + ": malformed (" + std::to_string(size) + " bytes)");
    return;
  }

  const std::uint64_t magic_offset = offset + detail::kRecordHeaderBytes + size;
  const std::uint64_t magic_bytes = detail::kMagic.size();
  const std::uint64_t left = file_.size() - magic_offset;
  if (left < magic_bytes) {
    problem("closing magic at byte " + std::to_string(magic_offset) + ": file ends " +
            std::to_string(magic_bytes - left) + " bytes short");
    return;
  }
  const std::string error = file_.read(magic_offset, magic_bytes, piece_);
  if (!error.empty()) {
    problem("closing magic at byte " + std::to_string(magic_offset) + ": " + error);
    return;
  }
  if (!std::equal(detail::kMagic.begin(), detail::kMagic.end(), piece_.begin())) {
    problem("closing magic at byte " + std::to_string(magic_offset) + ": wrong bytes");
    return;
  }
  if (left > magic_bytes) {
    problem(std::to_string(left - magic_bytes) + " bytes after the closing magic at byte " +
            std::to_string(magic_offset));
  }
  report_.has_footer = true;

  if (data_end_end_offset_ == 0) {
    problem(name + ": no DataEnd record before it (the data section is not closed)");
  } else if (summary_start != 0 && summary_start != data_end_end_offset_) {
    problem(name + ": summary_start " + std::to_string(summary_start) + " is not where the DataEnd record ends (" +
            std::to_string(data_end_end_offset_) + ")");
  }
  if (summary_crc != 0 && summary_start != 0) check_summary_crc(summary_start, offset, summary_crc);
  if (statistics_seen_ && statistics_message_count_ != report_.messages) {
    problem("the Statistics record counts " + std::to_string(statistics_message_count_) + " messages, " +
            std::to_string(report_.messages) + " were read");
  }
}

void Walk::check_summary_crc(std::uint64_t summary_start, std::uint64_t footer_offset, std::uint32_t stored_crc) {
  // Covers the summary and summary-offset sections and the footer up to its CRC field.
  const std::uint64_t covered_end = footer_offset + detail::kRecordHeaderBytes + 8 + 8;
  if (summary_start > footer_offset) {
    problem("Footer at byte " + std::to_string(footer_offset) + ": summary_start " + std::to_string(summary_start) +
            " lies after the footer");
    return;
  }
  std::uint32_t crc = 0;
  for (std::uint64_t at = summary_start; at < covered_end;) {
    const auto piece = static_cast<std::size_t>(std::min<std::uint64_t>(covered_end - at, kSkipPieceBytes));
    const std::string error = file_.read(at, piece, piece_);
    if (!error.empty()) {
      problem("summary at byte " + std::to_string(at) + ": " + error);
      return;
    }
    crc = detail::crc32_update(crc, piece_.data(), piece);
    at += piece;
  }
  if (crc != stored_crc) {
    problem("summary CRC mismatch: stored " + hex32(stored_crc) + ", computed " + hex32(crc) +
            " (the summary is corrupt; the messages were read without it)");
  }
}

}  // namespace

ReadReport read(const std::string& path, const ReadCallbacks& callbacks) {
  Walk walk(path, callbacks);  // throws only when the file cannot be opened
  return walk.run();
}

}  // namespace pmlsm::mcap

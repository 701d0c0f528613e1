// Private to pmlsm_mcap: the MCAP byte layout (https://mcap.dev/spec) shared by the writer and the
// reader: opcodes, little-endian encoding into growing buffers, a bounds-checked decoding cursor,
// CRC-32 and the chunk codecs. Nothing here is installed or seen by users of mcap.hpp.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "pmlsm/mcap/mcap.hpp"

// The codec contexts are opaque C structs; only pointers to them appear here.
struct ZSTD_CCtx_s;
struct ZSTD_DCtx_s;
struct LZ4F_cctx_s;
struct LZ4F_dctx_s;

namespace pmlsm::mcap::detail {

/// "\x89MCAP0\r\n": the first and the last 8 bytes of every MCAP file (major version '0').
inline constexpr std::array<std::uint8_t, 8> kMagic{0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

enum class Opcode : std::uint8_t {
  header = 0x01,
  footer = 0x02,
  schema = 0x03,
  channel = 0x04,
  message = 0x05,
  chunk = 0x06,
  message_index = 0x07,
  chunk_index = 0x08,
  attachment = 0x09,
  attachment_index = 0x0A,
  statistics = 0x0B,
  metadata = 0x0C,
  metadata_index = 0x0D,
  summary_offset = 0x0E,
  data_end = 0x0F,
};

/// Every record starts with its opcode (1 byte) and its content length (uint64).
inline constexpr std::size_t kRecordHeaderBytes = 1 + 8;
/// Message record content before the payload: channel_id, sequence, log_time, publish_time.
inline constexpr std::size_t kMessagePrefixBytes = 2 + 4 + 8 + 8;
/// Footer content: summary_start, summary_offset_start, summary_crc.
inline constexpr std::size_t kFooterContentBytes = 8 + 8 + 4;
/// DataEnd content: data_section_crc.
inline constexpr std::size_t kDataEndContentBytes = 4;

/// "Chunk", "Message", ... for problem texts; "unknown (0x42)" for others.
std::string opcode_name(std::uint8_t opcode);

// ---- encoding: appends little-endian fields to a buffer that is reused, so it only grows ----

void put_u8(std::vector<std::uint8_t>& out, std::uint8_t value);
void put_u16(std::vector<std::uint8_t>& out, std::uint16_t value);
void put_u32(std::vector<std::uint8_t>& out, std::uint32_t value);
void put_u64(std::vector<std::uint8_t>& out, std::uint64_t value);
void put_bytes(std::vector<std::uint8_t>& out, const std::uint8_t* data, std::size_t size);
/// uint32 byte length, then the bytes (MCAP String and the Schema's data).
void put_string(std::vector<std::uint8_t>& out, const std::string& text);
/// Overwrites 8 bytes at `at` (a length field reserved earlier).
void patch_u64(std::vector<std::uint8_t>& out, std::size_t at, std::uint64_t value);
void patch_u32(std::vector<std::uint8_t>& out, std::size_t at, std::uint32_t value);

/// Appends opcode and a placeholder length; returns where the length sits, for end_record().
std::size_t begin_record(std::vector<std::uint8_t>& out, Opcode opcode);
/// Sets the length reserved by begin_record() to the bytes appended since.
void end_record(std::vector<std::uint8_t>& out, std::size_t length_at);

// ---- decoding ----

/// Reads little-endian fields from [data, data + size). Reading past the end never touches
/// memory outside the range: it returns zeros and clears ok(), so a parser checks once at the end.
class Cursor {
 public:
  Cursor(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}

  std::uint8_t u8();
  std::uint16_t u16();
  std::uint32_t u32();
  std::uint64_t u64();
  /// uint32 length + bytes.
  std::string string();
  /// A uint32-length-prefixed Map<string, string>.
  std::map<std::string, std::string> string_map();
  /// Pointer to the next `size` bytes (nullptr and !ok() when fewer remain).
  const std::uint8_t* bytes(std::uint64_t size);

  bool ok() const { return ok_; }
  std::size_t position() const { return position_; }
  std::size_t remaining() const { return size_ - position_; }

 private:
  bool take(std::size_t size);  // advances when `size` bytes remain, else fails

  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t position_ = 0;
  bool ok_ = true;
};

// ---- CRC-32 (IEEE 802.3, as zlib's crc32 and the MCAP spec) ----

/// Continues `crc` (0 to start) over the bytes.
std::uint32_t crc32_update(std::uint32_t crc, const std::uint8_t* data, std::size_t size);

// ---- chunk codecs ----

/// Compresses whole chunks into the MCAP forms: a zstd frame, an LZ4 frame (lz4frame.h, the
/// format other MCAP readers expect), or a copy. Keeps its codec context for the writer's life,
/// so closing a chunk allocates nothing once the output buffer has grown to its working size.
class Compressor {
 public:
  explicit Compressor(Compression compression);
  ~Compressor();
  Compressor(const Compressor&) = delete;
  Compressor& operator=(const Compressor&) = delete;

  /// Appends the compressed form of [data, data + size) to out.
  /// @throws std::runtime_error when the codec fails (it does not for valid input).
  void compress_append(const std::uint8_t* data, std::size_t size, std::vector<std::uint8_t>& out);

 private:
  Compression compression_;
  ZSTD_CCtx_s* zstd_ = nullptr;  // owned; C API, freed in the destructor
  LZ4F_cctx_s* lz4_ = nullptr;   // owned
};

/// Decompresses chunk records given by the file, trusting nothing in them: the output grows with
/// what the data really decompresses to and never beyond the declared uncompressed size, so a
/// corrupt size field cannot make it allocate gigabytes.
class Decompressor {
 public:
  Decompressor();
  ~Decompressor();
  Decompressor(const Decompressor&) = delete;
  Decompressor& operator=(const Decompressor&) = delete;

  /// Decompresses a "zstd" or "lz4" chunk into out[0, expected_size) (out only grows, its size may
  /// exceed the result; uncompressed chunks are used in place and never come here).
  /// @return "" on success, else why it failed (unknown compression, codec error, wrong size).
  std::string decompress(const std::string& compression, const std::uint8_t* data, std::size_t size,
                         std::uint64_t expected_size, std::vector<std::uint8_t>& out);

 private:
  std::string zstd(const std::uint8_t* data, std::size_t size, std::size_t expected_size,
                   std::vector<std::uint8_t>& out);
  std::string lz4(const std::uint8_t* data, std::size_t size, std::size_t expected_size,
                  std::vector<std::uint8_t>& out);

  ZSTD_DCtx_s* zstd_ = nullptr;  // owned, created on first use
  LZ4F_dctx_s* lz4_ = nullptr;   // owned, created on first use
};

}  // namespace pmlsm::mcap::detail
